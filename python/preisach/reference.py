r"""A plain NumPy relay-grid Preisach model, for validation and benchmarks only.

Every relay :math:`\gamma_{\alpha\beta}` is stored explicitly and updated at every sample, so
the cost per sample grows with the number of relays.  The fast simulator in
:class:`preisach.PreisachModel` must agree with it; it is never used for real work.

Relay convention (volts in, volts out): a relay switches to +1 when ``u >= alpha`` and to
-1 when ``u <= beta``; ``alpha >= beta``.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["RelayGrid"]


class RelayGrid:
    """Discrete Preisach model with explicit relays.

    Parameters
    ----------
    alpha, beta : array_like
        Switching thresholds of the relays (V), one entry per relay, ``alpha >= beta``.
    weights : array_like
        Weight of each relay (V).
    y_min : float
        Output at negative saturation (V); the output is
        ``y_min + sum(weights) + sum(weights * state)``.

    """

    def __init__(self, alpha: ArrayLike, beta: ArrayLike, weights: ArrayLike, y_min: float):
        self.alpha = np.asarray(alpha, float).ravel()
        self.beta = np.asarray(beta, float).ravel()
        self.weights = np.asarray(weights, float).ravel()
        if not (self.alpha.shape == self.beta.shape == self.weights.shape):
            raise ValueError("alpha, beta and weights must have the same number of relays")
        if np.any(self.alpha < self.beta):
            raise ValueError("every relay needs alpha >= beta")
        self.offset = float(y_min) + float(self.weights.sum())
        self.state = -np.ones_like(self.weights)

    @classmethod
    def from_everett(
        cls,
        everett: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]],
        u_min: float,
        u_max: float,
        n: int,
        y_min: float,
    ) -> RelayGrid:
        """Relays at the centres of an ``n x n`` grid, weighted by the Everett function.

        The weight of the relay in cell ``[a0, a1] x [b0, b1]`` is the mass of the Preisach
        density in that cell, ``E(a1,b0) - E(a0,b0) - E(a1,b1) + E(a0,b1)``; a diagonal cell
        holds the mass of its triangle, ``E(a1, a0)``, at its centroid.
        """
        g = np.linspace(u_min, u_max, n + 1)
        i, j = np.tril_indices(n)  # i: alpha cell, j: beta cell, j <= i
        a0, a1, b0, b1 = g[i], g[i + 1], g[j], g[j + 1]
        off = i > j
        w = np.where(
            off,
            everett(a1, b0) - everett(a0, b0) - everett(a1, b1) + everett(a0, b1),
            everett(a1, a0),
        )
        h = g[1] - g[0]
        alpha = np.where(off, 0.5 * (a0 + a1), a0 + 2.0 * h / 3.0)
        beta = np.where(off, 0.5 * (b0 + b1), a0 + h / 3.0)
        return cls(alpha, beta, w, y_min)

    def reset(self) -> None:
        """Return to negative saturation (every relay at -1)."""
        self.state[:] = -1.0

    def output(self) -> float:
        """Return the current output (V)."""
        return self.offset + float(self.weights @ self.state)

    def run(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply the input samples ``u`` (V) one after the other; return the outputs (V)."""
        u = np.asarray(u, float).ravel()
        y = np.empty_like(u)
        s, a, b, w = self.state, self.alpha, self.beta, self.weights
        for k, uk in enumerate(u):
            s[a <= uk] = 1.0
            s[b >= uk] = -1.0
            y[k] = w @ s
        return y + self.offset
