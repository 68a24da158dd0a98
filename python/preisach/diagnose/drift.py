"""Sensor drift as a smooth function of time per recording, its roughness chosen by held-out time.

A sensor's offset wanders with time for reasons the input does not control (temperature, a
charge amplifier's leakage, a strain gauge's creep of its own).  In a lab that wander can be
a ramp, a slow thermal cycle, a random walk or a 1/f wander; no one law covers them, so the
drift of each recording is a P-spline in time: a cubic B-spline whose coefficients are
penalised by their **first** differences (the random-walk prior: between data the curve
stays where it was, so a held-out stretch at a recording's start or end is predicted by the
level next to it, not by extrapolating a local slope over a second or more).

How rough the curve may be is not fixed: per recording the knot spacing is chosen among a
few (a single interval per recording up to a knot every :data:`MIN_SPACING` seconds), and
one penalty weight for all recordings among :data:`SMOOTHINGS`, by cross-validation **held
out in time**, the way the drift is scored: the curve fitted on the recording's blocks of one
parity predicts the blocks of the other (a random split of the samples would let the curve
follow anything slower than the sample rate).  The residual it is chosen on is the
classical base's refitted with the finest drift projected off, on the recording's usable
samples: like the initial history, one discrete choice per recording made with its
measured output (:meth:`~preisach.diagnose.context.Context.choose_drift_roughness`).

A drift is a function of time, so it must also show where the input cannot act: during
input holds (:func:`hold_check`).  A curve that moves through the holds while the measured
output stands still there is a model error smoothed into a curve (level errors that jump
at the steps), not a sensor drift.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import interpolate

from .locate import amount_text

if TYPE_CHECKING:  # pragma: no cover
    from .context import Chain, Context

Array = NDArray[np.float64]

__all__ = [
    "DRIFT_SMOOTHING",
    "FOLLOWS_T_MAX",
    "HOLD_MOTION_MIN",
    "HOLD_SHARE_MIN",
    "MAX_INTERVALS",
    "MIN_SPACING",
    "ROUGHER_GAIN",
    "SMOOTHINGS",
    "HoldCheck",
    "bspline_basis",
    "choose_roughness",
    "choose_spacing",
    "drift_hold_check",
    "drift_refuted_by_holds",
    "hold_check",
    "penalised_system",
    "spacing_options",
]

#: Weight of the first-difference penalty, relative to the mean diagonal of ``A^T A``.
DRIFT_SMOOTHING: float = 0.3
#: Smallest knot spacing (s) a drift curve may get.
MIN_SPACING: float = 0.5
#: Most knot intervals per recording (bounds the dense basis of long recordings).
MAX_INTERVALS: int = 40
#: Relative drop of the held-out error a rougher spacing must bring to be preferred.
ROUGHER_GAIN: float = 0.0
#: Penalty weights tried (:func:`choose_roughness`).
SMOOTHINGS: tuple[float, ...] = (0.03, 0.1, 0.3, 1.0)


def bspline_basis(t: Array, spacing: float) -> Array:
    """Cubic B-spline basis over ``t`` (s, from the recording's start), knots every ``spacing``."""
    t = np.asarray(t, dtype=float) - float(t[0])
    T = max(float(t[-1]), 1e-9)
    n_int = max(1, int(math.ceil(T / spacing - 1e-9)))
    inner = np.linspace(0.0, T, n_int + 1)
    knots = np.concatenate([[0.0] * 3, inner, [T] * 3])
    return np.asarray(
        interpolate.BSpline.design_matrix(np.clip(t, 0.0, T), knots, 3).toarray(), dtype=float
    )


def penalised_system(A: Array, smoothing: float = DRIFT_SMOOTHING) -> tuple[Array, float]:
    """Penalised normal matrix ``A^T A + lam D^T D`` (first differences) and its effective dof.

    ``lam`` is ``smoothing`` times the mean diagonal of ``A^T A`` (so the penalty does not
    depend on how many samples a column covers).
    """
    m = A.shape[1]
    D = np.diff(np.eye(m), 1, axis=0) if m > 1 else np.zeros((0, m))
    AtA = A.T @ A
    lam = smoothing * max(float(np.trace(AtA)) / max(m, 1), 1e-300)
    G = AtA + lam * (D.T @ D) + 1e-9 * lam * np.eye(m)
    dof = float(np.trace(np.linalg.solve(G, AtA)))
    return G, dof


def spacing_options(duration: float) -> list[float]:
    """Knot spacings (s) tried for a recording of ``duration`` seconds, smoothest first.

    One interval over the whole recording, then halved, down to :data:`MIN_SPACING` (and no
    more than :data:`MAX_INTERVALS` intervals).
    """
    T = max(float(duration), 1e-9)
    floor = max(MIN_SPACING, T / MAX_INTERVALS)
    out = [T]
    while out[-1] / 2 >= floor - 1e-12:
        out.append(out[-1] / 2)
    return out


def _fit(A: Array, r: Array, smoothing: float) -> Array:
    G, _ = penalised_system(A, smoothing)
    return np.asarray(np.linalg.solve(G, A.T @ r), dtype=float)


def choose_spacing(
    t: Array,
    res: Array,
    usable: NDArray[np.bool_],
    parity: NDArray[np.int64],
    smoothing: float = DRIFT_SMOOTHING,
) -> tuple[float, dict[float, float]]:
    """Knot spacing (s) of one recording's drift chosen by held-out time blocks.

    Parameters
    ----------
    t : array
        Sample times (s).
    res : array
        Residual (V) the drift would explain.
    usable : bool array
        Samples that count.
    parity : int array
        Block parity (0/1) of every sample: the curve fitted on one parity predicts the other.
    smoothing : float
        Penalty weight (:func:`penalised_system`).

    Returns
    -------
    spacing : float
        The smoothest spacing within :data:`ROUGHER_GAIN` of the best held-out error.
    sse : dict
        Held-out sum of squares (V^2) per spacing tried.
    """
    table = _heldout_table(t, res, usable, parity, [smoothing])
    return _smoothest_best(table[smoothing])


def choose_roughness(
    recordings: list[tuple[Array, Array, NDArray[np.bool_], NDArray[np.int64]]],
    smoothings: tuple[float, ...] = SMOOTHINGS,
) -> tuple[float, list[float], float]:
    """Penalty weight (one for all) and knot spacing per recording, by held-out time blocks.

    ``recordings`` holds ``(t, res, usable, parity)`` per recording (see
    :func:`choose_spacing`).  For every penalty weight in ``smoothings`` each recording gets
    its best spacing; the weight with the lowest held-out error summed over the recordings is
    chosen.  Returns the weight, the spacings and that held-out sum of squares (V^2).
    """
    tables = [_heldout_table(*rec, smoothings) for rec in recordings]
    best: tuple[float, list[float], float] | None = None
    for lam in smoothings:
        picks = [_smoothest_best(tb[lam]) for tb in tables]
        total = float(sum(sse[sp] for sp, sse in picks))
        if best is None or total < best[2]:
            best = (lam, [sp for sp, _ in picks], total)
    assert best is not None
    return best


def _heldout_table(
    t: Array,
    res: Array,
    usable: NDArray[np.bool_],
    parity: NDArray[np.int64],
    smoothings: tuple[float, ...] | list[float],
) -> dict[float, dict[float, float]]:
    """Held-out sum of squares per penalty weight and knot spacing (other parity predicts)."""
    usable = np.asarray(usable, dtype=bool)
    out: dict[float, dict[float, float]] = {lam: {} for lam in smoothings}
    for s in spacing_options(float(t[-1] - t[0])):
        B = bspline_basis(t, s)
        for lam in smoothings:
            tot, n = 0.0, 0
            for p in (0, 1):
                tr = usable & (parity != p)
                te = usable & (parity == p)
                if not tr.any() or not te.any():
                    continue
                e = res[te] - B[te] @ _fit(B[tr], res[tr], lam)
                tot += float(e @ e)
                n += int(te.sum())
            out[lam][s] = tot if n else math.inf
    return out


def _smoothest_best(sse: dict[float, float]) -> tuple[float, dict[float, float]]:
    """Return the smoothest spacing unless a rougher one lowers the error enough."""
    opts = sorted(sse, reverse=True)
    chosen = opts[0]
    for s in opts[1:]:
        if sse[s] < (1.0 - ROUGHER_GAIN) * sse[chosen]:
            chosen = s
    return chosen, sse


# ----------------------------------------------------------------------------------------
#: A fitted drift is refused when the measured residual moves, over the holds, by less than
#: this share of what the drift curve claims there (upper 2-sigma bound).
HOLD_SHARE_MIN: float = 0.5
#: ... and only when the curve's RMS motion over the holds is at least this many noise sigmas.
HOLD_MOTION_MIN: float = 2.0
#: A drift curve whose motion in the holds follows the moves into them with this t or more
#: follows the input steps (the creep rule's threshold, :data:`.rate_family.CREEP_MIN_T`).
FOLLOWS_T_MAX: float = 2.0


def slope_t(x: Array, y: Array) -> float:
    """t-statistic of the least-squares slope of ``y`` on ``x`` through zero (0 if undefined)."""
    xx = float(x @ x)
    if xx <= 0.0 or x.size < 2:
        return 0.0
    k = float(x @ y) / xx
    e = y - k * x
    return k / math.sqrt(max(float(e @ e), 1e-300) / (x.size - 1) / xx)


@dataclass(frozen=True)
class HoldCheck:
    """How the residual moves during input holds compared with a fitted drift curve.

    Attributes
    ----------
    n_holds : int
        Holds used (input within 0.1 % of its span for at least ``2.5 settle`` s).
    share : float
        Least-squares slope of the residual's late motion in the holds on the drift curve's
        motion over the same stretches (1: the residual moves as the drift says).
    se : float
        Standard error of ``share``.
    drift_motion : float
        RMS of the drift curve's motion over those stretches (V).
    follows_t : float
        t-statistic of the drift curve's motion in the holds regressed on the measured output
        move into each hold: a sensor drift has nothing to do with the moves' sizes and signs,
        creep (or any input-driven after-effect) moves on in the direction of the move.

    """

    n_holds: int
    share: float
    se: float
    drift_motion: float
    follows_t: float = 0.0

    def refutes(self, sigma: float) -> bool:
        """Whether the holds show the drift is not there (the curve moves, the output not).

        Only judged when the curve claims motion in the holds of at least twice the noise
        ``sigma`` (V) and there are three holds or more: smaller motions are within what a
        held-out curve may wander.
        """
        return (
            self.n_holds >= 3
            and self.drift_motion >= HOLD_MOTION_MIN * sigma
            and self.share + 2.0 * self.se < HOLD_SHARE_MIN
        )


def hold_check(
    recordings: list[tuple[Array, Array, Array, float, Array]], u_span: float, settle: float = 0.5
) -> HoldCheck:
    """Compare the residual's motion during holds with a drift curve's (model-free test).

    ``recordings`` holds ``(u, res, drift, dt, y)`` per recording (V, V, V, s, V; ``y`` the
    measured output, whose move into each hold the drift's motion must not follow).  While the input
    is held the classical model (and any input-driven effect after ``settle`` seconds) stands
    still, so the residual moves there only by what the sensor does: a sensor drift goes on
    through the holds, while a curve smoothed through a staircase of level errors that
    jump at the steps (a model error that follows the input) moves where the output does not.
    Per hold the motion from ``settle`` after it began to its end is taken as the difference
    of means over ``settle / 2`` windows, for the residual and for the drift curve.
    """
    tol = 1e-3 * u_span
    dr, dd, mv = [], [], []
    for u, res, drift, dt, y in recordings:
        n_set = int(round(settle / dt))
        h = max(1, n_set // 2)
        still = np.abs(np.diff(u)) <= tol
        edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if a < h or b - a + 1 < 2 * n_set + h or np.ptp(u[a : b + 1]) > tol:
                continue
            mv.append(float(np.mean(y[a + 1 : a + 1 + h]) - np.mean(y[a - h : a])))
            early = slice(a + n_set, a + n_set + h)
            late = slice(b + 1 - h, b + 1)
            dr.append(float(np.mean(res[late]) - np.mean(res[early])))
            dd.append(float(np.mean(drift[late]) - np.mean(drift[early])))
    n = len(dd)
    d, r = np.asarray(dd), np.asarray(dr)
    dd2 = float(d @ d) if n else 0.0
    if n < 2 or dd2 <= 0.0:
        return HoldCheck(n, 1.0, math.inf, math.sqrt(dd2 / max(n, 1)))
    share = float(d @ r) / dd2
    e = r - share * d
    se = math.sqrt(max(float(e @ e), 1e-300) / (n - 1) / dd2)
    return HoldCheck(n, share, se, math.sqrt(dd2 / n), slope_t(np.asarray(mv), d))


def drift_hold_check(ctx: Context, chain: Chain, settle: float = 0.25) -> HoldCheck:
    """:func:`hold_check` of ``chain``'s drift curves (fitted on the usable samples).

    ``settle`` 0.25 s: holds of 0.625 s and more count (step-and-hold experiments hold for
    about a second or two).
    """
    data = []
    for i in ctx.diag:
        r = ctx.recs[i]
        res = r.y - ctx.predict_one(i, chain)
        d = ctx.drift_basis(i) @ ctx.drift_fit(i, res, r.usable)
        data.append((r.u, res, d, r.dt, r.y))
    return hold_check(data, ctx.u_span, settle)


def drift_refuted_by_holds(
    ctx: Context, chains: list[Chain], sigma: float
) -> tuple[str | None, bool]:
    """Why the fitted drift of any of ``chains`` is not a drift by the holds (or None).

    Also returns whether the reason is that the drift curve follows the input steps
    (a creep beside it may have made it do so: ``selection._drift_beside_creep``).
    """
    for ch in chains:
        hc = drift_hold_check(ctx, ch)
        if hc.n_holds >= 3 and hc.follows_t >= FOLLOWS_T_MAX:
            return (
                f"over {hc.n_holds} input holds the drift curve moves on in the direction of "
                f"the output's move into each hold (t = {hc.follows_t:.2g} >= "
                f"{FOLLOWS_T_MAX:g}): it follows the input steps, as creep does, not a sensor "
                "drift"
            ), True
        if hc.refutes(sigma):
            return (
                f"the drift curve moves by {amount_text(hc.drift_motion, ctx.output_unit, '.2g')} "
                f"(RMS) over {hc.n_holds} input holds where the measured output moves by "
                f"{100 * hc.share:.2g} ± {100 * hc.se:.2g} % of that: a model error that "
                "changes with the input steps, smoothed into a curve, not a sensor drift"
            ), False
    return None, False
