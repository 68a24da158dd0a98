"""Find first-order descending (FOD) and first-order reversal (FORC) curves in a recording.

The identification procedure of the thesis (section 2.6, Mayergoyz) needs the outputs
``y(alpha, beta)`` (volts) of first-order descending curves: the input goes to negative
saturation, rises monotonically to a turning value ``alpha`` and falls monotonically; the
output read when the falling input passes ``beta`` is ``y(alpha, beta)``.  The identification
input of the thesis (Fig 3.17, section 3.3.1) visits the 21 levels ``{-100 + 10 i}`` V: for every
``alpha_i`` the input goes to -100 V, rises to ``alpha_i`` and falls back to -100 V.

:func:`find_fod_curves` finds such curves in *any* recording ``(t, u, y)`` by themselves, and
:func:`find_forc_curves` finds the mirror image: first-order reversal curves from positive
saturation (fall to a reversal value ``beta``, then rise).

Algorithm
---------
1. **Turning points** with a hysteresis threshold: the input counts as having turned only
   when it reverses by more than ``reversal_tol`` volts from its running extreme (a "zig-zag"
   filter).  Smaller wiggles (noise, dither) do not end a monotone leg.  The extreme of a leg is
   its highest (lowest) sample; among equal samples the last one, so that a hold at a turning
   value ends where the next leg starts.  The default ``reversal_tol`` grows with the input
   noise: it is the larger of 0.5 % of the input range and ``NOISE_TOL_FACTOR`` (10) times
   the noise estimate ``sigma_u = 1.4826 MAD(diff(u, 2)) / sqrt(6)`` (V; second differences
   vanish on ramps and smooth legs, so only the noise is left), the noise term capped at 5 % of
   the range.  The default ``saturation_tol`` (1 % of the range) grows the same way, since
   noise also lowers the recorded ``u_min``.

   **Turning values.**  The highest sample of a noisy leg overstates the turning value (it is
   the largest of the noise samples near the top).  When ``sigma_u`` exceeds 0.01 % of the
   input range, the turning value is instead read from quadratics fitted to the samples on
   either side of the extreme (up to the farthest within ``reversal_tol`` of it, at least 20
   and at most 100 per side): the highest point of the lower of the two curves (the apex of a
   sharp turn, the vertex of a smooth one, the level of a hold), kept between ``reversal_tol``
   below and ``3 sigma_u`` above the extreme sample.  Otherwise (noise-free input) it is the
   extreme sample itself.  The turning *sample* (the diagonal node) is always the extreme one.
2. **Classification.**  Every turning point at the top of a leg (FOD; bottom for FORC) opens a
   candidate curve whose branch runs to the next turning point (or the end of the recording).
   It is a first-order curve when the leg before it starts at saturation: its lowest input is
   within ``saturation_tol`` of ``u_min`` (FORC: highest within ``saturation_tol`` of ``u_max``).
   Otherwise the curve is rejected with a reason ("did not start from negative saturation",
   "non-monotone rise" when the input did visit saturation but reversed by more than
   ``reversal_tol`` on its way up to this turning point, "too short" when the recording ends
   within ``reversal_tol`` of the turning point).
3. **Snapping.**  The turning value is snapped to the nearest grid level when it lies within
   ``level_tol`` of it; a first-order curve that turns elsewhere is *not* put on the grid but
   is kept as a raw curve (:attr:`FODData.raw_curves`) and reported.
4. **Reading the levels.**  On the branch the output is read at every grid level below
   ``alpha`` (FORC: above ``beta``) at the **first crossing**: the branch input is replaced by
   its monotone envelope (running minimum of the falling input, running maximum of the rising
   input) and the output is linearly interpolated between the last sample before and the first
   sample at or past the level.  Dither that moves the input back within ``reversal_tol`` after
   a crossing therefore never produces a second reading.  A level that the branch does not
   cross but whose end comes within ``level_tol`` of it (e.g. the saturation level of a sweep
   that turns exactly there) is read at the branch's extreme sample.  Levels the branch does
   not reach stay NaN (curves that stop early).  The diagonal node ``(i, i)`` is the output at
   the turning-point sample itself.
5. **Averaging.**  Repeated curves are averaged per node; ``count`` holds the number of
   readings and ``spread`` their sample standard deviation (``ddof = 1``, NaN for ``count < 2``).

Grid conventions
----------------
``levels`` is ascending (volts).  In both directions ``y_grid[i, j]`` with ``j <= i`` is the
output at the Preisach-plane point ``(alpha, beta) = (levels[i], levels[j])``; the upper
triangle ``j > i`` is always NaN.

* FOD (``direction == "descending"``): row ``i`` is the descending curve that turned at
  ``alpha = levels[i]``; ``y_grid[i, j]`` is read when the falling input passes
  ``beta = levels[j]``; ``y_grid[i, i]`` is the output at the turning point.  Node ``(0, 0)``
  (``alpha = beta = u_min``, a degenerate curve) is the output at the visits to negative
  saturation that start the used curves, so its ``count`` is the number of those visits.
* FORC (``direction == "ascending"``): column ``j`` is the reversal curve that reversed at
  ``beta = levels[j]``; ``y_grid[i, j]`` is read when the rising input passes
  ``alpha = levels[i]``; ``y_grid[j, j]`` is the output at the reversal point.  Node
  ``(n-1, n-1)`` is the output at the visits to positive saturation that start the used curves.

Both grids are therefore indexed the same way: ``i`` is the larger input ``alpha``, ``j`` the
smaller ``beta``, and a curve is a row (FOD) or a column (FORC).  The two are not the same
function: FOD data of a Preisach model are the ``y(alpha, beta)`` of the thesis, FORC data are
``y_max - 2 E(u_max, beta) + 2 E(alpha, beta)`` with the Everett function
``E(alpha, beta) = (y(alpha, alpha) - y(alpha, beta)) / 2`` of the FOD surface.

Levels
------
With ``levels=None`` the grid is inferred: the turning values of the first-order curves and
the input at the saturation visits that start them are clustered (values closer than
``level_tol`` form one cluster); when there are at least three clusters and they all lie within
``level_tol`` of a regular grid ``a + k h`` (least-squares fit; the grid positions ``k`` come
from the gaps between neighbouring clusters), that grid is used, extended over the recording's
input range and clipped to it: no level outside ``[u_min, u_max]`` widened by three times the
input noise estimate ``sigma_u`` (noise can leave the sample at a turning level just below it).
Its offset and step are rounded to the coarsest of about ``h``, ``h / 10``, ``h / 100``,
``h / 1000`` that moves the fitted grid by at most ``level_tol / 2`` and still fits every
cluster within ``level_tol``, so the thesis grid comes out as exactly ``-100 + 10 i`` even from
dithered data.  Otherwise 21 equally spaced levels over ``[u_min, u_max]`` are used; turning
points are then usually off the grid and the curves are only available as raw curves
(:attr:`FODData.raw_curves`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..recording import SampledData

__all__ = ["CurveRecord", "FODData", "find_fod_curves", "find_forc_curves"]

#: Number of levels used when no regular grid can be inferred from the turning values.
DEFAULT_N_LEVELS = 21

#: Default ``reversal_tol`` and ``saturation_tol`` are at least this many times the estimated
#: input noise (V) ...
NOISE_TOL_FACTOR = 10.0

#: ... but the noise term is at most this fraction of the input range.
MAX_NOISE_TOL_FRACTION = 0.05

#: Input noise below this fraction of the input range is negligible: turning values are then
#: the extreme samples themselves.
NOISE_NEGLIGIBLE = 1e-4

#: At least / at most this many samples per side enter the local fit of an extreme.
_FIT_MIN, _FIT_MAX = 20, 100


# ------------------------------------------------------------------------------------------
# result types
# ------------------------------------------------------------------------------------------
@dataclass
class CurveRecord:
    """One candidate curve found in a recording.

    Attributes
    ----------
    index : int
        Ordinal of the candidate in the recording (0, 1, ...).
    start : int
        Sample index where the curve's history starts: the turning point at saturation before
        the first leg (or the start of the first leg / of the recording when rejected).
    turn : int
        Sample index of the turning point (the top of an FOD, the bottom of a FORC).
    stop : int
        Last sample index (inclusive) of the branch after the turning point.
    t_start, t_turn, t_stop : float
        Times (s) of ``start``, ``turn`` and ``stop``.
    turning_value : float
        Input at the turning point (V): ``alpha`` of an FOD, the reversal ``beta`` of a FORC.
        The extreme sample ``u[turn]``, or for a noisy input the estimate from the samples
        around it (see "Turning values" in the module docstring).
    level : int or None
        Index into :attr:`FODData.levels` the turning value was snapped to, ``None`` when the
        curve is not on the grid (or not a first-order curve).
    first_order : bool
        ``True`` when the curve is a genuine first-order curve (start at saturation, monotone
        first leg, a branch after the turning point), on the grid or not.
    used : bool
        ``True`` when the curve contributed to :attr:`FODData.y_grid`.
    reason : str
        Why the curve was used or rejected, in words.
    n_nodes : int
        Number of grid nodes the curve contributed (including its diagonal node).
    u, y : ndarray
        Input (V) and output (V) samples of the branch, ``turn .. stop`` inclusive (raw, not
        the monotone envelope).
    direction : str
        ``"descending"`` (FOD) or ``"ascending"`` (FORC).

    """

    index: int
    start: int
    turn: int
    stop: int
    t_start: float
    t_turn: float
    t_stop: float
    turning_value: float
    level: int | None
    first_order: bool
    used: bool
    reason: str
    n_nodes: int
    u: NDArray[np.float64]
    y: NDArray[np.float64]
    direction: str

    @property
    def alpha(self) -> float:
        """Turning value ``alpha`` (V) of an FOD curve; NaN for a FORC (alpha varies)."""
        return self.turning_value if self.direction == "descending" else math.nan

    @property
    def beta(self) -> float:
        """Reversal value ``beta`` (V) of a FORC; NaN for an FOD curve (beta varies)."""
        return self.turning_value if self.direction == "ascending" else math.nan


@dataclass
class FODData:
    """First-order curve data found in a recording.

    Attributes
    ----------
    levels : ndarray, shape (n,)
        Ascending input levels (V).
    y_grid : ndarray, shape (n, n)
        Mean output (V); ``y_grid[i, j] = y(alpha=levels[i], beta=levels[j])`` for ``j <= i``,
        NaN where not measured and in the upper triangle.  A FOD curve is a row, a FORC a
        column; see the module docstring for the two conventions.
    count : ndarray of int, shape (n, n)
        Number of readings averaged per node (0 where not measured).
    spread : ndarray, shape (n, n)
        Sample standard deviation (V, ``ddof = 1``) of the readings per node; NaN where
        ``count < 2``.
    curves : list of CurveRecord
        Every candidate curve, used or not, in the order of the recording.
    direction : str
        ``"descending"`` (FOD, :func:`find_fod_curves`) or ``"ascending"`` (FORC,
        :func:`find_forc_curves`).
    u_min, u_max : float
        Input range (V) taken as negative and positive saturation.
    saturation_tol, reversal_tol, level_tol : float
        Tolerances (V) actually used.
    levels_source : str
        How ``levels`` were obtained ("given", "regular grid inferred ...", "fallback ...").
    n_samples : int
        Number of samples in the recording.
    input_noise : float
        Estimated standard deviation (V) of the noise on the input, ``1.4826 MAD(diff(u, 2)) /
        sqrt(6)``; 0 for a noise-free piecewise-linear input.
    input_units, output_units : str
        Units of the input and output: the recording's ``input_units``/``output_units``
        metadata when a recording was given (e.g. tesla and A m^2 for FORC data of a
        magnetometer, see :mod:`preisach.forc`), else ``"V"``.  "V" above means these units.

    """

    levels: NDArray[np.float64]
    y_grid: NDArray[np.float64]
    count: NDArray[np.int64]
    spread: NDArray[np.float64]
    curves: list[CurveRecord]
    direction: str
    u_min: float
    u_max: float
    saturation_tol: float
    reversal_tol: float
    level_tol: float
    levels_source: str
    n_samples: int
    input_noise: float = 0.0
    input_units: str = "V"
    output_units: str = "V"

    @property
    def used_curves(self) -> list[CurveRecord]:
        """Curves that contributed to the grid."""
        return [c for c in self.curves if c.used]

    @property
    def rejected_curves(self) -> list[CurveRecord]:
        """Curves that did not contribute to the grid (with their ``reason``)."""
        return [c for c in self.curves if not c.used]

    @property
    def raw_curves(self) -> list[tuple[float, NDArray[np.float64], NDArray[np.float64]]]:
        """Every first-order curve as ``(turning value, u along branch, y along branch)``.

        All in volts.  For FOD data this is ``(alpha, beta samples, y samples)``, for FORC data
        ``(beta, alpha samples, y samples)``.  Includes curves whose turning value is not on
        the grid; the samples are raw (noise and dither included).
        """
        return [(c.turning_value, c.u, c.y) for c in self.curves if c.first_order]

    def nodes(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Measured nodes as flat arrays ``(alpha, beta, y, count)`` (V, V, V, 1)."""
        i, j = np.nonzero(self.count > 0)
        return self.levels[i], self.levels[j], self.y_grid[i, j], self.count[i, j]

    def report(self) -> str:
        """Readable multi-line summary: settings, grid coverage and one line per curve."""

        def _v(x: float) -> str:  # an input value
            return _fmt(x, self.input_units)

        n = self.levels.size
        fod = self.direction == "descending"
        kind = "FOD (first-order descending)" if fod else "FORC (first-order reversal)"
        sat = "negative" if fod else "positive"
        sat_line = (
            f"u <= {_v(self.u_min + self.saturation_tol)}"
            if fod
            else f"u >= {_v(self.u_max - self.saturation_tol)}"
        )
        n_nodes = n * (n + 1) // 2
        measured = int(np.count_nonzero(self.count))
        repeated = int(np.count_nonzero(self.count >= 2))
        finite_spread = self.spread[np.isfinite(self.spread)]
        spread_txt = (
            _fmt(float(finite_spread.max()), self.output_units) if finite_spread.size else "n/a"
        )
        spacing = np.diff(self.levels)
        spacing_txt = (
            f"step {_v(float(spacing[0]))}" if np.allclose(spacing, spacing[0]) else "irregular"
        )
        used = self.used_curves
        off_grid = [c for c in self.curves if c.first_order and not c.used]
        lines = [
            f"{kind} curves in a recording of {self.n_samples} samples",
            f"  input range {_v(self.u_min)} .. {_v(self.u_max)}; {sat} saturation: {sat_line}",
            f"  tolerances: saturation {_v(self.saturation_tol)}, reversal "
            f"{_v(self.reversal_tol)}, level {_v(self.level_tol)}; input noise estimate "
            f"{_v(self.input_noise)}",
            f"  levels: {n} from {_v(float(self.levels[0]))} to {_v(float(self.levels[-1]))}, "
            f"{spacing_txt} ({self.levels_source})",
            f"  nodes measured: {measured} of {n_nodes}; repeated (count >= 2): {repeated}; "
            f"max spread: {spread_txt}",
            f"  curves: {len(self.curves)} found, {len(used)} used, "
            f"{len(self.curves) - len(used)} rejected ({len(off_grid)} of them first-order "
            "but off the grid, kept as raw curves)",
        ]
        if self.curves:
            lines.append(
                f"  {'#':>4}  {'t [s]':>21}  {'turn [' + self.input_units + ']':>10}  "
                f"{'level':>5}  {'nodes':>5}  status"
            )
        for c in self.curves:
            lvl = "-" if c.level is None else str(c.level)
            status = "used" if c.used else "rejected"
            lines.append(
                f"  {c.index:>4}  {c.t_start:>9.4g} .. {c.t_stop:<9.4g}  "
                f"{c.turning_value:>10.5g}  {lvl:>5}  {c.n_nodes:>5}  {status}: {c.reason}"
            )
        return "\n".join(lines)


