"""Identification of the square-root FOD surface of the thesis (section 3.3.2, Eq 3.1-3.2).

The input is a grid of first-order descending (FOD) data: for every pair of input levels
``(alpha_i, beta_j)`` with ``j <= i`` the output ``y(alpha_i, beta_j)`` (volts) measured after
the input went to negative saturation, rose to ``alpha_i`` and fell to ``beta_j``.  The
procedure of the thesis is followed and then extended:

1. **Per-curve fit.**  Every FOD curve (fixed ``alpha``) with more than three points is fit by
   least squares with ``y(beta) = X1 + X2 * sqrt(beta - X3)`` using the Nelder-Mead simplex
   (the thesis uses Matlab's ``fminsearch``).  Curves are processed from ``alpha = u_max``
   downward, i.e. from the longest curve to the shortest, and each fit is warm-started from
   the parameters of the previous curve, as the thesis does to stop the simplex from wandering
   off on the short, almost straight curves.  The first curve is started from a data-derived
   guess: for a log-spaced grid of ``X3`` values the model is linear in ``X1, X2``, which are
   solved in closed form; the best grid point is the start.  The square-root domain is guarded
   by a reparametrisation (``X3 = beta_min - exp(theta)``, so ``X3 < beta_min`` always) and,
   for good simplex conditioning, the other two unknowns are the model values at the two ends of
   the curve (volts).
2. **Polynomials in alpha.**  ``X1, X2, X3`` are fit by second-order polynomials in ``alpha``
   (``numpy.polyfit``): ``f1 = x1 a^2 + x2 a + x3``, ``f2 = x4 a^2 + x5 a + x6``,
   ``f3 = x7 a^2 + x8 a + x9``.
3. **Constrained surface.**  Eq 3.1-3.2: ``x1..x3`` and ``x6`` are eliminated so that
   ``y(u_max, u_max) = y_max`` and ``y(alpha, u_min) = y_min`` hold exactly;
   ``xbar4 = x4 / x6`` and ``xbar5 = x5 / x6``.
4. **Joint refinement** (beyond the thesis, on by default).  The five free parameters
   ``(xbar4, xbar5, x7, x8, x9)`` of Eq 3.2 are refined by :func:`scipy.optimize.least_squares`
   against *all* FOD data points at once, starting from the values of step 3.  The
   polynomial stage fits parameters, not outputs, and gives the short, ill-conditioned curves
   (whose ``X3`` is poorly determined) the same say as the long ones; the joint fit minimises
   the output error that Table 3.1 reports.  On noise-free samples of an Eq 3.2 surface both
   stages are exact (to about 1e-11 V); with 2 mV noise on the thesis' 21-level grid the
   refinement cuts the worst surface error from typically 3-7 mV (up to 30 mV) to about 1 mV
   plus the noise of the single ``y_max`` sample the surface is pinned to.

Error measures
--------------
Table 3.1 of the thesis reports "the square root of the least-squares error over all the FOD
data points", i.e. ``sqrt(sum(residual**2))`` (volts), here ``root_sum_sq_error``.  The text
then quotes "the average error at each sampled data point" as 0.0016, 0.0025 and 0.0047 V for
the errors 0.38, 0.57 and 1.10 V of Table 3.1.  Those numbers are the root-sum-square error
divided by the number of points ``N``, ``sqrt(SSE) / N``:

* ``N = 231`` (all ``j <= i`` pairs of the 21 levels, what :func:`fit_sqrt_surface` counts):
  0.38/231 = 0.00165, 0.57/231 = 0.00247, 1.10/231 = 0.00476.  All three quotes are reproduced
  if the unrounded errors were about 0.375-0.381, 0.565-0.575 and 1.095-1.097 V, which the
  two-digit table values allow.
* ``N = 230`` (the thesis' count ``n (n + 3) / 2`` for ``n = 20`` sections, i.e. without one
  point, presumably ``(-u_hat, -u_hat)``): 0.00165, 0.00248, 0.00478; the last would need an
  error below 1.0925 V, i.e. a table entry of 1.09, so this count fits 0.0047 only if the thesis
  truncated rather than rounded.

They are *not* root-mean-square errors: ``sqrt(SSE / N)`` gives 0.025, 0.038 and 0.072 V, which
also contradicts the quoted "within 0.07 % of the whole output measurement range" (about
7.1 V), whereas 0.0047 V / 7.1 V = 0.066 %.  :class:`SurfaceFitResult` reports all three:
``root_sum_sq_error`` (Table 3.1), ``mean_error_per_point = root_sum_sq_error / n_points`` (the
quoted averages) and ``rmse``.  None of this can be checked against the thesis' own fits because
its raw FOD data are not published; the interpretation rests on the numbers above.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, minimize

from ..surface import SqrtSurface

__all__ = ["SurfaceFitResult", "fit_sqrt_surface", "format_table"]

#: Curves need more than this many points to be fit (three parameters per curve).
_MIN_CURVE_POINTS = 4
#: Number of log-spaced X3 candidates of the linearised initial guess.
_N_GRID = 161
#: Bounds of ``beta_min - X3`` in units of the curve's beta span (per-curve fits).
_OFFSET_MIN, _OFFSET_MAX = 1e-6, 1e4


# --------------------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------------------
@dataclass
class SurfaceFitResult:
    """Result of :func:`fit_sqrt_surface`.

    Attributes
    ----------
    surface : SqrtSurface
        The identified constrained surface of Eq 3.2 (``fit_error`` holds
        ``root_sum_sq_error``).
    curve_params : ndarray, shape (m, 4)
        Step 1, one row per fitted FOD curve in increasing ``alpha``:
        ``[alpha, X1, X2, X3]`` (V, V, V^0.5, V) of ``y = X1 + X2 sqrt(beta - X3)``.
    curve_n_points : ndarray of int, shape (m,)
        Number of data points of each fitted curve.
    curve_rms : ndarray, shape (m,)
        Root-mean-square residual of each per-curve fit (V).
    poly : ndarray, shape (9,)
        Step 2, the unconstrained polynomial coefficients ``x1 .. x9`` (``f1 = x1 a^2 + x2 a +
        x3`` etc.; units V/V^2, V/V, V for ``f1``, V^0.5/V^2 ... for ``f2``, 1/V, 1, V for
        ``f3``).
    rmse : float
        Root-mean-square error of ``surface`` over all finite FOD points (V).
    max_error : float
        Largest absolute error of ``surface`` over the FOD points (V).
    root_sum_sq_error : float
        ``sqrt(sum(residual**2))`` over the FOD points (V): the "error" row of Table 3.1.
    n_points : int
        Number of FOD data points used for the errors (finite entries with ``j <= i``).
    warnings : list of str
        Non-fatal problems met during the fit (non-converged simplex, repaired infeasible
        polynomial stage, refinement not improving, ...).
    unrefined_surface : SqrtSurface or None
        The constrained surface straight from the polynomial stage (the thesis' result), before
        the joint refinement; ``None`` if it was not valid (``f3 >= u_min`` somewhere).
    unrefined_root_sum_sq_error : float
        ``root_sum_sq_error`` of ``unrefined_surface`` (V); ``nan`` if it is ``None``.
    refined : bool
        Whether ``surface`` comes from the joint least-squares refinement.

    """

    surface: SqrtSurface
    curve_params: NDArray[np.float64]
    curve_n_points: NDArray[np.int64]
    curve_rms: NDArray[np.float64]
    poly: NDArray[np.float64]
    rmse: float
    max_error: float
    root_sum_sq_error: float
    n_points: int
    warnings: list[str] = field(default_factory=list)
    unrefined_surface: SqrtSurface | None = None
    unrefined_root_sum_sq_error: float = float("nan")
    refined: bool = False

    @property
    def mean_error_per_point(self) -> float:
        """``root_sum_sq_error / n_points`` (V): the thesis' "average error at each point".

        This is how the thesis turns the Table 3.1 errors 0.38/0.57/1.10 V into the quoted
        0.0016/0.0025/0.0047 V; it equals ``rmse / sqrt(n_points)``, not a mean error.
        """
        return self.root_sum_sq_error / self.n_points if self.n_points else float("nan")

    def table(self, digits: int = 3) -> str:
        """Table 3.1-style text table of the identified surface (one column).

        Parameters
        ----------
        digits : int, optional
            Significant digits of the surface coefficients.

        Returns
        -------
        str
            Rows ``xbar4, xbar5, x7, x8, x9, umax, umin, ymax, ymin, error`` (inputs and outputs
            in volts; ``error`` is ``root_sum_sq_error``).

        """
        return format_table([self], digits=digits)


def format_table(fits: Iterable[SurfaceFitResult | SqrtSurface], digits: int = 3) -> str:
    """Format surfaces side by side like Table 3.1 of the thesis.

    Parameters
    ----------
    fits : iterable of SurfaceFitResult or SqrtSurface
        One column per entry.  For a :class:`SqrtSurface` the ``error`` row is its
        ``fit_error``.
    digits : int, optional
        Significant digits of ``xbar4 .. x9``; inputs, outputs and the error use two decimals
        (volts), as in the thesis, or scientific notation when the error is below 0.005 V.

    Returns
    -------
    str
        The table, rows ``f (Hz), xbar4, xbar5, x7, x8, x9, umax, umin, ymax, ymin, error``.

    Examples
    --------
    >>> from preisach.surface import TABLE_3_1
    >>> print(format_table(TABLE_3_1.values()))  # doctest: +SKIP

    """
    surfaces: list[SqrtSurface] = []
    errors: list[float] = []
    for item in fits:
        if isinstance(item, SurfaceFitResult):
            surfaces.append(item.surface)
            errors.append(item.root_sum_sq_error)
        elif isinstance(item, SqrtSurface):
            surfaces.append(item)
            errors.append(float(item.fit_error))
        else:
            raise TypeError(f"fits: expected SurfaceFitResult or SqrtSurface, got {type(item)!r}")
    if digits < 1:
        raise ValueError(f"digits must be >= 1, got {digits}")

    def sci(v: float) -> str:
        return f"{v:.{digits - 1}e}"

    def fix(v: float) -> str:
        return "nan" if not math.isfinite(v) else f"{v:.2f}"

    def err(v: float) -> str:
        if not math.isfinite(v):
            return "nan"
        return f"{v:.2f}" if abs(v) >= 5e-3 else f"{v:.2e}"

    def freq(v: float) -> str:
        return "-" if not math.isfinite(v) else f"{v:g}"

    rows: list[tuple[str, list[str]]] = [
        ("f (Hz)", [freq(s.frequency) for s in surfaces]),
        ("xbar4", [sci(s.xbar4) for s in surfaces]),
        ("xbar5", [sci(s.xbar5) for s in surfaces]),
        ("x7", [sci(s.x7) for s in surfaces]),
        ("x8", [sci(s.x8) for s in surfaces]),
        ("x9", [sci(s.x9) for s in surfaces]),
        ("umax", [fix(s.u_max) for s in surfaces]),
        ("umin", [fix(s.u_min) for s in surfaces]),
        ("ymax", [fix(s.y_max) for s in surfaces]),
        ("ymin", [fix(s.y_min) for s in surfaces]),
        ("error", [err(e) for e in errors]),
    ]
    w0 = max(len(r[0]) for r in rows)
    w = max([len(c) for _, cells in rows for c in cells] + [1])
    return "\n".join(
        f"{name:<{w0}}" + "".join(f"  {c:>{w}}" for c in cells) for name, cells in rows
    )


# --------------------------------------------------------------------------------------
# step 1: per-curve fits
# --------------------------------------------------------------------------------------
@dataclass
class _Curve:
    alpha: float
    beta: NDArray[np.float64]
    y: NDArray[np.float64]


def _linear_guess(beta: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Data-derived ``(X1, X2, X3)``: closed-form ``X1, X2`` for a log grid of ``X3``."""
    b0 = float(beta.min())
    span = float(beta.max() - b0)
    scale = max(span, 1e-12)
    offsets = scale * np.logspace(-3.0, 3.0, _N_GRID)  # beta_min - X3
    x3 = b0 - offsets
    s = np.sqrt(beta[None, :] - x3[:, None])  # (grid, points)
    s_mean = s.mean(axis=1, keepdims=True)
    y_mean = y.mean()
    sc = s - s_mean
    den = (sc * sc).sum(axis=1)
    x2 = np.where(den > 0, (sc * (y - y_mean)).sum(axis=1) / np.where(den > 0, den, 1.0), 0.0)
    x1 = y_mean - x2 * s_mean[:, 0]
    sse = ((x1[:, None] + x2[:, None] * s - y) ** 2).sum(axis=1)
    k = int(np.argmin(sse))
    return np.array([x1[k], x2[k], x3[k]])


def _to_internal(p: NDArray[np.float64], b_lo: float, b_hi: float) -> NDArray[np.float64]:
    """``(X1, X2, X3)`` -> ``(y(b_lo), y(b_hi), theta)`` with ``X3 = b_lo - exp(theta)``."""
    x1, x2, x3 = (float(v) for v in p)
    off = b_lo - x3
    if not off > 0.0:  # outside the domain of this curve: keep the shape, move the pole
        off = max(b_hi - b_lo, 1.0) * 1e-3
        x3 = b_lo - off
    return np.array([x1 + x2 * math.sqrt(b_lo - x3), x1 + x2 * math.sqrt(b_hi - x3), math.log(off)])


def _from_internal(q: NDArray[np.float64], b_lo: float, b_hi: float) -> NDArray[np.float64]:
    """Inverse of :func:`_to_internal`."""
    y_lo, y_hi, theta = (float(v) for v in q)
    theta = min(max(theta, -700.0), 700.0)
    off = math.exp(theta)
    x3 = b_lo - off
    r_lo = math.sqrt(off)
    r_hi = math.sqrt(b_hi - x3)
    d = r_hi - r_lo
    x2 = (y_hi - y_lo) / d if d > 0.0 else 0.0
    x1 = y_lo - x2 * r_lo
    return np.array([x1, x2, x3])


def _curve_sse(p: NDArray[np.float64], beta: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    x1, x2, x3 = p
    d = beta - x3
    if np.any(d < 0.0):
        return math.inf
    r = x1 + x2 * np.sqrt(d) - y
    return float(r @ r)


def _fit_curve(
    curve: _Curve, start: NDArray[np.float64], y_scale: float
) -> tuple[NDArray[np.float64], bool]:
    """Nelder-Mead fit of ``X1 + X2 sqrt(beta - X3)`` to one FOD curve from ``start``."""
    beta, y = curve.beta, curve.y
    b_lo, b_hi = float(beta.min()), float(beta.max())
    norm = 1.0 / (len(y) * y_scale * y_scale)

    def obj(q: NDArray[np.float64]) -> float:
        p = _from_internal(q, b_lo, b_hi)
        val = _curve_sse(p, beta, y) * norm
        return val if math.isfinite(val) else 1e300

    span = max(b_hi - b_lo, 1e-12)
    # beta_min - X3 between 1e-6 and 1e4 curve spans: beyond the upper end the curve is a
    # straight line for all practical purposes, and the simplex would walk off to infinity
    # on short, almost straight curves (the failure the thesis warns about).
    theta_bounds = (math.log(_OFFSET_MIN * span), math.log(_OFFSET_MAX * span))
    q = _to_internal(start, b_lo, b_hi)
    q[2] = min(max(q[2], theta_bounds[0]), theta_bounds[1])
    converged = False
    best = obj(q)
    # A few restarts from the last optimum: the standard cure for premature simplex collapse.
    # Convergence needs both the simplex size (xatol: volts and log-volts) and the spread of
    # the normalised objective (fatol, i.e. relative to n * ptp(y)^2) to be small.
    for _ in range(4):
        res = minimize(
            obj,
            q,
            method="Nelder-Mead",
            bounds=[(None, None), (None, None), theta_bounds],
            options={"xatol": 1e-10, "fatol": 1e-16, "maxiter": 4000, "maxfev": 8000},
        )
        converged = bool(res.success)
        improved = res.fun < best * (1.0 - 1e-9)
        if res.fun <= best:
            q, best = np.asarray(res.x, float), float(res.fun)
        if not improved:
            break
    return _from_internal(q, b_lo, b_hi), converged


# --------------------------------------------------------------------------------------
# step 3/4: the constrained surface
# --------------------------------------------------------------------------------------
def _eq32(
    params: Sequence[float],
    alpha: NDArray[np.float64],
    beta: NDArray[np.float64],
    y_max: float,
    y_min: float,
    u_max: float,
    u_min: float,
) -> NDArray[np.float64]:
    """Eq 3.2 with the square roots clipped at zero (safe for infeasible trial parameters)."""
    xb4, xb5, x7, x8, x9 = params
    f3 = x7 * alpha * alpha + x8 * alpha + x9
    f2 = xb4 * alpha * alpha + xb5 * alpha + 1.0
    f3u = x7 * u_max * u_max + x8 * u_max + x9
    f2u = xb4 * u_max * u_max + xb5 * u_max + 1.0
    den = f2u * (math.sqrt(max(u_max - f3u, 0.0)) - math.sqrt(max(u_min - f3u, 0.0)))
    if den == 0.0 or not math.isfinite(den):
        return np.full(alpha.shape, np.nan)
    num = f2 * (np.sqrt(np.maximum(beta - f3, 0.0)) - np.sqrt(np.maximum(u_min - f3, 0.0)))
    return np.asarray((y_max - y_min) * num / den + y_min, dtype=np.float64)


def _f3_max(x7: float, x8: float, x9: float, u_min: float, u_max: float) -> float:
    """Maximum of ``f3`` on ``[u_min, u_max]`` (V)."""
    cand = [u_min, u_max]
    if x7 != 0.0:
        a_star = -x8 / (2.0 * x7)
        if u_min < a_star < u_max:
            cand.append(a_star)
    return max(x7 * a * a + x8 * a + x9 for a in cand)


def _try_surface(params: Sequence[float], **kw: float) -> SqrtSurface | None:
    if not all(math.isfinite(float(v)) for v in params):
        return None
    try:
        return SqrtSurface(*(float(v) for v in params), **kw)
    except ValueError:
        return None


# --------------------------------------------------------------------------------------
# input validation
# --------------------------------------------------------------------------------------
def _validate(
    levels: ArrayLike, y_grid: ArrayLike, frequency: float, y_min_source: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[str]]:
    warns: list[str] = []
    try:
        lv = np.asarray(levels, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"levels must be a 1-D array of input levels (V): {exc}") from exc
    if lv.ndim != 1:
        raise ValueError(f"levels must be 1-D, got shape {lv.shape}")
    if lv.size < 2:
        raise ValueError(f"levels needs at least 2 entries, got {lv.size}")
    if not np.all(np.isfinite(lv)):
        raise ValueError("levels must be finite")
    if not np.all(np.diff(lv) > 0):
        raise ValueError("levels must be strictly increasing")
    try:
        yg = np.array(y_grid, dtype=float)  # copy: the upper triangle is blanked below
    except (TypeError, ValueError) as exc:
        raise ValueError(f"y_grid must be a 2-D array of outputs (V): {exc}") from exc
    n = lv.size
    if yg.ndim != 2 or yg.shape != (n, n):
        raise ValueError(
            f"y_grid must have shape (len(levels), len(levels)) = ({n}, {n}), got {yg.shape}"
        )
    if np.any(np.isinf(yg)):
        raise ValueError("y_grid must not contain infinities (use NaN for missing points)")
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)
    if np.any(np.isfinite(yg[upper])):
        warns.append(
            "y_grid has finite values above the diagonal (beta > alpha); they were ignored"
        )
        yg[upper] = np.nan
    if not np.isfinite(yg[-1, -1]):
        raise ValueError("y_grid[-1, -1] = y(u_max, u_max) (the y_max constraint) is missing")
    if y_min_source == "corner":
        if not np.isfinite(yg[-1, 0]):
            raise ValueError("y_grid[-1, 0] = y(u_max, u_min) (the y_min constraint) is missing")
    elif y_min_source == "column_mean":
        if not np.any(np.isfinite(yg[:, 0])):
            raise ValueError("y_grid[:, 0] (the beta = u_min column, y_min) has no finite value")
    else:
        raise ValueError(f"y_min_source must be 'column_mean' or 'corner', got {y_min_source!r}")
    try:
        f = float(frequency)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"frequency must be a number (Hz), got {frequency!r}") from exc
    if math.isfinite(f) and f <= 0.0:
        raise ValueError(f"frequency must be positive (Hz) or nan, got {f}")
    return lv, yg, warns


