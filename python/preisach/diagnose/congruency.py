"""Loops that are not congruent: a test beyond the fine classical model, and one with no model.

The classical Preisach model is *congruent* (Mayergoyz's congruency theorem): minor loops
between the same two inputs have the same height wherever the output sits.  A device whose
loop heights scale with the output level - the product Preisach model (the increments of a
classical output scaled by a function of the magnetisation or strain, Kadar), domains that
stiffen as the strain grows, or a sensor that reads through a nonlinear curve - breaks that.
To first order all of them read ``y = f(x)``, ``x`` a classical Preisach output and ``f`` a
smooth static curve: a loop of height ``h`` at output level ``x`` reads ``f'(x) h``.

The fine classical model of the resolution check
(:func:`~preisach.diagnose.scoring.classical_check`: 61 levels, smooth density, each
recording's unknown initial state free, fitted to the identification recordings and every
other 10 ms stretch of the diagnosis recordings, predicting the stretches in between)
absorbs what any congruent model can make, including a density much finer than the model's
grid.  What a static curve of the output adds to it on the held-out stretches is what no
classical model can make: :func:`output_curve_check` fits both models on the same folds,
the second with the powers ``d**2, d**3`` of the output level ``d`` (the given model's
simulation, scaled to [-1, 1] over the output range: no measured output enters a feature;
the linear term is a rescaling of the weights), and returns the held-out gain in noise
variances with a one-sided sign-flip test over the recordings' time blocks.

What it cannot tell apart is the cause: a device whose loops scale with the output
(non-congruence) and a sensor curve give the same readings on these experiments; a
calibrated sensor, or the same minor loop recorded at several output levels with a second
sensor, separates them.  Measured on the blind dev sets (seeds 7-9, models from
``preisach identify``): nulls 0.02 noise variances at most (p >= 0.09); non-congruence
cases 0.27 (seed 9 case 018, p 0.001), 0.11 (seed 7 case 011), 0.04 (seed 8 case 001),
0.02 or less on eight others - most non-congruence there is absorbed by the fine
classical model, see docs/diagnosis.md.

Where the recordings repeat a minor loop - the congruent-minor-loop (CML) experiment of thesis
§3.2.2 runs one loop at two output levels - congruency is tested with no model at all
(:func:`minor_loop_check`): the loops are read as splines of the input and must agree up to a
vertical shift, which no refit of the weights can change.  Its power grows with how far
apart the loops' output levels lie.  Two tests pool the pairs: the loops' shapes (a spline
per loop against one shared), and their heights - one coefficient for how a loop's height
changes with its output level, what a static curve ``f`` makes to first order
(``f'(x_b) / f'(x_a) - 1`` about ``f''/f'`` times the level difference).  The height test
spends one parameter where the shape test spends one per spline coefficient, so smaller
non-congruences show; a drift or creep changes a loop along its branches in time, rarely by
its height alone, so the height is named only when it makes most of the shape difference
(:data:`LOOP_SCALE_SHARE`).  Measured with the given models on the seen blind cases of seeds
27-34 (208 cases with CML recordings; docs/diagnosis.md section 5q), with splines of one
interval per 160 samples (since made finer, :data:`LOOP_MAX_INTERVALS`; section 5zh): no
null passes either test (height p >= 0.089 over 24); 25 of the 36 cases that carry a
non-congruence pass, 19 by their shape - the height adds six, and no case of another kind;
where a creep or a drift
made the height significant it made 2-32 % of the shape difference, two flicker drifts 51
and 65 % (both passed by their shape anyway).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import interpolate, stats

from ..verify import comparable_loops, minor_loops
from .context import Chain, Context
from .locate import amount_text
from .scoring import CHECK_LEVELS, BeyondClassical, beyond_classical

__all__ = [
    "LOOP_ALPHA",
    "LOOP_HINT_P",
    "LOOP_JOINT_ALPHA",
    "LOOP_JOINT_CURVE_GAIN",
    "LOOP_MAX_INTERVALS",
    "LOOP_MIN_SHAPE",
    "LOOP_RATE_RATIO",
    "LOOP_SCALE_SHARE",
    "LoopShape",
    "MinorLoopCheck",
    "OutputCurveCheck",
    "loop_difference_text",
    "loop_shapes",
    "minor_loop_check",
    "output_curve_check",
    "output_level",
    "pooled_loop_check",
    "repeated_loops_text",
]

#: Level of the minor-loop test (:func:`minor_loop_check`): an F-test exact under congruency.
LOOP_ALPHA = 0.001
#: Level of the joint test of the loops' heights and the static output curve beyond the fine
#: classical model (Fisher's method, :meth:`MinorLoopCheck.joint_p`): two tests of one
#: physics, loops whose height changes with the output level.  Measured on seen blind seeds
#: 42-52 (docs/diagnosis.md, section 5y): the 33 nulls' joint p were all above 0.2; five of
#: the 14 non-congruences left ``none`` (the fine classical model within the noise bound, no
#: single test passed) had joint p of 0.0001-0.008.
LOOP_JOINT_ALPHA = 0.01
#: Least gain (noise variances) of the static output curve beyond the fine classical model for
#: the joint test to name loops whose heights alone are not at :data:`LOOP_HINT_P`: a quarter
#: of the curve's own bar (``selection.RESOLUTION_BEYOND_CLASSICAL``).  On long recordings the
#: curve's sign-flip p is small for a gain far below anything physical: blind seed 68's null
#: 015 had the curve at p 0.001 with a gain of 0.0012 and heights at p 0.135 (jointly 0.0013).
#: On seen seeds 56-69 the nulls whose curves were at p < 0.05 gained at most 0.0012; of the
#: non-congruences the joint test named with heights at p >= 0.01 on seen seeds 44-67, six
#: gained 0.0039-0.034 and one (44/021) 0.0021, now left ``none`` (docs/diagnosis.md, 5zd).
LOOP_JOINT_CURVE_GAIN = 0.0025
#: Smallest RMS shape difference (in noise standard deviations) it names.
LOOP_MIN_SHAPE = 0.3
#: Level below which the shape or height test, short of :data:`LOOP_ALPHA`, is said as a hint
#: (:meth:`MinorLoopCheck.hints`): not named, and not said to agree.  Blind seed 65's
#: electrostrictive case 016 (8.9 x the noise) had heights at p 0.0013 and was reported as
#: loops that "agree"; the nulls' height p were at least 0.089 on seeds 27-34 and 0.035 on
#: seed 65 with the coarser splines of the time, and at least 0.0015 (65/020, now a hint) over
#: the 48 nulls of seeds 65-80 with :data:`LOOP_MAX_INTERVALS`.
LOOP_HINT_P = 0.01
#: Least share of the loops' shape difference (beyond the noise's) a change of their height
#: must make for :meth:`MinorLoopCheck.passes` to name it by the height test alone.
LOOP_SCALE_SHARE = 0.5
#: Smallest RMS height change (noise standard deviations, on loop B's samples) the height
#: test names, and with which the heights carry the joint test
#: (:meth:`MinorLoopCheck.joint_carried`).  Thousands of loop samples resolve a height change
#: far below anything that matters: blind seed 82's case 018 (a Debye relaxation, which keeps
#: loops congruent) had heights at p 0.00074 changing by 0.054 x the noise and was named
#: ``non_congruence``.  The 14 non-congruences of seen blind seeds 66-83 named by their
#: heights changed them by 0.080-0.29 x (docs/diagnosis.md, section 5zj).
LOOP_MIN_HEIGHT = 0.07
#: Most knot intervals of a loop branch's spline (:func:`loop_shapes`, one per ``min_samples``
#: samples).  The residual against a model on a grid of input levels bends at every level;
#: a spline too coarse to follow it leaves that misfit in the own-shape residual, the
#: F-test's denominator and the height test's variance, and the tests lose their power.
#: With one interval per 160 samples (2 to 12) the 48 nulls of blind seeds 65-80 had a
#: median F of 0.37 (an exact test gives 1) and four non-congruences their CML loops carry
#: (65/016, 73/017, 78/018, 78/024) were left ``none``, heights at p 0.0013-0.082; with one
#: per 40 samples the nulls' median F is 0.95, those four are at p 1.8e-5 to 8e-12, the nulls'
#: least p are 0.063 (shape) and 0.0015 (height), and no case of another kind left ``none``
#: or ``unexplained`` passes (docs/diagnosis.md, section 5zh).
LOOP_MAX_INTERVALS = 48
#: Largest ratio of the durations of two loops' branches compared: loops run at other rates
#: differ wherever the device is not quite rate-independent (blind seed-27 nulls: pairs of
#: a multi-sine's loops at other rates and with inner reversals gave F 9-28).
LOOP_RATE_RATIO = 1.2

Array = NDArray[np.float64]


@dataclass
class OutputCurveCheck(BeyondClassical):
    """Outcome of :func:`output_curve_check` (``coef`` in V per power of the output level)."""

    powers: tuple[int, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "gain_noise_variances": self.gain,
            "p": self.p,
            "ratio_classical": self.ratio_classical,
            "ratio_curve": self.ratio_with,
            "powers": list(self.powers),
            "coefficients": [float(c) for c in self.coef],
            "seconds": self.seconds,
        }


def output_level(ctx: Context, powers: Sequence[int], identification: bool = True) -> list[Array]:
    """Powers of the output level ``d`` per recording (columns), zeros where they do not act.

    ``d`` is the given model's simulation scaled to [-1, 1] over the output range (no
    measured output enters a feature).  ``identification``: whether the columns act on the
    identification recordings too; without, ``powers=(0, 1)`` are a zero and a scale of the
    diagnosis recordings that differ from the identification's (a sensor recalibrated between
    them; a scale and zero common to both are the weights' own).
    """
    sims = ctx.predict(Chain(ctx.given))
    out = []
    for i, r in enumerate(ctx.recs):
        d = np.clip((np.nan_to_num(sims[i]) - ctx.y_centre) / ctx.y_half_span, -1.5, 1.5)
        on = identification or not r.ident
        out.append(np.column_stack([d**k if on else np.zeros_like(d) for k in powers]))
    return out


def output_curve_check(
    ctx: Context,
    sigma: float,
    *,
    powers: Sequence[int] = (2, 3),
    seed: int = 0,
    identification: bool = True,
    levels: int = CHECK_LEVELS,
) -> OutputCurveCheck:
    """Measure what a static curve of the output adds to the fine classical model.

    See the module docstring: :func:`~preisach.diagnose.scoring.beyond_classical` with the
    columns :func:`output_level` (``powers``, ``identification``) on a ``levels``-level grid.
    ``sigma`` is the noise (V).
    """
    pw = tuple(int(k) for k in powers)
    cols = output_level(ctx, pw, identification)
    res = beyond_classical(ctx, sigma, cols, seed=seed, levels=levels)
    return OutputCurveCheck(**vars(res), powers=pw)


@dataclass
class LoopShape:
    """Two minor loops between the same inputs compared by :func:`loop_shapes`.

    ``rss_same``/``rss_own``: residual sums of squares (V^2) with one shape for both loops
    plus a vertical shift, and with a shape of their own; ``q`` the parameters the second
    adds, ``n`` the samples, ``k`` the second's parameters.  ``shape_rms`` (V): RMS of loop
    B's shape minus loop A's beyond the shift, less what the noise alone makes of it (the
    drop of the residual sum of squares beyond its expectation under congruency, ``q``
    noise variances: about half of a shape difference ``d`` goes to each loop, so the drop
    is ``n d^2 / 4``); ``level_a``/``level_b`` (V): the loops' mean outputs;
    ``samples_b`` and ``difference`` (V): loop B's samples and its fitted shape minus A's.
    ``scale`` (1): loop B's height relative to loop A's, less one - the coefficient of loop
    B's own shape (the shared spline of the output, centred on B) added to the shared model;
    ``scale_info`` (V^2): that shape's sum of squares beyond the shared model, so that the
    scale's variance is the noise variance over it.
    """

    low: float
    high: float
    t_a: float
    t_b: float
    level_a: float
    level_b: float
    rss_same: float
    rss_own: float
    q: int
    n: int
    k: int
    shape_rms: float
    samples_b: NDArray[np.int64]
    difference: Array
    scale: float = 0.0
    scale_info: float = 0.0


def _branch_samples(
    u: Array, usable: NDArray[np.bool_], i0: int, i1: int, lo: float, hi: float
) -> NDArray[np.int64]:
    """Return the usable samples of branch ``[i0, i1]`` that move the input within [lo, hi]."""
    k = np.arange(i0, i1 + 1, dtype=np.int64)
    moving = np.r_[True, np.diff(u[k]) != 0]  # the samples of a hold add nothing
    keep: NDArray[np.bool_] = moving & usable[k] & (u[k] >= lo) & (u[k] <= hi)
    return k[keep]


def _shape_rms(drop: float, q: int, rss: float, dof: int, n: int) -> float:
    """RMS (V) of a shape difference from the drop ``drop`` of the residual sum of squares.

    Less its expectation under congruency (``q`` noise variances, the variance ``rss / dof``);
    about half of a difference ``d`` goes to each loop, so the drop is ``n d^2 / 4``.
    """
    excess = drop - q * rss / max(dof, 1)
    return 2.0 * math.sqrt(max(excess, 0.0) / max(n, 1))


def _monotone(u: Array, i0: int, i1: int, direction: int) -> bool:
    """Whether ``u[i0..i1]`` never moves against ``direction``.

    An inner reversal, however small, starts a minor loop of its own inside the branch, and
    two loops differ there.
    """
    return bool(np.all(direction * np.diff(u[i0 : i1 + 1]) >= 0.0))


def _similar(u: Array, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether two branches move the input for about as long (within :data:`LOOP_RATE_RATIO`).

    Only the samples that move the input count: a branch's range may include a hold at one
    end (a reversal's turning point is the last sample at the extreme), and a hold sets no
    rate.
    """
    na, nb = (int(np.count_nonzero(np.diff(u[i0 : i1 + 1]))) for i0, i1 in (a, b))
    return bool(max(na, nb) <= LOOP_RATE_RATIO * min(na, nb))