# ------------------------------------------------------------------------------------------
# public functions
# ------------------------------------------------------------------------------------------
def find_fod_curves(
    t: ArrayLike | SampledData,
    u: ArrayLike | None = None,
    y: ArrayLike | None = None,
    levels: ArrayLike | None = None,
    *,
    u_min: float | None = None,
    u_max: float | None = None,
    saturation_tol: float | None = None,
    reversal_tol: float | None = None,
    level_tol: float | None = None,
) -> FODData:
    """Find the first-order descending (FOD) curves in a recording and grid their outputs.

    Parameters
    ----------
    t : array_like or recording
        Sample times (s), or an object with attributes ``t``, ``u`` and ``y`` (e.g.
        ``preisach.recording.Recording``); then ``u`` and ``y`` must not be given.
    u, y : array_like
        Input (V) and output (V) samples, same length as ``t``.
    levels : array_like, optional
        Ascending grid of input levels (V).  ``None``: inferred (see module docstring): the
        regular grid of the turning values when there is one, else 21 equally spaced levels
        over ``[u_min, u_max]``.
    u_min, u_max : float, optional
        Negative and positive saturation (V); default: the recording's input range.
    saturation_tol : float, optional
        A leg starts at negative saturation when its lowest input is ``<= u_min +
        saturation_tol`` (V).  Default: 1 % of ``u_max - u_min``, or 10 times the estimated
        input noise when that is larger (at most 5 % of ``u_max - u_min``).
    reversal_tol : float, optional
        The input must reverse by more than this (V) for a turning point (hysteresis of the
        turning-point detector).  Default: 0.5 % of ``u_max - u_min``, or 10 times the
        estimated input noise when that is larger (at most 5 % of ``u_max - u_min``).
    level_tol : float, optional
        A turning value (or the end of a branch) within this distance (V) of a grid level is
        snapped to it; must be below half the smallest level spacing.  Default: the smaller of
        0.5 % of ``u_max - u_min`` and a quarter of the smallest level spacing.

    Returns
    -------
    FODData
        ``y_grid[i, j] = y(alpha=levels[i], beta=levels[j])`` (V) for ``j <= i``, with counts,
        spreads and a record of every candidate curve (``direction == "descending"``).

    Raises
    ------
    ValueError
        On arrays of different lengths, fewer than 2 samples, non-finite values, decreasing
        ``t``, bad levels or tolerances; the message names the argument.

    """
    return _find(t, u, y, levels, +1.0, u_min, u_max, saturation_tol, reversal_tol, level_tol)


