"""Within-hold evidence: the part of a residual no rate-independent model can produce.

While the input is held, a classical Preisach model's output stands still (whatever its grid,
weights or initial state), and so does the output of any block that has settled.  So the
motion of the measured output *within* an input hold - its variation about the hold's own
mean, from ``settle`` seconds after the input stopped - is free of the base model's
resolution error (which only shifts each hold by a constant): it is noise, or it is physics
that acts in time (creep relaxing toward equilibrium, a sensor drifting, a slow mode
ringing on).

On recordings whose base leaves several noise sigmas of resolution error elsewhere, an
after-effect worth a noise sigma in the holds lowers the pooled held-out RMSE by a few per
cent only and is not kept by the selection's global rule; measured where it lives - on the
held-out holds, with each hold's mean removed - it is plain.  :func:`hold_pieces` cuts the
holds of every diagnosed recording into pieces (contiguous scored samples of one hold and
one held-out block); :func:`hold_evidence` compares two chains' held-out residuals on them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from .drift import slope_t
from .scoring import Score, sign_flip_p

if TYPE_CHECKING:
    from .context import Context

Array = NDArray[np.float64]

#: time (s) after the input stops before a hold's samples count (a step's own transient:
#: the output's rise through the drive's and the sensor's bandwidth, a delay)
HOLD_SETTLE = 0.05
#: shortest hold piece (s) scored after the settle
HOLD_MIN_PIECE = 0.25
#: input change (share of the model's input span) per sample still counted as holding
HOLD_TOL = 1e-3
#: fewest hold pieces for the within-hold evidence to count
HOLD_MIN_PIECES = 4
#: least reduction of the within-hold held-out RMS (relative) for an effect to qualify on it
HOLD_MIN_GAIN = 0.1
#: least within-hold mean-square reduction, in noise variances, for the same
HOLD_MIN_EXPLAINED = 0.2
#: within-hold RMS of what is left (x the noise) above which the holds show motion
HOLD_EXCESS = 1.2
#: t-statistic of the hold motion on the moves into the holds from which it follows them
HOLD_FOLLOWS_T = 3.0
#: one-sided p-value (t-distribution, one degree of freedom per hold piece less one) below
#: which a motion within the noise's RMS that follows the moves into the holds is named an
#: after-effect (:attr:`HoldMotion.after_effect`).  Seen blind seeds 42-53 (docs/diagnosis.md,
#: section 5y): the 36 nulls' |t| were at most 1.9, the other kinds' (nothing kept, holds
#: within the noise) at most 2.3; the creeps' 4.9-12.8.
HOLD_AFTER_EFFECT_P = 0.001


@dataclass(frozen=True)
class HoldPieces:
    """Hold pieces of the diagnosed recordings: (recording index, first, end) sample ranges."""

    pieces: list[tuple[int, int, int]]
    seconds: Array  # length of every piece (s)
    moves: Array  # the measured output's move into each piece's hold (V)

    def __len__(self) -> int:
        return len(self.pieces)


def _still_runs(u: Array, tol: float) -> list[tuple[int, int]]:
    """Maximal runs ``[a, b)`` of samples within ``tol`` of each other (greedy, in order)."""
    runs: list[tuple[int, int]] = []
    a, lo, hi = 0, float(u[0]), float(u[0])
    for k in range(1, u.size):
        v = float(u[k])
        lo, hi = min(lo, v), max(hi, v)
        if hi - lo > tol:
            runs.append((a, k))
            a, lo, hi = k, v, v
    runs.append((a, int(u.size)))
    return runs


def hold_pieces(ctx: Context) -> HoldPieces:
    """Cut the diagnosed recordings' input holds into scorable pieces.

    A hold is a stretch where the input stays within :data:`HOLD_TOL` of the model's input
    span; its first :data:`HOLD_SETTLE` seconds are skipped, and the rest
    is cut where the time block (the unit of the held-out folds) changes.  Pieces shorter
    than :data:`HOLD_MIN_PIECE` s are dropped.
    """
    tol = HOLD_TOL * ctx.u_span
    out: list[tuple[int, int, int]] = []
    secs: list[float] = []
    moves: list[float] = []
    for i in ctx.diag:
        r = ctx.recs[i]
        n_set = int(round(HOLD_SETTLE / r.dt))
        n_min = max(int(round(HOLD_MIN_PIECE / r.dt)), 3)
        for a, b in _still_runs(r.u, tol):
            lo, hi = a + n_set, b
            if hi - lo < n_min:
                continue
            h = max(n_set, 1)
            move = float(np.mean(r.y[lo : lo + h]) - np.mean(r.y[max(a - h, 0) : a])) if a else 0.0
            ok = r.usable[lo:hi]
            blk = r.block[lo:hi]
            cuts = np.flatnonzero(np.diff(blk) != 0) + 1
            for s, e in zip(np.r_[0, cuts], np.r_[cuts, hi - lo]):
                if e - s >= n_min and ok[s:e].all():
                    out.append((i, lo + int(s), lo + int(e)))
                    secs.append(float(e - s) * r.dt)
                    moves.append(move)
    return HoldPieces(out, np.asarray(secs, float), np.asarray(moves, float))


def within_hold_sse(score: Score, holds: HoldPieces) -> tuple[Array, Array]:
    """Held-out SSE of the residual about each hold piece's own mean, and the pieces' sizes.

    Pieces with unscored samples (not held out by any fold) are given zero size.
    """
    sse = np.zeros(len(holds))
    cnt = np.zeros(len(holds))
    for k, (i, a, b) in enumerate(holds.pieces):
        res = score.residuals[i][a:b]
        if res.size < 3 or np.isnan(res).any():
            continue
        d = res - res.mean()
        sse[k] = float(d @ d)
        cnt[k] = res.size - 1  # one degree of freedom goes to the piece's mean
    return sse, cnt


@dataclass(frozen=True)
class HoldEvidence:
    """How much better a chain predicts the motion within the held-out holds than a baseline."""

    n_pieces: int
    seconds: float
    base_ratio: float  # baseline's within-hold RMS / noise
    ratio: float  # the chain's within-hold RMS / noise
    gain: float  # relative reduction of the within-hold RMS
    explained: float  # within-hold MSE reduction / noise variance
    p_value: float  # one-sided sign-flip test over the pieces

    def qualifies(self, alpha: float) -> bool:
        """Whether the holds alone show the effect (enough pieces, large and significant)."""
        return (
            self.n_pieces >= HOLD_MIN_PIECES
            and self.gain >= HOLD_MIN_GAIN
            and self.explained >= HOLD_MIN_EXPLAINED
            and self.p_value < alpha
        )

    def statement(self) -> str:
        """One line: the evidence in words."""
        return (
            f"within {self.n_pieces} held-out input holds ({self.seconds:.3g} s, each hold's "
            f"mean removed: motion no rate-independent model makes) the residual falls from "
            f"{self.base_ratio:.3g} to {self.ratio:.3g} x the noise ({100 * self.gain:.0f} % "
            f"lower, sign-flip p = {self.p_value:.2g})"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "pieces": self.n_pieces,
            "seconds": self.seconds,
            "base_ratio": self.base_ratio,
            "ratio": self.ratio,
            "gain": self.gain,
            "explained_noise_variances": self.explained,
            "p_value": self.p_value,
        }


def hold_evidence(
    base: Score, cand: Score, holds: HoldPieces, sigma: float, seed: int = 0
) -> HoldEvidence | None:
    """Compare two chains' held-out residuals within the holds (None when there are none)."""
    if len(holds) == 0 or not sigma > 0:
        return None
    sb, cb = within_hold_sse(base, holds)
    sc, cc = within_hold_sse(cand, holds)
    m = (cb > 0) & (cc > 0)
    if not m.any():
        return None
    n = float(cb[m].sum())
    mse_b, mse_c = float(sb[m].sum()) / n, float(sc[m].sum()) / n
    gain = 1.0 - math.sqrt(mse_c / mse_b) if mse_b > 0 else 0.0
    return HoldEvidence(
        int(m.sum()),
        float(holds.seconds[m].sum()),
        math.sqrt(mse_b) / sigma,
        math.sqrt(mse_c) / sigma,
        gain,
        (mse_b - mse_c) / sigma**2,
        sign_flip_p(sb[m] - sc[m], seed=seed),
    )


