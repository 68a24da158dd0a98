r"""Neutral states: the locus N(l), its inverse and the class Mp (thesis §2.8).

For a desired output ``y_d`` a Preisach model has many *equivalent states* (Definition 2).
Among them the **neutral state** :math:`\psi_n^l` (Eq 2.17) is the boundary made of the
horizontal segment ``s = l`` for ``0 <= r <= u_hat - |l|``, continued along the edge of the
Preisach plane; it is reached (approximately) by a sinusoid decaying about ``l`` (Eq 4.1/4.2,
see :func:`preisach.experiments.neutral_input`).  Its output

.. math:: N(l) = \Gamma_r(\psi_n^l)                                       \qquad (2.18)

is the **neutral locus**; it runs inside the major loop from ``y_-`` (``l = u_min``) to ``y_+``
(``l = u_max``) and connects the points where ascending and descending branches have similar
slopes.  Its inverse picks ``l`` for a desired output:

* Eq 2.19: ``N_inv = N^-1`` when ``N`` is monotone (guaranteed when ``mu`` is in ``Mp``);
* Eq 2.20: ``N_inv(y) = the l of smallest |l| with N(l) = y`` otherwise (the neutral state with
  the longest horizontal segment).

``N`` is computed from the **exact** neutral boundary (an antidiagonal boundary piece, no
staircase approximation) in C++ (:func:`preisach._core.neutral_locus`), on a grid of ``l``; the
inverse brackets the roots on the grid and refines each with Brent's method on the exact
``N``.  A locus measured on a rig (outputs at a set of ``l``) is inverted by linear
interpolation instead.

Volts in, volts out: ``l`` is an input offset (V), ``N`` an output (V).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from . import _core
from .errors import ConvergenceError

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .model import PreisachModel

__all__ = ["MpCheck", "NeutralLocus", "check_mp", "neutral_locus", "neutral_output"]

_METHODS = ("auto", "inverse", "min-abs")


@dataclass(frozen=True)
class MpCheck:
    """Whether a tabulated Preisach weight belongs to the class ``Mp`` (§2.7).

    ``Mp`` is the set of weights ``mu`` that are bounded, piecewise continuous and
    non-negative.  A tabulated model has a finite relay mass per grid cell (the mixed second
    differences of the Everett table, :meth:`PreisachModel.cell_weights`), so it is bounded
    and piecewise continuous exactly when those masses are finite; it is non-negative when no
    cell mass is below ``-tolerance``.

    Attributes
    ----------
    in_mp : bool
        ``bounded`` and no cell mass below ``-tolerance``.
    bounded : bool
        Every cell mass is finite.
    n_cells : int
        Cells of the triangular grid (diagonal half-cells included).
    n_negative : int
        Cells whose mass is below ``-tolerance``.
    min_weight : float
        Smallest cell mass (V).
    negative_mass : float
        Sum of the masses below ``-tolerance`` (V, <= 0).
    total_mass : float
        Sum of all cell masses (V): ``E(u_max, u_min) = (y_+ - y_-) / 2``.
    tolerance : float
        Absolute tolerance (V) used for "negative".
    negative_cells : list of (float, float, float)
        Up to 10 most negative cells as ``(alpha, beta, mass)``: the cell's corner farthest
        from the diagonal (upper ``alpha``, lower ``beta``, V) and its mass (V).

    """

    in_mp: bool
    bounded: bool
    n_cells: int
    n_negative: int
    min_weight: float
    negative_mass: float
    total_mass: float
    tolerance: float
    negative_cells: list[tuple[float, float, float]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary of the check."""
        return {
            "in_mp": self.in_mp,
            "bounded": self.bounded,
            "n_cells": self.n_cells,
            "n_negative": self.n_negative,
            "min_weight": self.min_weight,
            "negative_mass": self.negative_mass,
            "total_mass": self.total_mass,
            "tolerance": self.tolerance,
            "negative_cells": [list(c) for c in self.negative_cells],
        }

    def __str__(self) -> str:
        if self.in_mp:
            return (
                f"mu in Mp: all {self.n_cells} cell masses >= {-self.tolerance + 0.0:g} V "
                f"(min {self.min_weight:.3g} V)"
            )
        if not self.bounded:
            return "mu not in Mp: some cell masses are not finite"
        return (
            f"mu not in Mp: {self.n_negative} of {self.n_cells} cells negative, min "
            f"{self.min_weight:.3g} V, negative mass {self.negative_mass:.3g} V of "
            f"{self.total_mass:.4g} V"
        )