def find_forc_curves(
    t: ArrayLike | SampledData,
    u: ArrayLike | None = None,
    y: ArrayLike | None = None,
    levels: ArrayLike | None = None,
    *,
    u_min: float | None = None,
    u_max: float | None = None,
    saturation_tol: float | None = None,
    reversal_tol: float | None = None,
    level_tol: float | None = None,
) -> FODData:
    """Find the first-order reversal curves (FORC) from positive saturation in a recording.

    The mirror image of :func:`find_fod_curves`: a visit to positive saturation (input
    ``>= u_max - saturation_tol``), a monotone fall to a reversal value ``beta``, a monotone
    rise; the output is read when the rising input passes the levels ``alpha > beta``.

    Parameters
    ----------
    t, u, y, levels, u_min, u_max, saturation_tol, reversal_tol, level_tol
        As for :func:`find_fod_curves`, with the roles of the saturations mirrored.

    Returns
    -------
    FODData
        ``direction == "ascending"``; ``y_grid[i, j]`` (V) is the output at input
        ``alpha = levels[i]`` on the rising branch after the reversal at ``beta = levels[j]``
        (``j <= i``); a curve is a column, ``y_grid[j, j]`` the output at the reversal and
        ``y_grid[n-1, n-1]`` the output at positive saturation.

    Raises
    ------
    ValueError
        As for :func:`find_fod_curves`.

    """
    return _find(t, u, y, levels, -1.0, u_min, u_max, saturation_tol, reversal_tol, level_tol)


