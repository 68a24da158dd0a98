r"""The constrained square-root FOD surface of the thesis (Eq 3.1-3.2, Table 3.1).

The surface gives the output ``y(alpha, beta)`` (volts) at the end of a first-order
descending (FOD) curve: the input goes to negative saturation ``u_min``, rises to
``alpha`` and falls to ``beta`` (``alpha >= beta``, both in input volts).

.. math::

    \tilde y(\alpha,\beta) = \frac{(y_{max}-y_{min})\,\bar f_2(\alpha)
        \left(\sqrt{\beta-f_3(\alpha)}-\sqrt{u_{min}-f_3(\alpha)}\right)}
        {\bar f_2(\hat u)\left(\sqrt{\hat u-f_3(\hat u)}-\sqrt{u_{min}-f_3(\hat u)}\right)}
        + y_{min}

with :math:`\bar f_2(\alpha) = \bar x_4\alpha^2 + \bar x_5\alpha + 1` and
:math:`f_3(\alpha) = x_7\alpha^2 + x_8\alpha + x_9`.  By construction
``y(u_max, u_max) = y_max`` and ``y(alpha, u_min) = y_min`` for every ``alpha``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SqrtSurface", "TABLE_3_1"]


@dataclass(frozen=True)
class SqrtSurface:
    r"""Parameters of the constrained square-root FOD surface (one column of Table 3.1).

    Attributes
    ----------
    xbar4, xbar5 : float
        Normalised coefficients of :math:`\bar f_2` (1/V^2 and 1/V).
    x7, x8, x9 : float
        Coefficients of :math:`f_3` (1/V, 1, V).  ``f_3(alpha) < u_min`` must hold on
        the input range so that the square roots are real.
    y_max, y_min : float
        Output (V) at positive saturation and at the end of every FOD curve.
    u_max, u_min : float
        Input range (V).  ``u_max`` plays the role of :math:`\hat u`.
    fit_error : float
        Root of the summed squared fit error over the FOD data (V), as Table 3.1 reports;
        ``nan`` when unknown.
    frequency : float
        Frequency (Hz) of the identification input, ``nan`` when unknown.

    """

    xbar4: float
    xbar5: float
    x7: float
    x8: float
    x9: float
    y_max: float
    y_min: float
    u_max: float = 100.0
    u_min: float = -100.0
    fit_error: float = float("nan")
    frequency: float = float("nan")

    def __post_init__(self) -> None:
        if not self.u_max > self.u_min:
            raise ValueError(f"u_max ({self.u_max}) must exceed u_min ({self.u_min})")
        a = np.linspace(self.u_min, self.u_max, 401)
        if np.any(self._f3(a) >= self.u_min):
            raise ValueError(
                "f3(alpha) = x7*alpha^2 + x8*alpha + x9 must stay below u_min on the input "
                "range; the square roots of Eq 3.2 are not real otherwise"
            )
        if np.any(self._f2(a) == 0.0) or self._den() == 0.0:
            raise ValueError("f2bar(alpha) vanishes on the input range; Eq 3.2 is undefined")

    # -- pieces of Eq 3.2 -------------------------------------------------------------
    def _f2(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.xbar4 * a * a + self.xbar5 * a + 1.0

    def _f3(self, a: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.x7 * a * a + self.x8 * a + self.x9

    def _den(self) -> float:
        u = self.u_max
        f3u = self.x7 * u * u + self.x8 * u + self.x9
        f2u = self.xbar4 * u * u + self.xbar5 * u + 1.0
        return float(f2u * (np.sqrt(u - f3u) - np.sqrt(self.u_min - f3u)))

    def _scale(self) -> float:
        return (self.y_max - self.y_min) / self._den()

    # -- public evaluation ------------------------------------------------------------
    def __call__(self, alpha: ArrayLike, beta: ArrayLike) -> NDArray[np.float64]:
        """FOD output ``y(alpha, beta)`` in volts (Eq 3.2), for ``alpha >= beta``."""
        a, b = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(beta, float))
        f3 = self._f3(a)
        y: NDArray[np.float64] = (
            self._scale() * self._f2(a) * (np.sqrt(b - f3) - np.sqrt(self.u_min - f3)) + self.y_min
        )
        return y

    def everett(self, alpha: ArrayLike, beta: ArrayLike) -> NDArray[np.float64]:
        """Everett function ``E = (y(alpha, alpha) - y(alpha, beta)) / 2`` in volts."""
        a, b = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(beta, float))
        return 0.5 * (self(a, a) - self(a, b))

    def weight_density(self, alpha: ArrayLike, beta: ArrayLike) -> NDArray[np.float64]:
        """Continuous weight ``v(alpha, beta) = 1/2 d2y/(dalpha dbeta)`` (Eq 2.13), V/V^2."""
        a, b = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(beta, float))
        f3 = self._f3(a)
        d = b - f3
        df2 = 2.0 * self.xbar4 * a + self.xbar5
        df3 = 2.0 * self.x7 * a + self.x8
        mixed = self._scale() * (df2 / (2.0 * np.sqrt(d)) + self._f2(a) * df3 / (4.0 * d**1.5))
        return 0.5 * mixed

    def kappa(self, beta: ArrayLike) -> NDArray[np.float64]:
        """Reversible weight ``kappa(beta) = 1/2 dy/dbeta`` at ``beta -> alpha`` (Eq 2.14), V/V."""
        b = np.asarray(beta, float)
        return self._scale() * self._f2(b) / (4.0 * np.sqrt(b - self._f3(b)))

    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary of the parameters (JSON-friendly)."""
        return asdict(self)


#: Table 3.1 of the thesis: the SS15 FOD surfaces identified at 1, 2 and 4 Hz.
TABLE_3_1: dict[int, SqrtSurface] = {
    1: SqrtSurface(
        8.81e-06,
        3.47e-03,
        -4.16e-03,
        -4.83e-01,
        -1.94e02,
        3.49,
        -3.63,
        fit_error=0.38,
        frequency=1.0,
    ),
    2: SqrtSurface(
        2.24e-06,
        3.99e-03,
        -1.73e-03,
        -3.19e-01,
        -1.55e02,
        3.49,
        -3.62,
        fit_error=0.57,
        frequency=2.0,
    ),
    4: SqrtSurface(
        -5.28e-06,
        4.39e-03,
        -3.41e-04,
        -1.33e-01,
        -1.24e02,
        3.48,
        -3.60,
        fit_error=1.10,
        frequency=4.0,
    ),
}