def check_mp(model: PreisachModel, tolerance: float = 0.0) -> MpCheck:
    """Check whether the model's weight is in ``Mp`` (bounded and non-negative).

    Parameters
    ----------
    model : PreisachModel
        The model to check.
    tolerance : float, default 0.0
        Cell masses (V) down to ``-tolerance`` count as non-negative.  The thesis (§3.3.3)
        regards the 2 Hz and 4 Hz SS15 weights, whose only negative values are of order
        ``1e-6``, as members of ``Mp``; pass e.g. ``tolerance=1e-5`` to follow it.

    Returns
    -------
    MpCheck

    """
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"tolerance: must be finite and >= 0 (V), got {tolerance!r}")
    w = model.cell_weights()
    lv = model.levels
    lower = np.tril(np.ones_like(w, dtype=bool))
    vals = w[lower]
    bounded = bool(np.all(np.isfinite(vals)))
    neg = lower & (w < -tolerance)
    idx = np.argwhere(neg)
    order = np.argsort(w[neg])[:10]
    # Cell [lv[i], lv[i+1]] x [lv[j], lv[j+1]] (alpha x beta), named by its corner farthest
    # from the diagonal (upper alpha, lower beta), as the thesis names (100, -100).
    cells = [(float(lv[i + 1]), float(lv[j]), float(w[i, j])) for i, j in idx[order]]
    return MpCheck(
        in_mp=bounded and not bool(np.any(neg)),
        bounded=bounded,
        n_cells=int(vals.size),
        n_negative=int(np.count_nonzero(neg)),
        min_weight=float(np.min(vals)) if bounded else float("nan"),
        negative_mass=float(np.sum(w[neg])) if bounded else float("nan"),
        total_mass=float(np.sum(vals)) if bounded else float("nan"),
        tolerance=float(tolerance),
        negative_cells=cells,
    )


def neutral_output(model: PreisachModel, l: ArrayLike) -> NDArray[np.float64]:  # noqa: E741
    """Exact ``N(l) = Gamma(psi_n^l)`` (Eq 2.18, V) for offsets ``l`` (V) in the input range.

    Raises
    ------
    ValueError
        If an ``l`` is outside ``[u_min, u_max]`` or not finite (the message names its index).

    """
    arr = np.ascontiguousarray(np.atleast_1d(np.asarray(l, dtype=float)).ravel())
    out = _core.neutral_locus(model.table, arr)
    return out.reshape(np.shape(l))


def _make_residual(table: _core.EverettTable, y: float) -> Callable[[float], float]:
    def g(x: float) -> float:
        return float(_core.neutral_locus(table, np.array([x]))[0]) - y

    return g