# ------------------------------------------------------------------------------------------
# implementation
# ------------------------------------------------------------------------------------------
def _fmt(x: float, unit: str = "V") -> str:
    """Format a value in ``unit`` (the input's, volts unless the recording says otherwise)."""
    if x == 0.0:
        x = 0.0  # no "-0"
    return f"{x:.6g} {unit}"


@dataclass(frozen=True)
class _Frame:
    """Wording and sign of the working frame ``s = sign * u`` (FOD frame: sign = +1)."""

    sign: float
    unit: str = "V"

    @property
    def fod(self) -> bool:
        return self.sign > 0

    @property
    def sat(self) -> str:
        return "negative saturation" if self.fod else "positive saturation"

    @property
    def first_leg(self) -> str:
        return "rise" if self.fod else "fall"

    @property
    def branch(self) -> str:
        return "falling branch" if self.fod else "rising branch"

    @property
    def turn_name(self) -> str:
        return "turning value" if self.fod else "reversal value"

    @property
    def bound(self) -> str:
        return "u_min" if self.fod else "u_max"

    def v(self, s: float) -> str:
        """Format a working-frame value in the user's input unit."""
        return _fmt(self.sign * float(s), self.unit)


def _as_1d(name: str, a: ArrayLike) -> NDArray[np.float64]:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of numbers: {exc}") from None
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    return arr