# --------------------------------------------------------------------------------------
# public entry point
# --------------------------------------------------------------------------------------
def fit_sqrt_surface(
    levels: ArrayLike,
    y_grid: ArrayLike,
    *,
    frequency: float = float("nan"),
    refine: bool = True,
    y_min_source: str = "column_mean",
) -> SurfaceFitResult:
    """Identify the square-root FOD surface of Eq 3.2 from an FOD data grid (thesis 3.3.2).

    Parameters
    ----------
    levels : array_like, shape (n,)
        Strictly increasing input levels (V); ``levels[0]`` is ``u_min`` (``-u_hat``) and
        ``levels[-1]`` is ``u_max`` (``u_hat``).  The thesis uses the 21 levels -100, -90, ...,
        100 V.
    y_grid : array_like, shape (n, n)
        Measured FOD outputs (V): ``y_grid[i, j] = y(alpha=levels[i], beta=levels[j])`` for
        ``j <= i``; ``NaN`` elsewhere and for missing points.  Row ``i`` is the FOD curve that
        rose from negative saturation to ``alpha_i`` and fell through the ``beta_j``;
        ``y_grid[i, i]`` is ``y_alpha`` on the ascending major branch.  Finite values above the
        diagonal are ignored (with a warning in the result).
    frequency : float, optional
        Frequency of the identification input (Hz), stored in the surface; ``nan`` if unknown.
    refine : bool, optional
        Run the joint least-squares refinement of ``(xbar4, xbar5, x7, x8, x9)`` against all
        FOD points (step 4, beyond the thesis).  ``False`` returns the thesis' polynomial-stage
        surface.
    y_min_source : {'column_mean', 'corner'}, optional
        How ``y_min = y(u_hat, -u_hat)`` is taken.  ``'corner'`` uses the single point
        ``y_grid[-1, 0]`` as the thesis states; ``'column_mean'`` (default) averages the finite
        entries of the ``beta = u_min`` column, all of which measure the same output because
        every FOD curve merges at ``-u_hat`` (thesis 3.3.2), so the noise on ``y_min`` drops by
        ``sqrt(n)``.  ``y_max`` is always ``y_grid[-1, -1]``.

    Returns
    -------
    SurfaceFitResult
        The identified :class:`~preisach.surface.SqrtSurface` with the intermediate results
        and error measures.

    Raises
    ------
    ValueError
        If ``levels`` is not 1-D, finite and strictly increasing, if ``y_grid`` does not have
        shape ``(n, n)`` or lacks the constraint points, if fewer than three FOD curves have
        more than three points, or if no valid surface (``f3 < u_min`` on the input range) can
        be formed.

    Notes
    -----
    Steps (see the module docstring for details): per-curve Nelder-Mead fits of
    ``X1 + X2 sqrt(beta - X3)`` from the longest curve down, each warm-started from the
    previous; quadratic ``polyfit`` of ``X1, X2, X3`` in ``alpha``; the constrained surface of
    Eq 3.1-3.2 (``xbar4 = x4/x6``, ``xbar5 = x5/x6``, ``x7..x9`` from ``f3``); optional joint
    least-squares refinement.  If the polynomial-stage ``f3`` reaches ``u_min`` somewhere (the
    square roots would not be real), ``x9`` is lowered until it does not and a warning is
    recorded.

    """
    lv, yg, warns = _validate(levels, y_grid, frequency, y_min_source)
    n = lv.size
    u_min, u_max = float(lv[0]), float(lv[-1])
    freq = float(frequency)

    # all FOD data points (finite, j <= i)
    ii, jj = np.tril_indices(n)
    vals = yg[ii, jj]
    ok = np.isfinite(vals)
    a_pts, b_pts, y_pts = lv[ii[ok]], lv[jj[ok]], vals[ok]
    y_scale = float(max(np.ptp(y_pts), 1e-12)) if y_pts.size else 1.0

    # ---- step 1: per-curve fits, from alpha = u_max downward ---------------------------
    curves: list[_Curve] = []
    for i in range(n - 1, -1, -1):
        row = yg[i, : i + 1]
        m = np.isfinite(row)
        if int(m.sum()) >= _MIN_CURVE_POINTS:
            curves.append(_Curve(float(lv[i]), lv[: i + 1][m], row[m]))
    if len(curves) < 3:
        raise ValueError(
            f"y_grid: need at least 3 FOD curves with more than 3 points each for the quadratic "
            f"fits in alpha, got {len(curves)}"
        )

    params: list[NDArray[np.float64]] = []
    rms: list[float] = []
    prev: NDArray[np.float64] | None = None
    for c in curves:
        start = _linear_guess(c.beta, c.y) if prev is None else prev
        p, conv = _fit_curve(c, start, y_scale)
        if not conv:
            warns.append(f"Nelder-Mead did not converge on the FOD curve alpha = {c.alpha:g} V")
        c_span = float(c.beta.max() - c.beta.min())
        c_off = float(c.beta.min() - p[2])
        if c_off >= 0.99 * _OFFSET_MAX * c_span or c_off <= 1.01 * _OFFSET_MIN * c_span:
            warns.append(
                f"X3 of the FOD curve alpha = {c.alpha:g} V hit its bound (beta_min - X3 = "
                f"{c_off:.3g} V): the curve is {'straight' if c_off > c_span else 'singular'}"
            )
        params.append(p)
        rms.append(math.sqrt(_curve_sse(p, c.beta, c.y) / len(c.y)))
        prev = p
    order = np.argsort([c.alpha for c in curves])
    alphas = np.array([curves[k].alpha for k in order])
    cp = np.array([params[k] for k in order])
    curve_params = np.column_stack([alphas, cp])
    curve_n = np.array([len(curves[k].y) for k in order], dtype=np.int64)
    curve_rms = np.array([rms[k] for k in order])

    # ---- step 2: second-order polynomials in alpha -------------------------------------
    poly = np.concatenate([np.polyfit(alphas, cp[:, k], 2) for k in range(3)])
    x4, x5, x6, x7, x8, x9 = (float(v) for v in poly[3:])

    # ---- step 3: constrained surface (Eq 3.1-3.2) ---------------------------------------
    y_max = float(yg[-1, -1])
    if y_min_source == "corner":
        y_min = float(yg[-1, 0])
    else:
        col = yg[:, 0]
        y_min = float(np.mean(col[np.isfinite(col)]))
    if not y_max > y_min:
        raise ValueError(
            f"y_grid: y(u_max, u_max) = {y_max:g} V must exceed y(u_max, u_min) = {y_min:g} V"
        )
    kw = {"y_max": y_max, "y_min": y_min, "u_max": u_max, "u_min": u_min, "frequency": freq}

    if x6 == 0.0 or not math.isfinite(x6):
        raise ValueError("y_grid: the polynomial stage gave x6 = 0; Eq 3.2 cannot be formed")
    p0 = [x4 / x6, x5 / x6, x7, x8, x9]
    margin = 1e-3 * (u_max - u_min)
    f3max = _f3_max(x7, x8, x9, u_min, u_max)
    if f3max >= u_min - margin:
        p0[4] = x9 - (f3max - (u_min - margin))
        warns.append(
            f"polynomial-stage f3 reaches {f3max:.4g} V >= u_min = {u_min:g} V on the input "
            f"range; x9 was lowered from {x9:.6g} to {p0[4]:.6g} V"
        )
    unrefined = _try_surface(p0, **kw)

    def sse_of(p: Sequence[float]) -> float:
        r = _eq32(p, a_pts, b_pts, y_max, y_min, u_max, u_min) - y_pts
        return float(r @ r) if np.all(np.isfinite(r)) else math.inf

    unrefined_rss = math.sqrt(sse_of(p0)) if unrefined is not None else float("nan")
    if unrefined is None:
        warns.append("the polynomial-stage surface is not a valid Eq 3.2 surface")

    # ---- step 4: joint least-squares refinement -----------------------------------------
    final_p: list[float] | None = list(p0) if unrefined is not None else None
    refined = False
    if refine:
        s = max(abs(u_min), abs(u_max))
        # O(1) internal parameters: f2bar = 1 + c4 t^2 + c5 t, f3/s = c7 t^2 + c8 t + c9, t = a/s
        to_c = np.array([s * s, s, s, 1.0, 1.0 / s])
        c0 = np.asarray(p0, float) * to_c
        bad = np.full(y_pts.shape, 10.0 * y_scale)

        def resid(c: NDArray[np.float64]) -> NDArray[np.float64]:
            with np.errstate(all="ignore"):
                r = _eq32(c / to_c, a_pts, b_pts, y_max, y_min, u_max, u_min) - y_pts
            return r if np.all(np.isfinite(r)) else bad

        try:
            sol = least_squares(
                resid,
                c0,
                method="trf",
                x_scale=1.0,
                ftol=1e-15,
                xtol=1e-15,
                gtol=1e-15,
                max_nfev=2000,
            )
            cand = list(np.asarray(sol.x, float) / to_c)
            cand_surf = _try_surface(cand, **kw)
            base = sse_of(final_p) if final_p is not None else math.inf
            if cand_surf is None:
                warns.append("joint refinement left the valid region (f3 >= u_min); not used")
            elif sse_of(cand) <= base:
                final_p, refined = cand, True
                if not sol.success:
                    warns.append(f"joint refinement stopped early: {sol.message}")
            else:
                warns.append("joint refinement did not reduce the error; not used")
        except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - defensive
            warns.append(f"joint refinement failed: {exc}")

    if final_p is None:
        raise ValueError(
            "y_grid: no valid Eq 3.2 surface (f3 < u_min and f2bar != 0 on the input range) "
            "could be identified from these data"
        )

    # ---- errors ---------------------------------------------------------------------------
    with np.errstate(all="ignore"):
        r = _eq32(final_p, a_pts, b_pts, y_max, y_min, u_max, u_min) - y_pts
    sse = float(r @ r)
    npts = int(r.size)
    rss = math.sqrt(sse)
    surface = SqrtSurface(*(float(v) for v in final_p), fit_error=rss, **kw)  # type: ignore[misc]
    return SurfaceFitResult(
        surface=surface,
        curve_params=curve_params,
        curve_n_points=curve_n,
        curve_rms=curve_rms,
        poly=poly,
        rmse=math.sqrt(sse / npts),
        max_error=float(np.max(np.abs(r))),
        root_sum_sq_error=rss,
        n_points=npts,
        warnings=warns,
        unrefined_surface=unrefined,
        unrefined_root_sum_sq_error=unrefined_rss,
        refined=refined,
    )