@dataclass
class NeutralLocus:
    """The locus of neutral states ``N(l)`` (Eq 2.18) on a grid of offsets, and its inverse.

    Build it with :func:`neutral_locus` (exact, from a model) or directly from measured pairs
    (``NeutralLocus(l, N, source="measured")``, e.g. outputs of a rig driven by
    :func:`preisach.experiments.neutral_input`).

    Attributes
    ----------
    l : ndarray
        Increasing offsets (V).
    N : ndarray
        Outputs ``N(l)`` (V).
    source : str
        ``"model"`` (exact, refinable) or ``"measured"``.
    table : preisach._core.EverettTable or None
        The model's table when ``source == "model"``: roots are then refined on the exact
        ``N`` instead of interpolated.

    """

    l: NDArray[np.float64]  # noqa: E741 (the thesis's symbol)
    N: NDArray[np.float64]
    source: str = "measured"
    table: _core.EverettTable | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.l = np.asarray(self.l, dtype=float)
        self.N = np.asarray(self.N, dtype=float)
        if self.l.ndim != 1 or self.l.shape != self.N.shape or self.l.size < 2:
            raise ValueError(
                f"l and N: need two 1-D arrays of the same length >= 2, got shapes "
                f"{self.l.shape} and {self.N.shape}"
            )
        if not (np.all(np.isfinite(self.l)) and np.all(np.isfinite(self.N))):
            bad = int(np.flatnonzero(~(np.isfinite(self.l) & np.isfinite(self.N)))[0])
            raise ValueError(f"l and N: entry {bad} is not finite")
        if np.any(np.diff(self.l) <= 0):
            raise ValueError("l: offsets must be strictly increasing")

    # ---------------------------------------------------------------- properties
    @property
    def monotone(self) -> bool:
        """``N`` strictly monotone on the grid (then Eq 2.19 applies)."""
        d = np.diff(self.N)
        return bool(np.all(d > 0) or np.all(d < 0))

    @property
    def y_range(self) -> tuple[float, float]:
        """``(min N, max N)`` over the grid (V): the outputs that have a neutral state."""
        return float(self.N.min()), float(self.N.max())

    def __call__(self, l: ArrayLike) -> NDArray[np.float64]:  # noqa: E741
        """``N`` at offsets ``l`` (V): exact for a model locus, interpolated otherwise."""
        if self.table is not None:
            arr = np.ascontiguousarray(np.atleast_1d(np.asarray(l, dtype=float)).ravel())
            out = _core.neutral_locus(self.table, arr)
            return out.reshape(np.shape(l))
        x = np.asarray(l, dtype=np.float64)
        return np.asarray(np.interp(x, self.l, self.N), dtype=np.float64)

    # ---------------------------------------------------------------- inverse
    def solutions(self, y: float, *, xtol: float = 1e-10) -> NDArray[np.float64]:
        """Every offset ``l`` (V) on the grid's resolution with ``N(l) = y``, increasing.

        Roots are bracketed by sign changes of ``N - y`` between neighbouring grid points (or
        exact zeros at grid points) and refined by Brent's method on the exact ``N`` for a
        model locus (to ``xtol`` V), by linear interpolation for a measured one.  Two roots
        closer together than one grid step, or a tangency, can be missed: use a finer grid.

        Raises
        ------
        ValueError
            If ``y`` is not finite or outside ``y_range``.

        """
        y = float(y)
        lo, hi = self.y_range
        if not math.isfinite(y):
            raise ValueError(f"y: desired output is not finite ({y!r})")
        if y < lo or y > hi:
            raise ValueError(
                f"y = {y:g} V is outside the range of the neutral locus "
                f"[{lo:.6g}, {hi:.6g}] V; no neutral state has this output"
            )
        f = self.N - y
        roots: list[float] = [float(v) for v in self.l[f == 0.0]]
        idx = np.flatnonzero((f[:-1] * f[1:]) < 0.0)
        for i in idx:
            a, b = float(self.l[i]), float(self.l[i + 1])
            if self.table is not None:
                g = _make_residual(self.table, y)
                try:
                    r = brentq(g, a, b, xtol=xtol, maxiter=200)
                except RuntimeError as exc:  # pragma: no cover - brentq converges on a bracket
                    raise ConvergenceError(
                        f"N(l) = {y:g} V: root refinement in [{a:g}, {b:g}] V failed ({exc})"
                    ) from exc
            else:
                fa, fb = float(f[i]), float(f[i + 1])
                r = a + (b - a) * fa / (fa - fb)
            roots.append(float(r))
        return np.unique(np.asarray(roots, dtype=float))

    def inverse(self, y: float, method: str = "auto", *, xtol: float = 1e-10) -> float:
        """``N_inv(y)``: the offset ``l`` (V) of the neutral state with output ``y`` (V).

        Parameters
        ----------
        y : float
            Desired output (V), inside ``y_range``.
        method : {"auto", "inverse", "min-abs"}
            ``"inverse"``: Eq 2.19, ``N^-1``; requires a monotone locus.  ``"min-abs"``:
            Eq 2.20, the solution of smallest ``|l|`` (ties: the smaller ``l``).  ``"auto"``
            (default): Eq 2.19 when :attr:`monotone`, else Eq 2.20.
        xtol : float
            Absolute tolerance (V) of the root refinement on a model locus.

        Raises
        ------
        ValueError
            If ``y`` is outside the locus's range, or ``method="inverse"`` on a non-monotone
            locus.

        """
        if method not in _METHODS:
            raise ValueError(f"method: expected one of {_METHODS}, got {method!r}")
        if method == "inverse" and not self.monotone:
            raise ValueError(
                "method='inverse' (Eq 2.19) needs a monotone N(l); this locus is not "
                "monotone on its grid, use 'min-abs' (Eq 2.20)"
            )
        roots = self.solutions(y, xtol=xtol)
        if roots.size == 0:  # pragma: no cover - y in range always gives a sign change or zero
            raise ConvergenceError(f"N(l) = {y:g} V: no root found on the grid")
        if method == "inverse" or (method == "auto" and self.monotone):
            return float(roots[0])
        order = np.lexsort((roots, np.abs(roots)))
        return float(roots[order[0]])

    # ---------------------------------------------------------------- output
    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary: grid, values, monotonicity and source."""
        return {
            "l": self.l.tolist(),
            "N": self.N.tolist(),
            "monotone": self.monotone,
            "y_range": list(self.y_range),
            "source": self.source,
        }

    def plot(
        self,
        *,
        ax: Axes | None = None,
        model: PreisachModel | None = None,
        points: dict[str, tuple[float, float]] | None = None,
        title: str | None = None,
    ) -> Figure:
        """Plot ``N(l)`` in the input-output plane, optionally inside the major loop.

        Drawn by :func:`preisach.plotting.plot_locus` (see it for the parameters).
        """
        from .plotting.experiments import plot_locus

        return plot_locus(self, ax=ax, model=model, points=points, title=title)


def neutral_locus(
    model: PreisachModel,
    l: ArrayLike | None = None,  # noqa: E741
    *,
    points: int | None = None,
) -> NeutralLocus:
    """Exact neutral locus ``N(l)`` (Eq 2.18) of a model on a grid of offsets.

    Parameters
    ----------
    model : PreisachModel
        The model.
    l : array_like, optional
        Increasing offsets (V) inside ``[u_min, u_max]``.  Default: ``points`` evenly spaced
        offsets over the whole range.
    points : int, optional
        Size of the default grid; default ``2 * len(model.levels) - 1`` (every table level and
        every midpoint), which resolves ``N`` at the table's own resolution.

    Returns
    -------
    NeutralLocus
        With ``source="model"``: :meth:`NeutralLocus.inverse` refines roots on the exact ``N``.

    """
    if l is None:
        n = 2 * len(model.levels) - 1 if points is None else int(points)
        if n < 2:
            raise ValueError(f"points: need at least 2 offsets, got {n}")
        grid = np.linspace(model.u_min, model.u_max, n)
    else:
        if points is not None:
            raise ValueError("give either l or points, not both")
        grid = np.asarray(l, dtype=float)
    values = neutral_output(model, grid)
    return NeutralLocus(grid, values, source="model", table=model.table)