def loop_shapes(
    t: Array,
    u: Array,
    e: Array,
    usable: NDArray[np.bool_] | None = None,
    *,
    y: Array | None = None,
    reversal_tol: float | None = None,
    match_tol: float | None = None,
    min_samples: int = 40,
) -> list[LoopShape]:
    """Compare every pair of minor loops between the same inputs (Mayergoyz's congruency).

    ``t`` (s), ``u`` (V) and ``e`` (V): a recording's time, input and output, or its residual
    against any classical Preisach model (whose own loops are congruent, so subtracting it
    changes no shape difference; it only leaves less curvature to fit); ``y`` (V): the
    measured output, for the loops' levels (default ``e``).  Loops come from
    :func:`~preisach.verify.minor_loops` and :func:`~preisach.verify.comparable_loops`
    (reversals counted beyond ``reversal_tol``, default 0.5 % of the input range; extrema
    matched within ``match_tol``, default 1e-5 of it: a branch from another reversal value
    is another first-order curve, so only loops between the same inputs compare - the
    same loop repeated, as a CML experiment or a periodic input does).  Only loops whose
    branches are monotone (no inner reversal at all) and move the input for about as long
    (:data:`LOOP_RATE_RATIO`) are compared.  Per pair, each branch (rising, falling) of each
    loop is read as a cubic B-spline of the input over the loops' common range (one knot
    interval per ``min_samples`` samples of the shorter branch, 2 to
    :data:`LOOP_MAX_INTERVALS`), twice: one
    spline per branch shared by both loops plus one vertical shift (a classical model's
    loops differ by no more), and one spline per branch and loop; and loop B's height
    against A's (:attr:`LoopShape.scale`: the first model plus the shared shape of ``y``
    centred on B).  Samples of input holds
    are left out; pairs with fewer than ``min_samples`` samples on a branch are skipped.
    """
    t, u, e = (np.asarray(a, dtype=float) for a in (t, u, e))
    level = e if y is None else np.asarray(y, dtype=float)
    ok = np.ones(u.size, bool) if usable is None else np.asarray(usable, bool)
    span = float(np.ptp(u)) if u.size else 0.0
    if not span > 0:
        return []
    rtol = 0.005 * span if reversal_tol is None else float(reversal_tol)
    mtol = 1e-5 * span if match_tol is None else float(match_tol)
    loops = minor_loops(t, u, rtol)
    out = []
    for i, j in comparable_loops(loops, mtol):
        A, B = loops[i], loops[j]
        if not all(_monotone(u, *br, up) for L in (A, B) for br, up in ((L.rise, 1), (L.fall, -1))):
            continue
        if not (_similar(u, A.rise, B.rise) and _similar(u, A.fall, B.fall)):
            continue
        lo, hi = max(A.low, B.low), min(A.high, B.high)
        parts = [_branch_samples(u, ok, *L.rise, lo, hi) for L in (A, B)] + [
            _branch_samples(u, ok, *L.fall, lo, hi) for L in (A, B)
        ]
        m = min(p.size for p in parts)
        if m < min_samples:
            continue
        n_int = int(np.clip(m // min_samples, 2, LOOP_MAX_INTERVALS))
        knots = np.r_[[lo] * 3, np.linspace(lo, hi, n_int + 1), [hi] * 3]
        K = n_int + 3
        bases = [
            interpolate.BSpline.design_matrix(np.clip(u[p], lo, hi), knots, 3).toarray()
            for p in parts
        ]
        target = np.concatenate([e[p] for p in parts])
        n = target.size
        # own: one spline per branch and loop (4 K); same: per branch (2 K) and a shift of B
        own = np.zeros((n, 4 * K))
        same = np.zeros((n, 2 * K + 1))
        row = 0
        for b, (Bm, p) in enumerate(zip(bases, parts)):
            rows = slice(row, row + p.size)
            own[rows, b * K : (b + 1) * K] = Bm
            same[rows, (b // 2) * K : (b // 2 + 1) * K] = Bm
            same[rows, -1] = float(b % 2)  # loop B
            row += p.size
        c_own, *_ = np.linalg.lstsq(own, target, rcond=None)
        # the shared model of the difference and of the output level, one solve
        rhs = np.column_stack([target, np.concatenate([level[p] for p in parts])])
        c_same, c_lvl = np.linalg.lstsq(same, rhs, rcond=None)[0].T
        # loop B's height against A's: the output's shared shape, centred on B, as one more
        # column (its part the shared model makes is taken out: Frisch-Waugh-Lovell)
        on_b = same[:, -1] > 0
        shape = same[:, :-1] @ c_lvl[:-1]
        z = np.where(on_b, shape - shape[on_b].mean(), 0.0)
        z -= same @ np.linalg.lstsq(same, z, rcond=None)[0]
        zz = float(z @ z)
        scale = float(z @ (target - same @ c_same)) / zz if zz > 0 else 0.0
        rss_own = float(np.sum((target - own @ c_own) ** 2))
        rss_same = float(np.sum((target - same @ c_same) ** 2))
        # B's shape minus A's beyond the shift, on B's samples of both branches
        diffs = []
        for b in (1, 3):
            Bm = bases[b]
            diffs.append(Bm @ (c_own[b * K : (b + 1) * K] - c_own[(b - 1) * K : b * K]))
        d = np.concatenate(diffs)
        d = d - d.mean()
        loop_a = np.concatenate([parts[0], parts[2]])
        loop_b = np.concatenate([parts[1], parts[3]])
        q = 2 * K - 1
        out.append(
            LoopShape(
                lo,
                hi,
                A.t0,
                B.t0,
                float(np.mean(level[loop_a])),
                float(np.mean(level[loop_b])),
                rss_same,
                rss_own,
                q,
                n,
                4 * K,
                _shape_rms(rss_same - rss_own, q, rss_own, n - 4 * K, n),
                loop_b.astype(np.int64),
                d,
                scale,
                zz,
            )
        )
    return out


@dataclass
class MinorLoopCheck:
    """Outcome of :func:`minor_loop_check`.

    ``F``, ``dof``, ``p``: the shape test (one shape plus a shift per pair against a shape per
    loop); ``shape_rms`` (V): the shape differences beyond the noise's, all pairs pooled.
    ``height_per_volt`` (1/V) and ``height_sd``: the height test - loop B's height relative
    to loop A's, less one, as ``height_per_volt`` times the loops' output level difference
    (one coefficient for all pairs, as a static curve of the output makes to first order);
    ``height_p`` its two-sided p-value; ``height_share`` (0 to 1) the share of the shape
    differences beyond the noise's that the change of height makes (1 when the shape test
    sees less beyond the noise than the height alone); ``height_rms`` (V) the height change's
    RMS on loop B's samples (the fitted coefficient times each pair's level difference and
    shape).  ``curve_p``, ``curve_gain``: the
    sign-flip p and the gain (noise variances) of the static output curve beyond the fine
    classical model (:func:`output_curve_check`), when that test ran on the same recordings
    (None if not).
    """

    pairs: list[tuple[int, LoopShape]]  # (recording index, pair)
    F: float
    dof: tuple[int, int]
    p: float
    shape_rms: float
    sigma: float  # the noise (V)
    height_per_volt: float = 0.0
    height_sd: float = float("inf")
    height_p: float = 1.0
    height_share: float = 0.0
    height_rms: float = 0.0
    curve_p: float | None = None
    curve_gain: float | None = None

    def joint_p(self) -> float | None:
        """Fisher's combination of the height test's p and ``curve_p`` (None without it).

        Both test one physics - loops whose height changes with the output level - on nearly
        independent evidence: the repeated minor loops with no model, and a static curve of
        the output beyond the fine classical model over all the recordings' held-out stretches
        (the loops are a small part of those).  A non-congruence too weak for either test's
        bar alone can show in both.
        """
        if self.curve_p is None or not self.pairs:
            return None
        return float(stats.combine_pvalues([self.height_p, self.curve_p]).pvalue)

    def found_by(self, alpha: float = LOOP_ALPHA, min_shape: float = LOOP_MIN_SHAPE) -> list[str]:
        """Name the tests by which the loops are not congruent: ``shape``, ``height``, ``joint``.

        The shape test: p < ``alpha`` and a shape difference of ``min_shape`` noise SDs.  The
        height test: p < ``alpha``, at least :data:`LOOP_SCALE_SHARE` of the shape
        differences beyond the noise's made by the loops' heights changing with their output
        level, and a change of at least :data:`LOOP_MIN_HEIGHT` noise SDs RMS - the
        difference a non-congruence makes, told with one parameter where the shape test
        spends one per spline coefficient, so smaller ones show; a drift or creep changes a
        loop's shape in time and rarely its height alone.  The joint test: the height test's
        share met, :meth:`joint_p` below :data:`LOOP_JOINT_ALPHA`, and one of the
        two tests carrying evidence of its own (:meth:`joint_carried`).
        """
        if not self.pairs:
            return []
        share = self.height_share >= LOOP_SCALE_SHARE
        tests = {
            "shape": self.p < alpha and self.shape_rms >= min_shape * self.sigma,
            "height": share and self.height_p < alpha and self._height_sized(),
            "joint": self._joint_below() and self.joint_carried(),
        }
        return [name for name, found in tests.items() if found]

    def _joint_below(self) -> bool:
        """Tell whether :meth:`joint_p` is below :data:`LOOP_JOINT_ALPHA`, the share met."""
        joint = self.joint_p()
        return (
            self.height_share >= LOOP_SCALE_SHARE and joint is not None and joint < LOOP_JOINT_ALPHA
        )

    def _height_sized(self) -> bool:
        """Whether the height change is at least :data:`LOOP_MIN_HEIGHT` noise SDs (RMS)."""
        return self.height_rms >= LOOP_MIN_HEIGHT * self.sigma

    def joint_carried(self) -> bool:
        """Whether one of the joint test's two parts carries evidence of its own.

        The heights at :data:`LOOP_HINT_P` with a change of at least :data:`LOOP_MIN_HEIGHT`
        noise SDs, or the output curve's gain at least :data:`LOOP_JOINT_CURVE_GAIN`: a small
        p at a size far below anything physical (many loop samples, or long recordings that
        resolve the fine model's last per-mille) is not half of a finding.
        """
        gain = self.curve_gain
        heights = self.height_p < LOOP_HINT_P and self._height_sized()
        return heights or (gain is not None and gain >= LOOP_JOINT_CURVE_GAIN)

    def passes(self, alpha: float = LOOP_ALPHA, min_shape: float = LOOP_MIN_SHAPE) -> bool:
        """Whether the loops are not congruent by any test of :meth:`found_by`."""
        return bool(self.found_by(alpha, min_shape))

    def hints(self) -> list[str]:
        """Name the tests (``shape``, ``height``) at p < :data:`LOOP_HINT_P`, the loops not named.

        Loops that differ that much are too weak evidence to name a non-congruence, and too
        strong to be said to agree - also when a test is below its own bar but its size is
        not (a shape difference under :data:`LOOP_MIN_SHAPE`, heights that make less than
        :data:`LOOP_SCALE_SHARE` of it or change by less than :data:`LOOP_MIN_HEIGHT`):
        blind seed 78's moving model 024 had heights at p 5e-5 making 36 % of the shape
        difference and was said to "agree".  Empty when the loops are named and when neither
        p is below :data:`LOOP_HINT_P`.
        """
        if self.passes() or not self.pairs:
            return []
        return [t for t, p in (("shape", self.p), ("height", self.height_p)) if p < LOOP_HINT_P]

    def agree(self, p: float) -> bool:
        """Whether the loops agree: both tests' p-values at least ``p`` (pairs found)."""
        return bool(self.pairs and self.p >= p and self.height_p >= p)

    def largest(self) -> tuple[int, LoopShape]:
        """Return the pair whose shapes differ most (recording index, pair)."""
        return max(self.pairs, key=lambda ip: ip[1].shape_rms)

    def largest_dict(self, ctx: Context) -> dict[str, Any]:
        """JSON-ready fields of :meth:`largest`: its recording, inputs (V), times (s), levels."""
        k, pr = self.largest()
        return {
            "recording": ctx.recs[k].name,
            "low": pr.low,
            "high": pr.high,
            "t_a": pr.t_a,
            "t_b": pr.t_b,
            "level_a": pr.level_a,
            "level_b": pr.level_b,
            "shape_rms": pr.shape_rms,
        }

    def curves(self, ctx: Context) -> list[Array]:
        """Per recording: the shape differences (V) on loop B's samples, zeros elsewhere."""
        out = [np.zeros(r.n) for r in ctx.recs]
        for i, pr in self.pairs:
            out[i][pr.samples_b] = pr.difference
        return out

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "pairs": len(self.pairs),
            "F": self.F if self.pairs else None,
            "dof": list(self.dof),
            "p": self.p,
            "shape_rms": self.shape_rms,
            "shape_noise_ratio": self.shape_rms / self.sigma if self.sigma > 0 else None,
            "height_per_volt": self.height_per_volt if self.pairs else None,
            "height_sd": self.height_sd if self.pairs else None,
            "height_p": self.height_p,
            "height_share": self.height_share,
            "height_noise_ratio": self.height_rms / self.sigma if self.sigma > 0 else None,
            "curve_p": self.curve_p,
            "curve_gain": self.curve_gain,
            "joint_p": self.joint_p(),
            # below its level, but neither part carries it (not named)
            "joint_uncarried": self._joint_below() and not self.joint_carried(),
            "found_by": self.found_by(),
            "hints": self.hints(),
        }


def loop_difference_text(lc: dict[str, Any], unit: str = "V", bars: bool = False) -> str:
    """How the loops of a check differ, in words: the shape test and the height test.

    ``lc``: :meth:`MinorLoopCheck.as_dict` of a check with pairs; ``unit``: the output's
    unit (the height changes per unit of output level); ``bars``: state each test's bar.
    """
    shape_bar = f"; bar p < {LOOP_ALPHA:g} and {LOOP_MIN_SHAPE:g} x the noise" if bars else ""
    height_bar = (
        f"; bar p < {LOOP_ALPHA:g}, {100 * LOOP_SCALE_SHARE:.0f} % and {LOOP_MIN_HEIGHT:g} x "
        "the noise"
        if bars
        else ""
    )
    joint = lc.get("joint_p")
    joint_text = (
        f", and with the static output curve beyond the fine model (p = {lc['curve_p']:.2g}) "
        f"jointly p = {joint:.2g} by Fisher's method"
        + (f" (bar {LOOP_JOINT_ALPHA:g})" if bars else "")
        if joint is not None
        else ""
    )
    return (
        f"in shape by {amount_text(lc['shape_rms'], unit, '.2g')} RMS "
        f"({lc['shape_noise_ratio']:.2g} x the noise; one shape plus a shift against a shape "
        f"per loop over {lc['pairs']} pair(s): F = {lc['F']:.3g}, p = {lc['p']:.2g}"
        f"{shape_bar}) and in height by {100 * lc['height_per_volt']:+.3g} +/- "
        f"{100 * lc['height_sd']:.2g} % per {unit} of output level (p = "
        f"{lc['height_p']:.2g}, {100 * lc['height_share']:.0f} % of the shape "
        f"difference, {_height_size(lc)}{height_bar}){joint_text}"
    )


def _height_size(lc: dict[str, Any]) -> str:
    """Say the height change's RMS in noise SDs (from :meth:`MinorLoopCheck.as_dict`)."""
    ratio = lc.get("height_noise_ratio")
    return "size not known" if ratio is None else f"{ratio:.2g} x the noise RMS"


def repeated_loops_text(lc: dict[str, Any], unit: str = "V") -> str:
    """Say what the repeated minor loops of a check that named nothing show.

    ``lc``: :meth:`MinorLoopCheck.as_dict` of a check with pairs that did not pass.  Loops
    with :meth:`~MinorLoopCheck.hints` differ by those tests short of their bar; the others
    agree, as a congruent model's do.
    """
    if lc.get("hints"):
        parts = {
            "shape": f"in shape by {amount_text(lc['shape_rms'], unit, '.2g')} RMS "
            f"({lc['shape_noise_ratio']:.2g} x the noise; p = {lc['p']:.2g})",
            "height": f"in height by {100 * lc['height_per_volt']:+.3g} +/- "
            f"{100 * lc['height_sd']:.2g} % per {unit} of output level "
            f"({_height_size(lc)}; p = {lc['height_p']:.2g})",
        }
        return (
            f"{lc['pairs']} pair(s) of repeated minor loops differ "
            f"{' and '.join(parts[t] for t in lc['hints'])}, short of the bar that names "
            f"them (p < {LOOP_ALPHA:g} with a shape difference of at least {LOOP_MIN_SHAPE:g} "
            f"x the noise, or heights that make at least {100 * LOOP_SCALE_SHARE:.0f} % of "
            f"it and change by at least {LOOP_MIN_HEIGHT:g} x the noise), so not named - "
            "a weak non-congruence (or a sensor reading through a nonlinear curve) may be "
            "there; the same minor loop repeated more often, or at output levels further "
            "apart, would decide"
        )
    joint = lc.get("joint_p")
    joint_text = "" if joint is None else f"; with the output curve jointly p = {joint:.2g}"
    if lc.get("joint_uncarried") and lc["curve_gain"] is not None:  # MinorLoopCheck.joint_carried
        joint_text += (
            f", carried by a curve that adds only {lc['curve_gain']:.2g} x the noise variance "
            f"(at least {LOOP_JOINT_CURVE_GAIN:g} to name it)"
        )
    return (
        f"{lc['pairs']} pair(s) of repeated minor loops agree in shape up to a vertical shift "
        f"(F = {lc['F']:.3g}, p = {lc['p']:.2g}) and in height (p = {lc['height_p']:.2g}"
        f"{joint_text}), as a congruent model's do"
    )


def minor_loop_check(
    ctx: Context,
    sigma: float,
    chain: Chain | None = None,
    curve_p: float | None = None,
    curve_gain: float | None = None,
    preds: Sequence[Array] | None = None,
) -> MinorLoopCheck:
    """Test the diagnosis recordings' comparable minor loops for congruency.

    Every classical Preisach model is congruent (Mayergoyz's theorem): minor loops between
    the same two inputs are equal up to a vertical shift, whatever the history that led to
    them and wherever the output sits.  A recording that holds two or more such loops - the
    congruent-minor-loop (CML) experiment of thesis §3.2.2 repeats one loop at two output
    levels - tests this directly, with no model fitted: :func:`loop_shapes` on each diagnosis
    recording's residual against the given model (its usable samples), all pairs pooled
    (:func:`pooled_loop_check`) in one F-test of "one shape plus a shift" against "a shape per
    loop", and in one test of the loops' heights against their output levels.  With ``chain`` the
    residual is against that chain's prediction instead: whether a fitted effect makes
    loops that agree differ.  The F-test's denominator is the residual about each loop's
    own spline, so it does not lean on ``sigma`` (V); ``sigma`` only scales the size
    reported.  ``curve_p``, ``curve_gain``: the p and gain of :func:`output_curve_check` on the
    same recordings, for the joint test (:meth:`MinorLoopCheck.joint_p`).  ``preds``: per
    recording, a prediction (V) to take the residual against instead of a chain's (an
    augmented model's with its drift).
    """
    ch = Chain(ctx.given) if chain is None else chain
    pairs: list[tuple[int, LoopShape]] = []
    for i in ctx.diag:  # the identification recordings are not simulated: never read here
        r = ctx.recs[i]
        e = r.y - np.nan_to_num(ctx.predict_one(i, ch) if preds is None else preds[i])
        pairs += [(i, pr) for pr in loop_shapes(r.t, r.u, e, r.usable, y=r.y)]
    check = pooled_loop_check(pairs, sigma)
    check.curve_p, check.curve_gain = curve_p, curve_gain
    return check


def pooled_loop_check(pairs: list[tuple[int, LoopShape]], sigma: float) -> MinorLoopCheck:
    """Pool pairs of :func:`loop_shapes` (with their recording indices) into both tests.

    The shape test: one F-test of all pairs' drops against their own-shape residuals.  The
    height test: every pair's relative height change as one coefficient times its output
    level difference, by weighted least squares (each pair's scale variance is the pooled
    residual variance over its ``scale_info``), two-sided t-test.  ``sigma`` (V) only
    scales the sizes reported.
    """
    if not pairs:
        return MinorLoopCheck([], float("nan"), (0, 0), 1.0, 0.0, float(sigma))
    num = sum(pr.rss_same - pr.rss_own for _, pr in pairs)
    q = sum(pr.q for _, pr in pairs)
    den = sum(pr.rss_own for _, pr in pairs)
    dof2 = sum(pr.n - pr.k for _, pr in pairs)
    F = (num / q) / max(den / max(dof2, 1), 1e-300)
    p = float(stats.f.sf(F, q, dof2))
    rms = _shape_rms(num, q, den, dof2, sum(pr.n for _, pr in pairs))
    # the height test: scale_p = kappa * (level_b - level_a) for every pair, weighted least
    # squares with the pairs' scale variances s2 / scale_info
    s2 = max(den / max(dof2, 1), 1e-300)
    dl = np.array([pr.level_b - pr.level_a for _, pr in pairs])
    info = np.array([pr.scale_info for _, pr in pairs])
    lam = np.array([pr.scale for _, pr in pairs])
    w = float(np.sum(dl * dl * info))
    if w > 0:
        kappa = float(np.sum(lam * dl * info)) / w
        sd = math.sqrt(s2 / w)
        zt = kappa / sd
        hp = float(2.0 * stats.t.sf(abs(zt), max(dof2, 1)))
        # the height's part of the shape differences beyond the noise's (in noise variances);
        # all of it when the shape test sees less than the height alone
        height = zt * zt - 1.0
        share = height / max(num / s2 - q, height) if height > 0 else 0.0
        # the height change's RMS on loop B's samples (V)
        n_b = sum(pr.samples_b.size for _, pr in pairs)
        h_rms = abs(kappa) * math.sqrt(w / max(n_b, 1))
    else:
        kappa, sd, hp, share, h_rms = 0.0, float("inf"), 1.0, 0.0, 0.0
    return MinorLoopCheck(
        pairs, float(F), (int(q), int(dof2)), p, rms, float(sigma), kappa, sd, hp, share, h_rms
    )