@dataclass(frozen=True)
class HoldMotion:
    """The within-hold motion of a residual (:func:`hold_motion`)."""

    n_pieces: int
    seconds: float
    ratio: float  # within-hold RMS (each piece's mean removed) / noise
    follows_t: float  # t-statistic of each piece's motion on the move into its hold
    follows: float = 0.0  # that motion per unit move into the hold (the slope)

    @property
    def moves(self) -> bool:
        """Whether the output moves within the holds beyond the noise."""
        return self.n_pieces >= HOLD_MIN_PIECES and self.ratio >= HOLD_EXCESS

    @property
    def follows_p(self) -> float:
        """One-sided p of ``follows_t`` (t-distribution, ``n_pieces - 1`` degrees of freedom).

        Exact enough under any rate-independent model: its output stands still while the
        input holds, so each piece's motion is noise whatever the model's resolution.
        """
        return float(stats.t.sf(self.follows_t, max(self.n_pieces - 1, 1)))

    @property
    def after_effect(self) -> bool:
        """Whether a motion within the noise's RMS goes on in the direction of the moves.

        The holds do not move beyond :data:`HOLD_EXCESS` x the noise, but across at least
        :data:`HOLD_MIN_PIECES` holds their motion follows the moves into them at
        :data:`HOLD_AFTER_EFFECT_P`: an after-effect (creep) too small for any one hold's
        RMS, systematic over all of them.
        """
        return (
            self.n_pieces >= HOLD_MIN_PIECES
            and not self.moves
            and self.follows_p < HOLD_AFTER_EFFECT_P
        )

    def statement(self) -> str:
        """One line: the motion in words, and that nothing predicted it when it moves."""
        if not self.moves:
            return self.describe()
        return (
            f"{self.describe()}; no rate-independent model moves while the input holds, and "
            "no candidate predicted it on held-out data with a fit that fits its name"
        )

    def describe(self) -> str:
        """Describe the motion in words."""
        if not self.moves:
            return (
                f"within {self.n_pieces} input holds ({self.seconds:.3g} s) the residual stays "
                f"at {self.ratio:.3g} x the noise (bound {HOLD_EXCESS:g} x)"
            )
        how = (
            "following the moves into them (as creep does)"
            if self.follows_t >= HOLD_FOLLOWS_T
            else "not following the moves into them (as a sensor drift would not)"
        )
        return (
            f"the output moves within {self.n_pieces} input holds ({self.seconds:.3g} s) at "
            f"{self.ratio:.3g} x the noise (each hold's mean removed; bound {HOLD_EXCESS:g} x), "
            f"{how}, t = {self.follows_t:.2g}"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "pieces": self.n_pieces,
            "seconds": self.seconds,
            "ratio": self.ratio,
            "follows_moves_t": self.follows_t,
            "follows_moves_p": self.follows_p,
            "follows_moves": self.follows,
            "moves": self.moves,
            "after_effect": self.after_effect,
            "statement": self.statement(),
        }