def _validate(
    t: ArrayLike | SampledData, u: ArrayLike | None, y: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    if isinstance(t, SampledData):  # a recording (an ndarray has no attributes t, u, y)
        if u is not None or y is not None:
            raise TypeError(
                "u and y must not be given when the first argument is a recording with "
                "attributes t, u, y (pass levels by keyword)"
            )
        ta, ua, ya = _as_1d("t", t.t), _as_1d("u", t.u), _as_1d("y", t.y)
    elif u is None or y is None:
        raise TypeError("give t, u and y arrays, or a recording with attributes t, u, y")
    else:
        ta, ua, ya = _as_1d("t", t), _as_1d("u", u), _as_1d("y", y)
    if not (ta.size == ua.size == ya.size):
        raise ValueError(
            f"t, u and y must have the same length, got t: {ta.size}, u: {ua.size}, y: {ya.size}"
        )
    if ta.size < 2:
        raise ValueError(f"t, u and y need at least 2 samples, got {ta.size}")
    for name, arr in (("t", ta), ("u", ua), ("y", ya)):
        bad = ~np.isfinite(arr)
        if bad.any():
            k = int(np.argmax(bad))
            raise ValueError(f"{name} contains NaN or infinite values (first at sample {k})")
    if np.any(np.diff(ta) < 0):
        k = int(np.argmax(np.diff(ta) < 0))
        raise ValueError(f"t must be non-decreasing (t[{k + 1}] < t[{k}])")
    return ta, ua, ya


def _tol(name: str, value: float | None, default: float, allow_zero: bool) -> float:
    if value is None:
        return default
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        need = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {need}, got {value!r}")
    return v


def _input_noise(u: NDArray[np.float64]) -> float:
    """Robust estimate (V) of the standard deviation of white noise on the input.

    ``1.4826 MAD(diff(u, 2)) / sqrt(6)``: second differences vanish on ramps (and are small on
    smooth legs), while white noise of standard deviation ``sigma`` gives them ``sqrt(6) sigma``.
    """
    if u.size < 3:
        return 0.0
    d2 = np.diff(u, 2)
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return 1.4826 * mad / math.sqrt(6.0)


def _robust_extreme(
    s: NDArray[np.float64], k: int, left: int, right: int, kind: int, band: float, noise: float
) -> float:
    """Estimate the turning value (working frame) at the extreme sample ``k`` of a noisy input.

    ``kind`` is +1 at a top, -1 at a bottom; ``left`` and ``right`` bound the two legs (the
    neighbouring turning points).  A quadratic is fitted to the samples on each side, up to the
    farthest one within ``band`` (V) of the extreme (at least ``_FIT_MIN``, at most
    ``_FIT_MAX`` per side); the turning value is the highest point of the lower of the two
    curves between the window ends (the apex of a sharp turn, the vertex of a smooth one, the
    level of a hold), kept within ``[extreme - band, extreme + 3 noise]`` (noise can leave the
    sample at the turning point below the turning value).
    """
    g = kind * s  # the extreme is a maximum of g
    peak = float(g[k])

    def side(seg: NDArray[np.float64]) -> NDArray[np.float64]:
        within = np.nonzero(seg >= peak - band)[0]
        n = int(within[-1]) + 1 if within.size else 1
        return seg[: min(max(n, min(_FIT_MIN, seg.size)), _FIT_MAX)]

    gl = side(g[max(left, k - _FIT_MAX) : k + 1][::-1])  # from k backwards
    gr = side(g[k : min(right, k + _FIT_MAX) + 1])  # from k forwards
    fits = []
    for seg, sgn in ((gl, -1.0), (gr, 1.0)):
        if seg.size >= 4:
            x = sgn * np.arange(seg.size, dtype=float) / seg.size  # scaled for conditioning
            fits.append((np.polyfit(x, seg, 2), float(seg.size)))
    if not fits:
        return float(s[k])
    x = np.linspace(-(gl.size - 1), gr.size - 1, 4 * (gl.size + gr.size) + 1)
    curves = [np.polyval(c, x / n) for c, n in fits]
    est = float(np.max(np.minimum.reduce(curves)))
    return kind * min(max(est, peak - band), peak + 3.0 * noise)


def _turning_points(s: NDArray[np.float64], tol: float) -> tuple[list[int], list[int], int]:
    """Zig-zag turning points of ``s`` with hysteresis ``tol``.

    Returns ``(idx, kind, n_confirmed)``: sample indices and kinds (+1 top, -1 bottom),
    alternating; the first ``n_confirmed`` entries are confirmed turning points, the last one
    (if any beyond) is the pending extreme of the leg the recording ends in.
    """
    n = s.size
    d = np.diff(s)
    left, right = d[:-1], d[1:]
    mid = np.nonzero(((left >= 0) & (right <= 0)) | ((left <= 0) & (right >= 0)))[0] + 1
    cand = np.concatenate(([0], mid, [n - 1])).tolist()
    vals = s[cand].tolist()
    idx: list[int] = []
    kind: list[int] = []
    direction = 0
    hi = lo = ext = 0  # positions into cand / vals
    for p in range(1, len(vals)):
        v = vals[p]
        if direction > 0:
            if v >= vals[ext]:
                ext = p
            elif vals[ext] - v > tol:
                idx.append(cand[ext])
                kind.append(+1)
                direction, ext = -1, p
        elif direction < 0:
            if v <= vals[ext]:
                ext = p
            elif v - vals[ext] > tol:
                idx.append(cand[ext])
                kind.append(-1)
                direction, ext = +1, p
        else:
            if v >= vals[hi]:
                hi = p
            if v <= vals[lo]:
                lo = p
            if v - vals[lo] > tol:
                idx.append(cand[lo])
                kind.append(-1)
                direction, ext = +1, p
            elif vals[hi] - v > tol:
                idx.append(cand[hi])
                kind.append(+1)
                direction, ext = -1, p
    n_confirmed = len(idx)
    if direction != 0:
        idx.append(cand[ext])
        kind.append(direction)
    return idx, kind, n_confirmed


@dataclass
class _Candidate:
    start: int
    turn: int
    stop: int
    first_order: bool
    reason: str


def _classify(
    s: NDArray[np.float64],
    t: NDArray[np.float64],
    idx: list[int],
    kind: list[int],
    n_confirmed: int,
    sat_level: float,
    rev_tol: float,
    fr: _Frame,
) -> list[_Candidate]:
    """Candidate curves (one per top turning point) with first-order status and reason."""
    n = s.size
    # positions (into idx) of bottoms at saturation
    sat_pos = [m for m, (k, kd) in enumerate(zip(idx, kind)) if kd < 0 and s[k] <= sat_level]
    out: list[_Candidate] = []
    for m, (k, kd) in enumerate(zip(idx, kind)):
        if kd < 0:
            continue
        if m >= n_confirmed:  # the recording ends before the input turned back
            start = idx[m - 1] if m > 0 else 0
            out.append(
                _Candidate(
                    start,
                    k,
                    n - 1,
                    False,
                    "too short: the recording ends within reversal_tol = "
                    f"{_fmt(rev_tol, fr.unit)} of the {fr.turn_name} {fr.v(s[k])} (no {fr.branch})",
                )
            )
            continue
        stop = idx[m + 1]
        if m == 0:
            out.append(
                _Candidate(
                    0,
                    k,
                    stop,
                    False,
                    f"did not start from {fr.sat}: the recording begins at {fr.v(s[0])} "
                    f"(t = {t[0]:.6g} s), at or before the {fr.turn_name} {fr.v(s[k])}, with no "
                    f"visit to {fr.sat}",
                )
            )
            continue
        valley = idx[m - 1]
        if s[valley] <= sat_level:
            out.append(_Candidate(valley, k, stop, True, ""))
            continue
        q = bisect.bisect_left(sat_pos, m) - 1
        p_sat = sat_pos[q] if q >= 0 else -1
        # a non-monotone first leg: saturation, then a leg towards this turning point with
        # reversals that all stay below it
        if p_sat >= 0 and max(s[idx[p]] for p in range(p_sat + 1, m, 2)) < s[k]:
            rev, back = idx[p_sat + 1], idx[p_sat + 2]
            out.append(
                _Candidate(
                    valley,
                    k,
                    stop,
                    False,
                    f"non-monotone {fr.first_leg}: after {fr.sat} at t = {t[idx[p_sat]]:.6g} s the "
                    f"input reversed at {fr.v(s[rev])} (t = {t[rev]:.6g} s) back to "
                    f"{fr.v(s[back])} before reaching the {fr.turn_name} {fr.v(s[k])}",
                )
            )
        else:
            out.append(
                _Candidate(
                    valley,
                    k,
                    stop,
                    False,
                    f"did not start from {fr.sat}: the {fr.first_leg} began at {fr.v(s[valley])} "
                    f"(t = {t[valley]:.6g} s), not within saturation_tol of {fr.bound}",
                )
            )
    return out


def _infer_levels(
    values: NDArray[np.float64],
    s_min: float,
    s_max: float,
    level_tol: float,
    margin: float = 0.0,
) -> NDArray[np.float64] | None:
    """Regular grid through the clustered ``values`` (working frame), or None.

    The grid is clipped to ``[s_min - margin, s_max + margin]``.
    """
    if values.size < 3:
        return None
    v = np.sort(values)
    cut = np.nonzero(np.diff(v) > level_tol)[0] + 1
    centres = np.array([np.median(c) for c in np.split(v, cut)])
    if centres.size < 3:
        return None
    # integer grid positions from the gaps between neighbours (in units of the smallest gap,
    # so that errors of noisy centres do not accumulate), then a least-squares fit of a + k h;
    # refine
    gaps = np.diff(centres)
    k = np.concatenate(([0.0], np.cumsum(np.round(gaps / float(np.min(gaps))))))
    for _ in range(3):
        A = np.column_stack((np.ones_like(k), k))
        (a, h), *_ = np.linalg.lstsq(A, centres, rcond=None)
        a, h = float(a), float(h)
        if not h > 2.0 * level_tol:
            return None
        k = np.round((centres - a) / h)
    if np.max(np.abs(centres - (a + k * h))) > level_tol:
        return None
    e_top = int(math.floor(math.log10(h))) - 1
    for dec in range(-e_top - 1, -e_top + 3):  # round to ~h .. h/1000, coarsest that fits:
        # within level_tol / 2 of the fitted grid (which averages the noise of the centres)
        # and within level_tol of every centre
        a_r, h_r = float(np.round(a, dec)), float(np.round(h, dec))
        moved = float(np.max(np.abs((a_r + k * h_r) - (a + k * h))))
        if (
            h_r > 0
            and moved <= 0.5 * level_tol
            and np.max(np.abs(centres - (a_r + k * h_r))) <= level_tol
        ):
            a, h = a_r, h_r
            break
    k_lo = min(int(k.min()), int(math.ceil((s_min - level_tol - a) / h)))
    k_hi = max(int(k.max()), int(math.floor((s_max + level_tol - a) / h)))
    grid = a + h * np.arange(k_lo, k_hi + 1, dtype=float)
    # never beyond the input range, widened by the noise that can hide a level's visit (and by
    # the round-off of a + k h)
    eps = margin + 1e-9 * (s_max - s_min)
    grid = grid[(grid >= s_min - eps) & (grid <= s_max + eps)]
    return grid if grid.size >= 3 else None


def _read_branch(
    bs: NDArray[np.float64],
    by: NDArray[np.float64],
    lv: NDArray[np.float64],
    level_tol: float,
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Read a falling branch (working frame) at the ascending levels ``lv`` (all below the top).

    Returns the indices into ``lv`` that were reached and the outputs read there.
    """
    env = np.minimum.accumulate(bs)  # monotone (non-increasing) envelope
    pos = np.searchsorted(-env, -lv, side="left")  # first sample with env <= level
    reached = pos < bs.size
    jr = np.nonzero(reached)[0]
    k1 = pos[jr]
    k0 = np.maximum(k1 - 1, 0)
    u0, u1 = bs[k0], bs[k1]
    denom = u0 - u1
    w = np.divide(u0 - lv[jr], denom, out=np.zeros_like(denom), where=denom > 0)
    vals = by[k0] + w * (by[k1] - by[k0])
    # end snap: the highest level not crossed, if the branch ends within level_tol of it
    miss = np.nonzero(~reached)[0]
    if miss.size:
        jm = int(miss[-1])
        if env[-1] - lv[jm] <= level_tol:
            jr = np.append(jr, jm)
            k_end = bs.size - 1 - int(np.argmin(bs[::-1]))  # last sample at the branch's extreme
            vals = np.append(vals, by[k_end])
    return jr, vals


def _find(
    t: ArrayLike | SampledData,
    u: ArrayLike | None,
    y: ArrayLike | None,
    levels: ArrayLike | None,
    sign: float,
    u_min: float | None,
    u_max: float | None,
    saturation_tol: float | None,
    reversal_tol: float | None,
    level_tol: float | None,
) -> FODData:
    ta, ua, ya = _validate(t, u, y)
    meta = getattr(t, "metadata", None) if u is None else None
    units = [
        str(meta.get(k) or "V") if isinstance(meta, dict) else "V"
        for k in ("input_units", "output_units")
    ]
    fr = _Frame(sign, units[0])
    lo = float(ua.min()) if u_min is None else float(u_min)
    hi = float(ua.max()) if u_max is None else float(u_max)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError("u_min and u_max must be finite")
    if not hi > lo:
        raise ValueError(f"u_max ({hi}) must exceed u_min ({lo}); u must not be constant")
    span = hi - lo
    noise = _input_noise(ua)
    noise_tol = min(NOISE_TOL_FACTOR * noise, MAX_NOISE_TOL_FRACTION * span)
    sat_tol = _tol("saturation_tol", saturation_tol, max(0.01 * span, noise_tol), allow_zero=True)
    rev_tol = _tol("reversal_tol", reversal_tol, max(0.005 * span, noise_tol), allow_zero=False)
    lvl_tol_user = level_tol is not None
    lvl_tol = _tol("level_tol", level_tol, 0.005 * span, allow_zero=True)

    # working frame: FOD curves descend from a top turning point after negative saturation
    s = sign * ua
    s_min, s_max = (lo, hi) if sign > 0 else (-hi, -lo)
    sat_level = s_min + sat_tol

    idx, kind, n_conf = _turning_points(s, rev_tol)
    cands = _classify(s, ta, idx, kind, n_conf, sat_level, rev_tol, fr)
    # turning values (working frame) robust to input noise, per turning-point sample
    tv: dict[int, float] = {}
    if noise > NOISE_NEGLIGIBLE * span:
        for p, (k, kd) in enumerate(zip(idx, kind)):
            left = idx[p - 1] if p > 0 else 0
            right = idx[p + 1] if p + 1 < len(idx) else s.size - 1
            tv[k] = _robust_extreme(s, k, left, right, kd, rev_tol, noise)

    def value(k: int) -> float:
        return tv.get(k, float(s[k]))

    # ---- levels (working frame, ascending) ----
    if levels is not None:
        lv_user = _as_1d("levels", levels)
        if lv_user.size < 2:
            raise ValueError(f"levels needs at least 2 entries, got {lv_user.size}")
        if not np.all(np.isfinite(lv_user)):
            raise ValueError("levels contains NaN or infinite values")
        if np.any(np.diff(lv_user) <= 0):
            raise ValueError("levels must be strictly increasing")
        lv = lv_user.copy() if sign > 0 else -lv_user[::-1]
        source = "given"
    else:
        firsts = [c for c in cands if c.first_order]
        vals = np.array(
            [value(c.turn) for c in firsts] + [value(c.start) for c in firsts], dtype=float
        )
        inferred = _infer_levels(vals, s_min, s_max, lvl_tol, 3.0 * noise)
        if inferred is not None:
            lv = inferred
            source = f"regular grid inferred from {len(firsts)} first-order curves"
        else:
            grid = np.linspace(lo, hi, DEFAULT_N_LEVELS)
            lv = grid if sign > 0 else -grid[::-1]
            source = (
                f"fallback: {DEFAULT_N_LEVELS} equally spaced levels over the input "
                "range; the turning values are not on a regular grid"
            )
    min_step = float(np.min(np.diff(lv)))
    if lvl_tol_user:
        if lvl_tol >= 0.5 * min_step:
            raise ValueError(
                f"level_tol ({lvl_tol}) must be smaller than half the smallest level spacing "
                f"({0.5 * min_step})"
            )
    else:
        lvl_tol = min(lvl_tol, 0.25 * min_step)
    n = lv.size

    # ---- read the curves ----
    flat: list[NDArray[np.intp]] = []
    obs: list[NDArray[np.float64]] = []
    records: list[CurveRecord] = []
    for c_no, c in enumerate(cands):
        k, stop = c.turn, c.stop
        bs, by = s[k : stop + 1], ya[k : stop + 1]
        level: int | None = None
        used = False
        n_nodes = 0
        reason = c.reason
        turn_value = value(k)
        if c.first_order:
            i = int(np.argmin(np.abs(lv - turn_value)))
            if abs(lv[i] - turn_value) > lvl_tol:
                reason = (
                    f"{fr.turn_name} {fr.v(turn_value)} not on the grid (nearest level "
                    f"{fr.v(lv[i])}, level_tol = {_fmt(lvl_tol, fr.unit)}); kept as a raw curve"
                )
            else:
                level, used = i, True
                jr, vals = _read_branch(bs, by, lv[:i], lvl_tol)
                rows = np.concatenate((jr * 0 + i, [i]))
                cols = np.concatenate((jr, [i]))
                flat.append(rows * n + cols)
                obs.append(np.concatenate((vals, [by[0]])))
                n_nodes = cols.size
                if abs(value(c.start) - lv[0]) <= lvl_tol:  # saturation visit: node (0, 0)
                    flat.append(np.array([0], dtype=np.intp))
                    obs.append(np.array([ya[c.start]]))
                reason = f"ok, {n_nodes} nodes"
                if i > 0 and (jr.size == 0 or jr.min() > 0):
                    reason += f"; stops early at {fr.v(float(bs.min()))}, levels beyond not reached"
        records.append(
            CurveRecord(
                index=c_no,
                start=c.start,
                turn=k,
                stop=stop,
                t_start=float(ta[c.start]),
                t_turn=float(ta[k]),
                t_stop=float(ta[stop]),
                turning_value=fr.sign * turn_value + 0.0,
                level=level,
                first_order=c.first_order,
                used=used,
                reason=reason,
                n_nodes=n_nodes,
                u=ua[k : stop + 1].copy(),
                y=by.copy(),
                direction="descending" if sign > 0 else "ascending",
            )
        )

    # ---- average per node ----
    if flat:
        fi = np.concatenate(flat).astype(np.intp)
        fv = np.concatenate(obs)
    else:
        fi = np.zeros(0, dtype=np.intp)
        fv = np.zeros(0)
    cnt = np.bincount(fi, minlength=n * n)
    tot = np.bincount(fi, weights=fv, minlength=n * n)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, tot / np.maximum(cnt, 1), np.nan)
        ss = np.bincount(fi, weights=(fv - mean[fi]) ** 2, minlength=n * n)
        std = np.where(cnt >= 2, np.sqrt(ss / np.maximum(cnt - 1, 1)), np.nan)
    mean, cnt, std = mean.reshape(n, n), cnt.reshape(n, n).astype(np.int64), std.reshape(n, n)

    if sign > 0:
        levels_out = lv
    else:  # back from the mirrored frame: Y[i, j] = Y'[n-1-j, n-1-i]
        levels_out = -lv[::-1] + 0.0  # + 0.0: no -0.0 levels
        mean, cnt, std = (a[::-1, ::-1].T.copy() for a in (mean, cnt, std))
        for r in records:
            if r.level is not None:
                r.level = n - 1 - r.level
    return FODData(
        levels=levels_out,
        y_grid=np.asarray(mean, dtype=np.float64),
        count=cnt,
        spread=np.asarray(std, dtype=np.float64),
        curves=records,
        direction="descending" if sign > 0 else "ascending",
        u_min=lo,
        u_max=hi,
        saturation_tol=sat_tol,
        reversal_tol=rev_tol,
        level_tol=lvl_tol,
        levels_source=source,
        n_samples=int(ta.size),
        input_noise=noise,
        input_units=units[0],
        output_units=units[1],
    )