def hold_motion(score: Score, holds: HoldPieces, sigma: float) -> HoldMotion | None:
    """How the held-out residual of ``score`` moves within the holds (None without holds).

    The motion of a piece is the mean of its last third minus that of its first third; its
    regression (through zero) on the measured output's move into the hold gives
    ``follows_t``: an after-effect of the moves (creep) goes on in their direction, a sensor
    drift has nothing to do with them.
    """
    sse, cnt = within_hold_sse(score, holds)
    m = cnt > 0
    if not m.any() or not sigma > 0:
        return None
    motion = np.zeros(len(holds))
    for k, (i, a, b) in enumerate(holds.pieces):
        if m[k]:
            res = score.residuals[i][a:b]
            third = max(res.size // 3, 1)
            motion[k] = float(np.mean(res[-third:]) - np.mean(res[:third]))
    d, mv = motion[m], holds.moves[m]
    follows = slope_t(mv, d) if d.size > 2 else 0.0
    return HoldMotion(
        int(m.sum()),
        float(holds.seconds[m].sum()),
        math.sqrt(float(sse[m].sum()) / float(cnt[m].sum())) / sigma,
        follows,
        float(mv @ d) / float(mv @ mv) if float(mv @ mv) > 0 else 0.0,
    )


def motion_curves(score: Score, holds: HoldPieces) -> list[Array]:
    """Per recording: each hold piece's residual less its first third's mean (0 elsewhere).

    What the output moved within the holds since each began (after the settle), the motion
    :func:`hold_motion` measures.
    """
    out = [np.zeros(r.size) for r in score.residuals]
    for i, a, b in holds.pieces:
        res = score.residuals[i][a:b]
        out[i][a:b] = res - float(np.mean(res[: max(res.size // 3, 1)]))
    return out


#: length (s) of the alternating stretches of a hold piece the wander test predicts from
#: their neighbours (long enough to average a ring of tens of hertz away, short against a
#: sensor's wander)
WANDER_STRETCH = 0.05


@dataclass(frozen=True)
class HoldWander(HoldEvidence):
    """How well the output's motion within the holds predicts itself (:func:`hold_wander`).

    ``base_ratio`` is the held-out RMS (x the noise) of a still output at each hold's level,
    ``ratio`` that of each stretch's level taken from its neighbours.
    """

    wander_rms: float = 0.0  # RMS of the wander about each hold's level beyond the noise (V)

    def statement(self) -> str:
        """One line: the evidence in words."""
        ms = 1e3 * WANDER_STRETCH
        return (
            f"within {self.n_pieces} input holds ({self.seconds:.3g} s) the level of each "
            f"{ms:.0f} ms stretch, taken from its two neighbours, predicts it at "
            f"{self.ratio:.3g} x the noise, against {self.base_ratio:.3g} x for a still output "
            f"at the hold's level ({100 * self.gain:.0f} % lower, sign-flip p = "
            f"{self.p_value:.2g} over the pieces)"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {**super().as_dict(), "wander_rms": self.wander_rms, "stretch_s": WANDER_STRETCH}


def _stretched(
    score: Score, holds: HoldPieces, dt: Sequence[float]
) -> Iterator[tuple[int, int, Array, int]]:
    """Hold pieces of at least three whole stretches: (recording, first sample, residual, n).

    The residual is cut to whole :data:`WANDER_STRETCH` stretches of ``n`` samples.
    """
    for i, a, b in holds.pieces:
        res = score.residuals[i][a:b]
        n = max(int(round(WANDER_STRETCH / dt[i])), 1)
        k = res.size // n
        if k >= 3 and not np.isnan(res).any():
            yield i, a, res[: k * n], n


def wander_curves(score: Score, holds: HoldPieces, dt: Sequence[float]) -> list[Array]:
    """Per recording: each hold stretch's level taken from its neighbours (0 outside holds).

    The pieces are cut into alternating :data:`WANDER_STRETCH` stretches; a stretch's
    prediction is the mean of its neighbours' means (one neighbour at the ends), so no
    sample is predicted from itself.
    """
    out = [np.zeros(r.size) for r in score.residuals]
    for i, a, r, n in _stretched(score, holds, dt):
        means = r.reshape(-1, n).mean(axis=1)
        left = np.r_[means[1], means[:-1]]
        right = np.r_[means[1:], means[-2]]
        out[i][a : a + r.size] = np.repeat(0.5 * (left + right), n)
    return out


def hold_wander(
    score: Score, holds: HoldPieces, sigma: float, dt: Sequence[float], seed: int = 0
) -> HoldWander | None:
    """Whether the residual within the holds wanders smoothly: a held-out test on the holds.

    Each hold piece is cut into :data:`WANDER_STRETCH` stretches.  Every stretch is predicted
    twice, never from itself: by the mean of the piece's other stretches (an output that
    stands still, as every rate-independent model's does while the input holds) and by the
    mean of its two neighbouring stretches (:func:`wander_curves`: an output that moves
    smoothly, as a sensor drift or creep does).  The second must be better by
    :data:`HOLD_MIN_GAIN` and :data:`HOLD_MIN_EXPLAINED` noise variances with a sign-flip p
    below the level, over the pieces.  On white noise the neighbours' means are the noisier
    predictors, so the test leans against motion; a ring of tens of hertz averages out in
    every stretch and is not taken for a wander.  ``dt`` is the sample time (s) per recording.
    """
    if len(holds) == 0 or not sigma > 0:
        return None
    local = wander_curves(score, holds, dt)
    s_still, s_local, cnt, secs = [], [], [], 0.0
    for i, a, r, n in _stretched(score, holds, dt):
        sums = r.reshape(-1, n).sum(axis=1)
        others = (sums.sum() - sums) / (r.size - n)  # each stretch's level from the others
        e_still = r - np.repeat(others, n)
        e_local = r - local[i][a : a + r.size]
        s_still.append(float(e_still @ e_still))
        s_local.append(float(e_local @ e_local))
        cnt.append(r.size)
        secs += r.size * dt[i]
    if not cnt:
        return None
    ss, sl, c = np.asarray(s_still), np.asarray(s_local), np.asarray(cnt, float)
    mse_s, mse_l = float(ss.sum() / c.sum()), float(sl.sum() / c.sum())
    return HoldWander(
        int(c.size),
        secs,
        math.sqrt(mse_s) / sigma,
        math.sqrt(mse_l) / sigma,
        1.0 - math.sqrt(mse_l / mse_s) if mse_s > 0 else 0.0,
        (mse_s - mse_l) / sigma**2,
        sign_flip_p(ss - sl, seed=seed),
        math.sqrt(max(mse_s - sigma**2, 0.0)),
    )
