"""``diagnose(model, recordings)``: locate, name and model what a Preisach model leaves out."""

from __future__ import annotations

import functools
import math
import os
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Callable, TypeVar, Union, cast

import numpy as np
from threadpoolctl import threadpool_limits

from .._progress import line_progress
from ..model import PreisachModel, State
from ..recording import Recording
from .augmented import AugmentedModel
from .candidates import Candidate, DriftCandidate
from .congruency import loop_difference_text, minor_loop_check, repeated_loops_text
from .context import Chain, Context, FittedEffect
from .data import noise_sigma, prepare_recordings
from .effects import EffectBlock
from .holds import (
    HOLD_AFTER_EFFECT_P,
    HOLD_EXCESS,
    HOLD_FOLLOWS_T,
    HOLD_MIN_PIECES,
    HoldMotion,
    HoldPieces,
    hold_motion,
    hold_wander,
    motion_curves,
    wander_curves,
)
from .locate import amount_text, analyse_residuals, display_unit
from .registry import CANDIDATES
from .report import (
    DiagnosisReport,
    EffectReport,
    candidate_table,
    nearest_rejected,
    output_unit,
    unexplained_of,
    where_of,
)
from .scoring import Score, nameable_rms, sign_flip_p
from .selection import (
    RESOLUTION_BEYOND_CLASSICAL,
    GridChoice,
    Selection,
    StepResult,
    choose_grid,
    final_implausible,
    fold_fits,
    resolution_check,
    run_selection,
)

__all__ = ["diagnose", "rival_statement", "separating_experiment"]

#: The experiment that tells two explanations apart (unordered pairs of effect names).
SEPARATING: dict[frozenset[str], str] = {
    frozenset({"creep", "sensor_drift"}): "a step-and-hold longer than the slow motion (creep "
    "follows the step and settles; a drift goes on regardless of the input)",
    frozenset({"delay", "rate_dependence"}): "the same loop at several drive frequencies with "
    "sharp reversals (a delay shifts the whole output in time; rate dependence widens the loops "
    "with the rate)",
    frozenset({"delay", "structural_resonance"}): "a fast input step (a mode overshoots and rings; "
    "a delay only shifts the step)",
    frozenset({"creep", "rate_dependence"}): "a step-and-hold (creep keeps moving during the "
    "hold; rate dependence acts only while the input moves)",
    frozenset({"non_congruence", "rate_dependence"}): "the same minor loop at several rates and "
    "at several output levels (rate dependence changes with the rate, non-congruence with the "
    "level)",
    frozenset({"non_congruence", "sensor_drift"}): "the same minor loop repeated at the start and "
    "the end of a run (a drift moves it, non-congruence does not)",
    frozenset({"delay", "creep"}): "a step-and-hold (a delay is over within milliseconds, creep "
    "goes on for seconds)",
    frozenset({"rate_dependence", "sensor_drift"}): "the same loop at several drive rates, "
    "repeated at the start and the end of the run (rate dependence changes the loop with the "
    "rate; a drift moves it in time)",
}

#: What separates the actuator's non-congruence from a nonlinear sensor curve, the two readings
#: of the one form ``non_congruence/output_curve`` (not two effect names, so not in SEPARATING).
ACTUATOR_OR_SENSOR = (
    "the same minor loop at several output levels read by a second, calibrated sensor (a "
    "sensor curve is the reading's; non-congruence changes the actuator's own loops)"
)


def separating_experiment(a: str, b: str) -> str:
    """Name the experiment that separates effect ``a`` from effect ``b``."""
    return SEPARATING.get(
        frozenset({a, b}),
        "experiments that excite one of them alone (steps and holds, several rates, several "
        "output levels)",
    )


#: Share of the kept effect's held-out gain above which the best other name is reported as
#: nearly as good (with the experiment that separates the two).
NEARLY_AS_GOOD = 0.8


def rival_statement(
    step: StepResult, key: str, names: Mapping[str, str], *, seed: int = 0
) -> tuple[str, dict[str, str] | None]:
    """Say what the kept candidate ``key``'s evidence tells of the other names at its step.

    ``step`` is the selection step that kept it (scores with held-out block errors, gains,
    whether each qualifies, parameter counts), ``names`` the effect name of every candidate
    key.  A qualifying candidate of another name that is not significantly worse (one-sided
    sign-flip test over the held-out blocks, p >= 0.05) makes the choice ``AMBIGUOUS``; else
    the best qualifying other name with at least :data:`NEARLY_AS_GOOD` of the gain is
    reported as nearly as good (a refused fit is not: blind seed 42's warm-up 011 read "also
    nearly as good: sensor_drift" for a drift refused at that step).  Either way the text
    names the experiment that separates the two (:func:`separating_experiment`).  Returns the
    text (empty, or starting with "; ") and, when ambiguous, the report's ``{"effect",
    "rival", "experiment"}`` entry.
    """
    name, sc, gain = names[key], step.scores[key], step.gains[key]
    others = sorted(  # a refused fit is no rival, nor nearly as good
        (n for n in step.scores if names[n] != name and step.gains[n] > 0 and step.qualifies[n]),
        key=lambda n: -step.gains[n],
    )
    rivals = [
        n
        for n in others
        if sign_flip_p(step.scores[n].sse_blocks - sc.sse_blocks, seed=seed) >= 0.05
    ]
    if rivals:
        r = rivals[0]
        how = separating_experiment(name, names[r])
        text = (
            f"; AMBIGUOUS: {r} explains the data equally well within the noise "
            f"({100 * step.gains[r]:.0f} % lower, {step.n_params[r]:.3g} parameters; sign-flip "
            f"p >= 0.05); to separate {name} from {names[r]}: {how}"
        )
        return text, {"effect": name, "rival": names[r], "experiment": how}
    if others and step.gains[others[0]] > NEARLY_AS_GOOD * gain:
        o = others[0]
        return (
            f"; also nearly as good: {o} ({100 * step.gains[o]:.0f} % lower, "
            f"{step.n_params[o]:.3g} parameters); to separate {name} from {names[o]}: "
            f"{separating_experiment(name, names[o])}"
        ), None
    return "", None


RecordingLike = Union[Recording, str, "os.PathLike[str]"]
_F = TypeVar("_F", bound=Callable[..., Any])


def _one_blas_thread(f: _F) -> _F:
    """Run ``f`` with BLAS limited to one thread.

    A diagnosis solves thousands of small (~232 x 232) systems between C++ loops that run on
    every core; a threaded BLAS gains nothing on them and its spinning threads take the cores
    from those loops (measured: 64 s vs 44 s for the six-recording benchmark on 2 cores).
    """

    @functools.wraps(f)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1, user_api="blas"):
            return f(*args, **kwargs)

    return cast(_F, wrapper)


def _load(recs: Sequence[RecordingLike] | Recording | None) -> list[Recording]:
    if recs is None:
        return []
    if isinstance(recs, Recording):
        return [recs]
    out = []
    for r in recs:
        if isinstance(r, Recording):
            out.append(r)
        elif isinstance(r, (str, os.PathLike)):
            rec = Recording.load(r)
            if not any(
                isinstance(rec.metadata.get(k), str) and rec.metadata.get(k)
                for k in ("name", "experiment")
            ):
                rec.metadata["name"] = os.path.splitext(os.path.basename(os.fspath(r)))[0]
            out.append(rec)
        else:
            raise TypeError(
                f"recordings: expected Recording objects or file paths, got {type(r).__name__}"
            )
    return out


def _same_data(a: Recording, b: Recording) -> bool:
    """Return whether two recordings hold the same input and output samples."""
    return (
        a.u.shape == b.u.shape
        and a.y.shape == b.y.shape
        and np.array_equal(a.u, b.u)
        and np.array_equal(a.y, b.y)
    )


def _drop_identification(recs: list[Recording], ident: list[Recording]) -> list[Recording]:
    """Leave out recordings that are also identification data, with a warning."""
    if not ident:
        return recs
    keep = []
    for k, r in enumerate(recs):
        if any(_same_data(r, q) for q in ident):
            nm = r.metadata.get("name") or r.metadata.get("experiment") or f"recording {k}"
            warnings.warn(
                f"recordings: {nm!r} holds the same samples as an identification recording; "
                "it is left out of the diagnosis (identification data are training data only, "
                "never scored - pass it once, as identification)",
                UserWarning,
                stacklevel=4,  # _drop_identification <- diagnose <- _one_blas_thread <- caller
            )
        else:
            keep.append(r)
    if not keep:
        raise ValueError(
            "recordings: every recording is also an identification recording; nothing is left "
            "to diagnose (give recordings of other experiments)"
        )
    return keep


@_one_blas_thread
def diagnose(
    model: PreisachModel,
    recordings: Sequence[RecordingLike] | Recording,
    *,
    identification: Sequence[RecordingLike] | Recording | None = None,
    candidates: Sequence[str | Candidate] | None = None,
    initial_states: Sequence[State | str | None] | None = None,
    refit: bool | None = None,
    refit_levels: int = 21,
    cv: str = "auto",
    block_length: float | None = None,
    min_gain: float = 0.10,
    noise_factor: float = 1.0,
    alpha: float = 0.01,
    max_effects: int = 3,
    noise_ratio: float = 2.0,
    sigma: float | None = None,
    max_delay: float | None = None,
    progress: bool | Callable[[str], None] | None = True,
) -> DiagnosisReport:
    """Find where a model and recordings disagree, name the missing physics and model it.

    Every recording is simulated through ``model``; the residual ``y_meas - y_sim`` is
    analysed (where in time and in which recording, over which input range and direction,
    in which frequency band, and how it follows the input rate, the time since the last
    reversal or move, the output level and the absolute time).  Candidate explanations -
    physics blocks with few parameters around the Preisach operator - are then fitted on
    training data and scored on held-out data in a greedy forward selection that keeps an
    effect only when it lowers the held-out error clearly beyond what the noise allows (see
    :mod:`preisach.diagnose.selection`).

    Parameters
    ----------
    model : PreisachModel
        The classical model to diagnose (identified, or built in).  Volts in, volts out.
    recordings : sequence of Recording or path
        Recordings of the same device, preferably of experiments other than the
        identification (wiping-out, CML, multi-frequency sine, step-and-hold, noise).
    identification : Recording, path or sequence of them, optional
        The recording(s) the model was identified from (e.g. the FOD sweep).  Default: the
        ones the model carries (:attr:`PreisachModel.identification`, stored by
        ``preisach identify``); pass an empty list to diagnose without them.  They are used
        for training only; with them the Preisach weights are refitted together with every
        candidate (the sweep carries the effect too, so the identified model has absorbed
        part of it).  A diagnosis recording with the same input and output samples as an
        identification recording (e.g. from a glob that matched the sweep too) is left out
        of the diagnosed set with a ``UserWarning``.
    candidates : sequence of str or Candidate, optional
        Which explanations to test; default all of :data:`~preisach.diagnose.CANDIDATES`.
        An effect name (``rate_dependence``, ``structural_resonance``, ``creep``, ``delay``,
        ``sensor_drift``, ``non_congruence``, ``gain_offset``) tests all its forms; one
        form is given by its key (e.g. ``delay/lagrange``, ``non_congruence/output_curve``).
    initial_states : sequence, optional
        One per recording: a :class:`~preisach.State` or ``"negative_saturation"``,
        ``"positive_saturation"``, ``"anhysteretic"``, ``"unknown"``, ``"burn_in"`` or
        None.  Default (None): the recording's ``initial_state`` metadata, else
        negative/positive saturation when the input starts within 1 % of the range ends,
        else unknown: the initial state is a nuisance parameter, chosen among a rise from
        negative saturation, a fall from positive saturation and the anhysteretic state by
        the given model's least-squares fit to the recording, and every sample is scored
        (``"burn_in"``: the anhysteretic state with the samples before the input has visited
        both its extremes left out, the earlier behaviour).
    refit : bool, optional
        Refit the Preisach weights with every candidate (default: when ``identification`` is
        given).
    refit_levels : int
        Grid of the refitted weights when the model has more than 41 levels.
    cv : {"auto", "blocks", "recordings"}
        Held-out scheme: alternating time blocks within every recording (``"auto"`` and
        ``"blocks"``) or groups of whole recordings held out (``"recordings"``, stricter: an
        effect must carry over to experiments it was not fitted on).  One exception under
        ``"recordings"``: a sensor drift is a per-recording nuisance, so a held-out
        recording's drift curve is fitted on its own blocks of the other parity (each sample
        is still predicted by a drift fitted without it); the base weights and every other
        effect come from the other recordings only.
    block_length : float, optional
        Length (s) of the time blocks (units of the significance test, and the folds of the
        ``"blocks"`` scheme); default a tenth of the longest recording, within [0.25, 2] s.
    min_gain : float
        Smallest relative reduction of the held-out RMSE for an effect to be kept (default
        0.10 = 10 %).
    noise_factor : float
        An effect must reduce the held-out mean-square error by at least this multiple of
        the noise variance (default 1: the effect is at least as large as the noise).
    alpha : float
        Level of the one-sided sign-flip test over held-out blocks (default 0.01).
    max_effects : int
        Most effects kept (default 3).
    noise_ratio : float
        The noise test: the held-out residual after the kept effects is consistent with the
        noise when its RMS is at most ``noise_ratio`` times the noise (default 2, i.e. an
        excess variance of at most 3 noise variances; a re-identified classical model on
        effect-free data leaves 1.4-1.7 x, its own discretisation error).  Nothing kept and
        above the bound, with a refitted base: the resolution check
        (:func:`~preisach.diagnose.selection.resolution_check`: a classical model on a
        61-level grid with a smooth density and free initial states, predicting interleaved
        10 ms stretches) decides - within the same bound the verdict is ``"none"`` (the
        residual is the base's resolution), else ``"unexplained"``; without a refit:
        ``"unexplained"``.  Effects kept and above the bound: the remainder is reported as
        :attr:`DiagnosisReport.unexplained`.
    sigma : float, optional
        Noise standard deviation (V) when known; default estimated from the data.
    max_delay : float, optional
        Largest delay (s) the ``delay`` candidate may take; default max(50 ms, 10 samples).
    progress : bool or callable
        ``True`` (default): a progress bar over the stages and candidate fits; ``False``:
        nothing; a callable gets every progress line (e.g. ``print``).

    Returns
    -------
    DiagnosisReport
        ``verdict`` (the most important effect or ``"none"``), the kept effects with
        evidence, where they act, parameters with uncertainties and one-line statements,
        RMSE before and after, residual analyses, the candidate table, ``.plot()``,
        ``.to_json()`` and the augmented ``.model``.

    """
    t_start = time.perf_counter()
    _check_options(model, noise_ratio, min_gain, noise_factor, alpha, max_effects)
    ident_in = (
        list(getattr(model, "identification", []))
        if identification is None
        else _load(identification)
    )
    recs_in = _drop_identification(_load(recordings), ident_in)
    unit = output_unit(recs_in)  # the unit every output amount in the report is in
    cands = _resolve_candidates(candidates)
    do_refit = bool(ident_in) if refit is None else bool(refit)
    progress, bar = line_progress(progress, "diagnose", unit="step")

    # 1. prepare the data: initial states, time blocks, the context of the candidates
    recs = prepare_recordings(
        model,
        recs_in,
        initial_states=initial_states,
        block_length=block_length,
        identification=ident_in,
    )
    ctx = Context(
        model,
        recs,
        max_delay=max_delay,
        refit=do_refit,
        refit_levels=refit_levels,
        output_unit=unit,
    )
    # 2. the baseline: the given model's predictions and the noise level
    base = _baseline(ctx, sigma)
    ctx.noise_sigma = base.sigma
    if progress:
        progress(
            f"{len(ctx.diag)} recordings ({len(recs) - len(ctx.diag)} for identification), "
            f"{sum(r.n for r in recs)} samples; noise {amount_text(base.sigma, unit, '.3g')}"
        )
    # 3. the refitted base: the model's grid, or a finer or firmer one when it fails
    grid: dict[str, Any] | None = None
    gc: GridChoice | None = None
    if do_refit:
        gc = choose_grid(
            ctx,
            lambda lv, ridge: Context(
                model,
                recs,
                max_delay=max_delay,
                refit=True,
                levels=lv,
                ridge=ridge,
                output_unit=unit,
            ),
            sigma=base.sigma,
            noise_ratio=noise_ratio,
            alpha=alpha,
            min_gain=min_gain,
            cv=cv,
            progress=progress,
        )
        ctx, grid = gc.ctx, gc.report
    # 4. greedy forward selection on held-out data
    sel = run_selection(
        ctx,
        cands,
        sigma=base.sigma,
        cv=cv,
        min_gain=min_gain,
        noise_factor=noise_factor,
        alpha=alpha,
        max_effects=int(max_effects),
        progress=progress,
        base=gc,
        noise_ratio=noise_ratio,
    )
    # 5. the kept effects refitted on all usable samples
    final = _final_fits(ctx, cands, sel, do_refit)
    # 6. the augmented model and the report
    report = _report(
        model,
        ctx,
        sel,
        base,
        final,
        do_refit,
        noise_ratio,
        time.perf_counter() - t_start,
        grid,
        alpha,
        min_gain,
        noise_factor,
    )
    if progress:
        progress(f"verdict: {report.verdict} ({report.seconds:.1f} s)")
    bar.close()
    return report


def _check_options(
    model: PreisachModel,
    noise_ratio: float,
    min_gain: float,
    noise_factor: float,
    alpha: float,
    max_effects: int,
) -> None:
    """Reject a wrong model type or option values, naming the argument."""
    if not isinstance(model, PreisachModel):
        raise TypeError(f"model: expected a PreisachModel, got {type(model).__name__}")
    if not (np.isfinite(noise_ratio) and noise_ratio >= 1):
        raise ValueError(f"noise_ratio: must be a finite number >= 1, got {noise_ratio!r}")
    for name, v in (("min_gain", min_gain), ("noise_factor", noise_factor)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name}: must be a finite number >= 0, got {v!r}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha: must lie in (0, 1), got {alpha!r}")
    if int(max_effects) < 0:
        raise ValueError(f"max_effects: must be >= 0, got {max_effects!r}")


def _resolve_candidates(candidates: Sequence[str | Candidate] | None) -> list[Candidate]:
    """Candidate objects for effect names (all the effect's forms), form keys or instances.

    Names and keys that cover the same form test it once; two instances of one form are an
    error (their settings would compete).
    """
    if candidates is None:
        return [c() for c in CANDIDATES.values()]
    cands: dict[str, Candidate] = {}
    instances: set[str] = set()
    for c in candidates:
        if isinstance(c, Candidate):
            if c.key in instances:
                raise ValueError(f"candidates: two instances of {c.key!r}")
            instances.add(c.key)
            cands[c.key] = c
            continue
        if isinstance(c, str) and any(v.name == c for v in CANDIDATES.values()):
            forms = [k for k, v in CANDIDATES.items() if v.name == c]
        elif isinstance(c, str) and c in CANDIDATES:
            forms = [c]
        else:
            raise ValueError(
                f"candidates: unknown candidate {c!r}; choose from {sorted(CANDIDATES)}"
            )
        for k in forms:
            cands.setdefault(k, CANDIDATES[k]())
    return list(cands.values())


@dataclass
class _Baseline:
    """The given model's predictions and residuals (NaN where not usable), and the noise."""

    pred: list[np.ndarray]
    res: list[np.ndarray]
    sigma: float


def _baseline(ctx: Context, sigma: float | None) -> _Baseline:
    """Predict every recording with the given model; the noise from the data unless given."""
    recs = ctx.recs
    pred0 = ctx.predict(Chain(ctx.given))
    res0 = [np.where(r.usable, r.y - p, np.nan) for r, p in zip(recs, pred0)]
    if sigma is None:
        sig = np.array(
            [noise_sigma(np.nan_to_num(res0[i][recs[i].usable])) for i in range(len(recs))], float
        )
        n = np.array([int(r.usable.sum()) for r in recs], float)
        ok = np.isfinite(sig)
        sigma_hat = float(np.sqrt(np.average(sig[ok] ** 2, weights=n[ok]))) if ok.any() else 0.0
    else:
        sigma_hat = float(sigma)
        if not (np.isfinite(sigma_hat) and sigma_hat >= 0):
            raise ValueError(f"sigma: must be a finite number >= 0 (V), got {sigma!r}")
    return _Baseline(pred0, res0, sigma_hat)


@dataclass
class _Final:
    """The kept effects refitted on all usable samples."""

    names: list[str]
    chain: Chain
    effects: list[EffectReport]
    drift_eff: FittedEffect | None
    ambiguous: list[dict[str, str]]


def _full_pred(ctx: Context, ch: Chain, with_drift: bool) -> list[np.ndarray]:
    """Predictions of every recording by ``ch``, with each one's drift fitted on it."""
    preds = ctx.predict(ch)
    if not with_drift:
        return preds
    return [
        p + ctx.drift_basis(i) @ ctx.drift_fit(i, r.y - p, r.usable)
        for i, (r, p) in enumerate(zip(ctx.recs, preds))
    ]


def _final_fits(ctx: Context, cands: list[Candidate], sel: Selection, do_refit: bool) -> _Final:
    """Refit the kept effects on all usable samples, in the order of selection.

    As in the selection, effects kept before the drift are fitted without it, and the
    weights are refitted with the drift where it was kept.
    """
    recs, diag, steps = ctx.recs, ctx.diag, sel.steps
    by_key = {c.key: c for c in cands}
    names = [by_key[k].name for k in sel.kept]
    all_train = [r.usable.copy() for r in recs]
    base = ctx.refit_base([], ctx.given, all_train, False) if do_refit else ctx.given
    chain = Chain(base)
    effects: list[EffectReport] = []
    drift_eff: FittedEffect | None = None
    drift_curves: list[np.ndarray] = [np.zeros(r.n) for r in recs]
    drift_so_far = False
    ambiguous: list[dict[str, str]] = []
    for k, key in enumerate(sel.kept):
        cand = by_key[key]
        name = cand.name
        before = _full_pred(ctx, chain, drift_so_far)
        if isinstance(cand, DriftCandidate):
            drift_so_far = True
            if ctx.refits(chain):
                chain = Chain(
                    ctx.refit_base(chain.effects, chain.base, all_train, True), chain.effects
                )
            after = _full_pred(ctx, chain, True)
            plain = ctx.predict(chain)
            drift_curves = [a - b for a, b in zip(after, plain)]
            slopes, w = [], []
            for i in diag:
                r, d = recs[i], drift_curves[i]
                T = float(r.t[-1] - r.t[0])
                if T > 0:
                    slopes.append((d[-1] - d[0]) / T)
                    w.append(T)
            rate = float(np.average(slopes, weights=w)) if slopes else 0.0
            cov = np.array([[np.var(slopes, ddof=1) / len(slopes)]]) if len(slopes) > 1 else None
            eff = FittedEffect(cand, np.array([rate]), cov)
            drift_eff = eff
        else:
            # a mode named because both folds found it is fitted from their fits: on all
            # samples the error has other minima (blind seed 63's case 002: both folds 269 Hz,
            # the truth 270 Hz; from its own starts the fit on all samples went to 63 Hz)
            by_ring = key in steps[k].by_ring
            folds = fold_fits(cand, steps[k].chains[key]) if by_ring else None
            chain = ctx.fit(cand, chain, all_train, drift_so_far, starts=folds)
            eff = chain.effects[-1]
            eff.cov = ctx.covariance(chain, all_train, drift_so_far)
            after = _full_pred(ctx, chain, drift_so_far)
        st = steps[k]
        sc = st.scores[key]
        gain = st.gains[key]
        ku = display_unit(ctx.output_unit)[0]
        ev = (
            f"held-out RMSE {ku * st.baseline.rmse:.4g} -> "
            f"{amount_text(sc.rmse, ctx.output_unit, '.4g')} "
            f"({100 * gain:.0f} % lower); explains {st.explained[key]:.3g} x the noise variance; "
            f"sign-flip p = {st.p_values[key]:.2g} "
            f"over {sc.n_blocks.size} held-out blocks; {st.n_params[key]:.3g} fitted parameters"
        )
        if cand.variant:
            ev += f"; form: {cand.variant.replace('_', ' ')}"
        held, qual = st.holds.get(key), key in st.by_holds
        if held is not None:
            ev += ("; qualified on the holds: " if qual else "; ") + held.statement()
        if key in st.by_ring:
            ev += f"; qualified on its repeated ring: {st.by_ring[key]}"
        if key in st.fast_creep:
            ev += f"; qualified although fast: {st.fast_creep[key]}"
        bad = final_implausible(ctx, cand, chain, st, key, sel.holds)
        if bad:
            ev += f"; CAUTION: the fit on all usable samples is implausible for its name: {bad}"
        text, amb = rival_statement(st, key, {n: c.name for n, c in by_key.items()}, seed=k)
        ev += text
        if amb is not None:
            ambiguous.append(amb)
        dsub = [recs[i] for i in diag]
        corr = [after[i] - before[i] for i in diag]
        params = cand.report_params(eff.x, eff.cov, ctx)
        for pkey, v in cand.fixed.items():
            params[pkey] = {
                "value": float(v),
                "std": 0.0,
                "unit": dict(cand.block_type.PARAMS).get(pkey, ""),
                "fixed": True,
            }
        if isinstance(cand, DriftCandidate):
            params["peak_to_peak"] = _peak_to_peak(ctx, drift_curves)
        effects.append(
            EffectReport(
                name=name,
                statement=cand.statement(eff.x, eff.cov, ctx),
                evidence=ev,
                where=where_of(dsub, corr, ctx.u_span),
                parameters=params,
                heldout_rmse_before=st.baseline.rmse,
                heldout_rmse_after=sc.rmse,
                holds=None if held is None else {**held.as_dict(), "qualified": qual},
            )
        )
    return _Final(names, chain, effects, drift_eff, ambiguous)


def _peak_to_peak(ctx: Context, curves: Sequence[np.ndarray]) -> dict[str, Any]:
    """Return the ``peak_to_peak`` parameter of fitted curves (largest, and per recording)."""
    p2p = {ctx.recs[i].name: float(np.ptp(curves[i][ctx.recs[i].usable])) for i in ctx.diag}
    return {
        "value": max(p2p.values()),
        "std": float("nan"),
        "unit": ctx.output_unit or "V",
        "per_recording": p2p,
    }


def _fine_rmse(check: dict[str, Any], gain: float, sigma: float) -> tuple[float, float]:
    """Return the fine classical model's held-out RMSE (V) without and with what it found.

    ``check`` is the resolution check's report; ``gain`` what the finding removes from the
    held-out mean-square error, in noise variances (``sigma``, V).
    """
    before = float(check["heldout_rmse"])
    return before, math.sqrt(max(before**2 - gain * sigma**2, 0.0))


def _wander_drift(
    ctx: Context, sel: Selection, motion: HoldMotion, sigma: float, alpha: float
) -> EffectReport | None:
    """Name a sensor drift from its wander within the holds (or return None).

    When nothing was kept, the output moves within the input holds without following the
    moves into them (:class:`~preisach.diagnose.holds.HoldMotion`: no rate-independent model
    moves there, and creep would go on in the direction of each move), and that motion
    predicts itself on held-out stretches of the holds
    (:func:`~preisach.diagnose.holds.hold_wander`), the sensor drifts - faster than the
    drift curve's held-out time blocks can follow (it was tried in the selection and did not
    predict the blocks it was not fitted on), so it is reported as a wander of the reading
    (its RMS), not as a curve to subtract.
    """
    if motion.follows_t >= HOLD_FOLLOWS_T:
        return None
    if not sel.steps or "sensor_drift" not in sel.steps[0].scores:
        return None  # the drift was not among the candidates
    dts = [r.dt for r in ctx.recs]
    wander = hold_wander(sel.steps[-1].baseline, sel.holds, sigma, dts, seed=len(sel.steps))
    if wander is None or not wander.qualifies(alpha):
        return None
    curves = wander_curves(sel.steps[-1].baseline, sel.holds, dts)
    block = max(
        (r.t[-1] - r.t[0]) / (r.block.max() - r.block.min() + 1)
        for r in (ctx.recs[i] for i in ctx.diag)
    )
    amount = amount_text(wander.wander_rms, ctx.output_unit, ".2g")
    return EffectReport(
        name="sensor_drift",
        statement=(
            f"the reading wanders by {amount} (RMS within the input holds, beyond the noise) "
            "without following the input's moves: a sensor or electronics drift faster than "
            f"a drift curve fitted on other time blocks of about {block:.2g} s can predict; "
            "hold the input and average, or recalibrate the sensor's offset often"
        ),
        evidence=(
            f"{wander.statement()}; {motion.describe()}; "
            "no rate-independent model moves while the input holds, and creep would follow "
            "the moves"
        ),
        where=where_of([ctx.recs[i] for i in ctx.diag], [curves[i] for i in ctx.diag], ctx.u_span),
        parameters={
            "wander_rms": {
                "value": wander.wander_rms,
                "std": float("nan"),
                "unit": ctx.output_unit or "V",
            },
        },
        heldout_rmse_before=wander.base_ratio * sigma,
        heldout_rmse_after=wander.ratio * sigma,
        holds={**wander.as_dict(), "qualified": True},
    )


def _after_effect(ctx: Context, sel: Selection, motion: HoldMotion, sigma: float) -> EffectReport:
    """Name creep from an after-effect in the holds that no single hold shows.

    When nothing was kept, the output's motion within the input holds stays within the
    noise's RMS (below :data:`~.holds.HOLD_EXCESS` x), yet across the holds it goes on in the
    direction of the move into each (:attr:`~.holds.HoldMotion.after_effect`, one-sided
    p < :data:`~.holds.HOLD_AFTER_EFFECT_P`).  No rate-independent model moves while the
    input holds, whatever its grid or initial state, and a sensor drift does not know the
    moves: an after-effect of the moves, creep.  The candidates' creep forms could not show
    it against the base's resolution (blind seed-53 case 016, a threshold creep operator
    3.9 x the noise over the recordings: the creep form gained 3.6 %, the fine classical
    model left 1.36 x the noise, the holds' motion followed the moves at t = 12.8 over nine
    holds).  No block is added to the model: the curves are each hold's motion since it
    began, the held-out RMSE before and after the within-hold RMS.
    """
    curves = motion_curves(sel.steps[-1].baseline, sel.holds)
    diag = list(ctx.diag)
    share = f"{100 * motion.follows:.2g} %"
    return EffectReport(
        name="creep",
        statement=(
            "after input changes the output keeps moving the way it moved (creep): within "
            f"the input holds it goes on by about {share} of the move into each, too little "
            "for any one hold to show beyond the noise but systematic over all of them; no "
            "rate-independent model moves while the input holds, and a sensor drift would "
            "not follow the moves; to measure it, hold the input for several seconds after "
            "steps of both signs and fit a creep model to those holds"
        ),
        evidence=(
            f"{motion.describe()}; the motion from the first to the last third of each hold "
            f"on the output's move into it: {share} of the move, t = {motion.follows_t:.3g} "
            f"over {motion.n_pieces} holds (one-sided p = {motion.follows_p:.2g}; bar "
            f"{HOLD_AFTER_EFFECT_P:g}, holds within {HOLD_EXCESS:g} x the noise)"
        ),
        where=where_of([ctx.recs[i] for i in diag], [curves[i] for i in diag], ctx.u_span),
        parameters={
            "follows_moves": {  # the share of the move into a hold that goes on within it
                "value": motion.follows,
                "std": abs(motion.follows / motion.follows_t),
                "unit": "",
            },
            "peak_to_peak": _peak_to_peak(ctx, curves),
        },
        heldout_rmse_before=motion.ratio * sigma,
        heldout_rmse_after=motion.ratio * sigma,
        holds=motion.as_dict(),
    )


def _classical_change(
    ctx: Context,
    check: dict[str, Any],
    curves: list[np.ndarray],
    motion: HoldMotion | None,
    sigma: float,
) -> EffectReport | None:
    """Name a change in time that only the fine classical model shows (or return None).

    When nothing was kept, the fine classical model of the resolution check (free initial
    states) predicts interleaved stretches within the noise bound, and a slow drift curve per
    recording adds clearly to it (:func:`~preisach.diagnose.selection.resolution_check`),
    something changes in time that no classical model with any initial state follows.  The
    candidates' own fits could not show it: their gain sat below the base's resolution
    residual (blind seed-20 case 001, a thermal warm-up 14.6 x the noise: 0.33 noise
    variances beyond the fine model, p = 0.00025, while the refitted base left 5.8 x; seed-21
    case 024, a Kelvin-Voigt creep: 1.05 beyond it, base 4.0 x).  Input holds tell which:
    a residual that goes on in the direction of the moves into them (``follows_t`` at least
    :data:`~.holds.HOLD_FOLLOWS_T`) is creep, one that does not is a sensor drift; without
    at least :data:`~.holds.HOLD_MIN_PIECES` holds nothing is named.  No block is added to
    the model: the curves are the fine model's per-recording drift, a measure of the size.
    """
    if motion is None or motion.n_pieces < HOLD_MIN_PIECES:
        return None
    creep = motion.follows_t >= HOLD_FOLLOWS_T
    gain = float(check["drift"]["gain_noise_variances"])
    p = float(check["drift"]["p"])
    finer = check["drift"]["finer"][-1]  # the grid that confirmed it
    before, after = _fine_rmse(check, gain, sigma)
    diag = list(ctx.diag)
    size = _peak_to_peak(ctx, curves)
    amount = amount_text(size["value"], ctx.output_unit, ".2g")
    hidden = (
        "too small against the model's resolution for a fit on other time blocks to show; "
        "identify on a finer grid of reversal levels so that it stands out"
    )
    if creep:
        name = "creep"
        statement = (
            "after input changes the output keeps moving the way it moved (creep), a slow "
            f"change of up to {amount} peak to peak within a recording beyond any classical "
            f"model, {hidden}, and wait for it to settle after moves"
        )
        why = "it follows them, as creep does"
    else:
        name = "sensor_drift"
        statement = (
            f"the reading drifts by up to {amount} peak to peak within a recording without "
            f"following the input's moves: a sensor, electronics or temperature drift, {hidden}, "
            "and recalibrate the offset during the run"
        )
        why = "it does not follow them, as creep would"
    return EffectReport(
        name=name,
        statement=statement,
        evidence=(
            f"a classical Preisach model on a {check['levels']}-level grid with free initial "
            f"states predicts interleaved {1e3 * check['stretch_s']:.0f} ms held-out stretches "
            f"at {check['ratio']:.3g} x the noise; a slow drift per recording adds "
            f"{gain:.2g} x the noise variance to it (p = {p:.2g}; bar "
            f"{RESOLUTION_BEYOND_CLASSICAL:g}) and {finer['gain_noise_variances']:.2g} x "
            f"(p = {finer['p']:.2g}) to one with {finer['levels']} levels, which no "
            f"classical model with any initial states makes; within {motion.n_pieces} input "
            f"holds the residual's motion on the moves into them has t = "
            f"{motion.follows_t:.2g} (bar {HOLD_FOLLOWS_T:g}): {why}"
        ),
        where=where_of([ctx.recs[i] for i in diag], [curves[i] for i in diag], ctx.u_span),
        parameters={"peak_to_peak": size},
        heldout_rmse_before=before,
        heldout_rmse_after=after,
        holds=motion.as_dict(),
    )


def _classical_curve(
    ctx: Context, check: dict[str, Any], curves: list[np.ndarray], sigma: float
) -> EffectReport:
    """Name loop heights that change with the output level, found beyond the fine model.

    When nothing was kept, the fine classical model of the resolution check predicts
    interleaved stretches within the noise bound, and a static curve of the output adds
    clearly to it (:func:`~preisach.diagnose.congruency.output_curve_check`, the bar
    :data:`~preisach.diagnose.selection.RESOLUTION_BEYOND_CLASSICAL`): minor loops change their
    height with the output level, which no classical (congruent) model does.  The
    candidates' fits could not show it against the base's resolution (blind seed-21 case
    006, a non-congruent device: 0.14 noise variances beyond the fine model, p = 0.0002,
    while the refitted base left 2.9 x the noise).  It is named ``non_congruence``; a sensor
    reading through a nonlinear curve gives the same readings and is named with it.  No
    block is added to the model: ``curves`` (V, per recording) are the fine model's output
    curve, a measure of the size.
    """
    oc = check["output_curve"]
    gain, p = float(oc["gain_noise_variances"]), float(oc["p"])
    before, after = _fine_rmse(check, gain, sigma)

    def height(d: float) -> float:  # a minor loop's height at output level d, relative
        slope = sum(k * float(c) * d ** (k - 1) for k, c in zip(oc["powers"], oc["coefficients"]))
        return 1.0 + float(slope) / max(ctx.y_half_span, 1e-300)

    lo, hi = height(-0.8), height(0.8)
    diag = list(ctx.diag)
    return EffectReport(
        name="non_congruence",
        statement=(
            "minor loops change their height with the output level: relative to the middle "
            f"of the output range, {100 * (lo - 1):+.2g} % near the bottom and "
            f"{100 * (hi - 1):+.2g} % near the top, which no classical (congruent) Preisach "
            "model does - the actuator's loops scale with its strain (non-congruence, e.g. a "
            "product model), or the sensor reads through a nonlinear curve (sensor "
            "nonlinearity), which these recordings cannot tell apart; to separate them: "
            f"{ACTUATOR_OR_SENSOR}"
        ),
        evidence=(
            f"a classical Preisach model on a {check['levels']}-level grid with free initial "
            f"states predicts interleaved {1e3 * check['stretch_s']:.0f} ms held-out stretches "
            f"at {check['ratio']:.3g} x the noise; a static curve of the output (powers "
            f"{', '.join(str(k) for k in oc['powers'])} of its level) adds {gain:.2g} x the "
            f"noise variance to it (p = {p:.2g}; bar {RESOLUTION_BEYOND_CLASSICAL:g}), which no "
            "classical model makes; too small against the model's resolution for a fit on "
            "other time blocks to show: identify on a finer grid of reversal levels so that "
            "it stands out"
        ),
        where=where_of([ctx.recs[i] for i in diag], [curves[i] for i in diag], ctx.u_span),
        parameters={
            "height_bottom": {"value": lo, "std": float("nan"), "unit": ""},
            "height_top": {"value": hi, "std": float("nan"), "unit": ""},
            "peak_to_peak": _peak_to_peak(ctx, curves),
        },
        heldout_rmse_before=before,
        heldout_rmse_after=after,
    )


def _loop_congruency(ctx: Context, check: dict[str, Any], curves: list[np.ndarray]) -> EffectReport:
    """Name minor loops between the same inputs that differ in shape or height (non-congruence).

    When nothing was kept and the fine classical model of the resolution check is within
    the noise bound with neither a curve of the output nor a drift adding to it, or is above
    that bound (no resolution makes loops congruent), the recordings' comparable minor
    loops - the congruent-minor-loop experiment repeats one at two output levels - are
    compared with no model at all
    (:func:`~preisach.diagnose.congruency.minor_loop_check`): a classical Preisach model's
    loops between the same inputs differ by a vertical shift only, however the weights are
    refitted, and have the same height wherever their output level.  A refit that absorbs a
    non-congruence on every other experiment cannot hide it there.  No block is added to the
    model (the held-out RMSE is the fine model's before and after); ``curves`` (V, per
    recording) are the shape differences on the later loops.
    """
    lc = check["minor_loops"]
    evidence = (
        f"a classical Preisach model on a {check['levels']}-level grid with free initial "
        f"states predicts interleaved {1e3 * check['stretch_s']:.0f} ms held-out stretches "
        f"at {check['ratio']:.3g} x the noise, but the recordings' minor loops between "
        f"the same inputs differ {loop_difference_text(lc, ctx.output_unit, bars=True)}, tests "
        "of Mayergoyz's congruency property that fit no model"
    )
    return _loop_effect(ctx, lc, curves, evidence, float(check["heldout_rmse"]))


def _loop_effect(
    ctx: Context,
    lc: dict[str, Any],
    curves: list[np.ndarray],
    evidence: str,
    rmse: float,
) -> EffectReport:
    """Return the ``non_congruence`` report of minor loops that differ (``lc``: the check's dict).

    No block is added: the held-out RMSE ``rmse`` (V) stays.
    """
    big = lc["largest"]
    unit = ctx.output_unit
    moved = big["level_b"] - big["level_a"]
    heights = f"{100 * lc['height_per_volt'] * moved:+.2g} %"
    if "shape" in lc["found_by"]:
        change = (
            f"changes its shape by {amount_text(big['shape_rms'], unit, '.2g')} RMS beyond a "
            f"vertical shift from t = {big['t_a']:.3g} s to {big['t_b']:.3g} s, its output "
            f"level moved by {amount_text(moved, unit, '.2g')} (loops' heights: {heights} "
            "over that move)"
        )
    else:  # the height test, alone or jointly with the output curve
        change = (
            f"changes its height by {heights} from t = {big['t_a']:.3g} s to "
            f"{big['t_b']:.3g} s, its output level moved by {amount_text(moved, unit, '.2g')}, "
            "its shape otherwise the same within the noise"
        )
    return EffectReport(
        name="non_congruence",
        statement=(
            f"minor loops between the same inputs are not congruent: the loop between "
            f"{big['low']:.3g} and {big['high']:.3g} V in '{big['recording']}' {change}; no "
            "classical (congruent) Preisach model does that - the actuator's loops change with its "
            "strain (non-congruence), or the sensor reads through a nonlinear curve (sensor "
            "nonlinearity), which these recordings cannot tell apart; to separate them: "
            f"{ACTUATOR_OR_SENSOR}"
        ),
        evidence=evidence,
        where=where_of([ctx.recs[i] for i in ctx.diag], [curves[i] for i in ctx.diag], ctx.u_span),
        parameters={
            "shape_rms": {
                "value": float(lc["shape_rms"]),
                "std": float("nan"),
                "unit": unit or "V",
            },
            "height_per_volt": {  # a loop's relative height change per unit output level
                "value": float(lc["height_per_volt"]),
                "std": float(lc["height_sd"]),
                "unit": f"1/{unit or 'V'}",
            },
            "peak_to_peak": _peak_to_peak(ctx, curves),
        },
        heldout_rmse_before=rmse,
        heldout_rmse_after=rmse,
    )


def _loops_beside(
    ctx: Context,
    preds: Sequence[np.ndarray],
    names: Sequence[str],
    score: Score,
    holds: HoldPieces,
    sigma: float,
) -> tuple[dict[str, Any], str | None]:
    """Compare the minor loops with the named effects in the model, and say what they show.

    A non-congruence mixed with a larger effect is not named by the selection: beside a
    delay nothing has named yet, the feedback and output-curve forms gain nothing, and the
    tests beyond the fine classical model run only when nothing was kept.  The repeated
    minor loops need no model of the non-congruence: against the augmented model's
    prediction (``preds``, V per recording, with the effects ``names`` kept and the drift
    where it is one of them), loops between the same inputs whose heights still change with
    their output level (the height test of
    :meth:`~preisach.diagnose.congruency.MinorLoopCheck.found_by`, at its own bar; the shape
    test alone reads what a drift or creep fit leaves), while the held-out residual
    (``score``) does not move within the input holds (``holds``), are said in a note - not
    named.  Named, this read was right on the blind mixtures it was written on (11 of them)
    and wrong on the next fresh seeds: blind seeds 62 and 63 named a non-congruence beside a
    rate dependence (viscous switching, height p 7e-4) and beside creep (a Kelvin-Voigt chain,
    p 2e-5), and missed both real ones (docs/diagnosis.md, section 5zb): what a named effect's
    fit leaves can differ between loops run at different output levels.  Returns the check
    (JSON-ready, key ``moves``: whether the holds vetoed it) and the note (None when the
    loops' heights agree).
    """
    lc = minor_loop_check(ctx, sigma, preds=preds)
    out = lc.as_dict()
    motion = hold_motion(score, holds, sigma)
    out["moves"] = bool(motion is not None and (motion.moves or motion.after_effect))
    if "height" not in out["found_by"] or out["moves"]:
        return out, None
    out["largest"] = lc.largest_dict(ctx)
    beside = " and ".join(n.replace("_", " ") for n in names)
    return out, (
        f"beside the {beside}, minor loops between the same inputs still differ "
        f"{loop_difference_text(out, ctx.output_unit, bars=True)}: a non-congruence may be "
        f"there too, or what the {beside} fit leaves differs between the loops - not named "
        "(on fresh blind cases this read named non-congruence where there was none); to tell "
        "them apart, record the same minor loop at two output levels slowly, with holds long "
        f"enough, that the {beside} cannot act on it"
    )


def _unknown_start_note(
    ctx: Context, steps: Sequence[StepResult], names: Sequence[str]
) -> str | None:
    """Say so when non-congruence was tested, not kept, and recordings start from unknown states.

    The output feedback of the non-congruence candidates shifts the relays' input, so an
    unknown initial state chosen as a nuisance is wrong for it until the input has visited
    its extremes, and the profiled weights absorb that error.  Measured on a moving model
    of known feedback (docs/diagnosis.md, section 5h): 2.07 mV of training error at the
    true feedback when every recording starts from saturation (2 mV noise), 7-11 mV when
    they start at 0 V from unknown states - the feedback is then not found.
    """
    tried = any(n.split("/")[0] == "non_congruence" for st in steps for n in st.scores)
    unknown = [i for i in ctx.diag if ctx.recs[i].history is not None]
    if not tried or "non_congruence" in names or not unknown:
        return None
    return (
        f"{len(unknown)} of {len(ctx.diag)} recordings start from an unknown initial state "
        "(chosen as a nuisance), so loops that change with the output level (non-congruence) "
        "are fitted unreliably before the input has visited its extremes and can be missed; "
        "to test for them, start each experiment from a range end (saturation)"
    )


def _nameable(
    rmse: float,
    sigma: float,
    min_gain: float,
    noise_factor: float,
    alpha: float,
    further: bool,
    refit: bool,
    ctx: Context,
) -> dict[str, Any]:
    """Return the smallest effect the selection could have named beside the final model.

    ``rmse`` is the final held-out RMSE (V), ``sigma`` the noise; see
    :func:`~preisach.diagnose.scoring.nameable_rms`.  ``further``: effects were kept (the
    limit is then a further effect's).  Returns ``rms`` (V), ``ratio`` (to the noise) and
    ``statement``.  A "none" at several times the noise does not say that no effect is
    there: a refit of the weights absorbs part of most effects, and what is left must pass
    these bars on held-out data.
    """
    e = nameable_rms(rmse, sigma, min_gain, noise_factor)
    unit = ctx.output_unit
    ratio = e / sigma if sigma > 0 else float("inf")
    noun = "further effect" if further else "effect"
    which = f"a {noun}" if further else f"an {noun}"
    if e >= rmse:
        text = (
            f"the held-out residual ({amount_text(rmse, unit, '.3g')}) is too small for "
            f"{which} to lower it by {100 * min_gain:.0f} % and {noise_factor:g} noise "
            "variance: these recordings could name no more"
        )
    else:
        left = (
            "leaves less than that beside the weights refitted with it"
            if refit
            else "is smaller than that"
        )
        text = (
            f"smallest {noun} these recordings could name: one that explains "
            f"{amount_text(e, unit, '.3g')} RMS of the held-out residual "
            f"({ratio:.2g} x the noise; {100 * min_gain:.0f} % of its "
            f"{amount_text(rmse, unit, '.3g')} and {noise_factor:g} noise variance, at "
            f"p < {alpha:g}); {which} that {left} is not excluded"
        )
    return {"rms": e, "ratio": ratio, "statement": text}


def _report(
    model: PreisachModel,
    ctx: Context,
    sel: Selection,
    base: _Baseline,
    final: _Final,
    do_refit: bool,
    noise_ratio: float,
    seconds: float,
    grid: dict[str, Any] | None = None,
    alpha: float = 0.01,
    min_gain: float = 0.10,
    noise_factor: float = 1.0,
) -> DiagnosisReport:
    """Build the augmented model, the residual analyses, the noise test and the report.

    ``grid`` is the base choice of :func:`~preisach.diagnose.selection.choose_grid`;
    ``alpha``, ``min_gain`` and ``noise_factor`` the selection's bars (for the holds' wander
    and the smallest effect that could be named, :func:`_nameable`).
    """
    recs, diag, steps, kept = ctx.recs, ctx.diag, sel.steps, sel.kept
    names, chain = final.names, final.chain
    base_model = model
    if do_refit:
        base_model = PreisachModel(
            ctx.table(chain.base),
            name=(model.name or "model") + " (refitted)",
            metadata={"source": "diagnosis refit", "levels": int(ctx.levels.size)},
            out_of_range=model.out_of_range,
        )
    ordered = sorted(
        chain.effects, key=lambda e: ({"input": 0, "feedback": 1}.get(e.cand.side, 2), e.cand.order)
    )
    blocks: list[EffectBlock] = [e.cand.block(e.x, ctx.dt_min) for e in ordered]
    if final.drift_eff is not None:
        blocks.append(final.drift_eff.cand.block(final.drift_eff.x, ctx.dt_min))
    aug = AugmentedModel(
        base_model,
        blocks,
        name=(model.name + "+" + "+".join(names)) if names else model.name,
        metadata={
            "diagnosis": {"verdict": names[0] if names else "none", "effects": names, "forms": kept}
        },
    )
    last = steps[-1] if steps else None
    final_score = (
        last.scores[last.chosen] if last and last.chosen else (last.baseline if last else sel.given)
    )
    rmse_before = sel.given.rmse
    rmse_after = (
        final_score.rmse
        if kept
        else (sel.refit_baseline.rmse if sel.refit_baseline else rmse_before)
    )
    res_after = final_score.residuals if kept else base.res
    pred_after = _full_pred(ctx, chain, "sensor_drift" in names)
    sigma_hat = base.sigma
    dsub = [recs[i] for i in diag]
    before_a = analyse_residuals(
        dsub,
        [base.res[i] for i in diag],
        [base.pred[i] for i in diag],
        sigma_hat,
        u_span=ctx.u_span,
    )
    after_a = analyse_residuals(
        dsub,
        [res_after[i] for i in diag],
        [pred_after[i] for i in diag],
        sigma_hat,
        u_span=ctx.u_span,
    )
    ratio = rmse_after / sigma_hat if sigma_hat > 0 else float("inf")
    consistent = bool(ratio <= noise_ratio)
    # nothing kept: is the residual the base's resolution, and is anything beyond the fine
    # classical model (a curve of the output, a drift) even when the base is within the bound?
    check = None
    curves = None  # of the change the resolution check found beyond the fine model
    base_within = consistent
    if do_refit and not names:
        check, curves = resolution_check(ctx, sigma_hat, noise_ratio, base_within=base_within)
        consistent = bool(check["consistent"])
    # nothing kept: the holds must be still too (no classical model moves while the input
    # holds, whatever its resolution; motion there is evidence however small the RMSE)
    motion = None
    effects = final.effects
    if not names:
        motion = hold_motion(sel.steps[-1].baseline, sel.holds, sigma_hat)
        if motion is not None and motion.moves:
            consistent = False
            drift = _wander_drift(ctx, sel, motion, sigma_hat, alpha)
            if drift is not None:
                effects = [drift]
        if check is not None and curves is not None and effects is final.effects:
            if check["found"] == "output_curve":  # more than the resolution: loop heights
                effects = [_classical_curve(ctx, check, curves, sigma_hat)]
            elif check["found"] == "minor_loops":  # model-free: loops that are not congruent
                # (creep moves in the holds too, or goes on after the moves into them)
                if motion is None or not (motion.moves or motion.after_effect):
                    effects = [_loop_congruency(ctx, check, curves)]
            else:
                change = _classical_change(ctx, check, curves, motion, sigma_hat)
                if change is not None:
                    effects = [change]
        # model-free: holds within the noise's RMS whose motion follows the moves into them
        if effects is final.effects and motion is not None and motion.after_effect:
            tried = sel.steps[0].scores if sel.steps else {}
            if any(n.split("/")[0] == "creep" for n in tried):  # creep among the candidates
                consistent = False
                effects = [_after_effect(ctx, sel, motion, sigma_hat)]
    loops_beside = beside_note = None
    if names and "non_congruence" not in names:
        loops_beside, beside_note = _loops_beside(
            ctx, pred_after, names, final_score, sel.holds, sigma_hat
        )
    noise_test: dict[str, Any] = {
        "ratio": ratio,
        "threshold": float(noise_ratio),
        "classical": check,
        "holds": None if motion is None else motion.as_dict(),
        "loops_beside": loops_beside,
        "consistent": consistent,
        "nameable": _nameable(
            rmse_after, sigma_hat, min_gain, noise_factor, alpha, bool(names), do_refit, ctx
        ),
    }
    unexplained = None
    if not consistent:
        unexplained = unexplained_of(
            dsub, [res_after[i] for i in diag], after_a, ctx.u_span, ratio, noise_ratio
        )
        if motion is not None and motion.moves and effects is final.effects:
            unexplained["holds"] = motion.as_dict()
            unexplained["statement"] += f"; {motion.statement()}"
        near = nearest_rejected(steps[-1]) if steps else []
        if near:
            unexplained["nearest"] = near
            unexplained["statement"] += "; nearest, not named: " + "; ".join(
                f"{o['effect']} ({100 * o['gain']:.0f} % lower held-out RMSE, but {o['why_not']})"
                for o in near
            )
    verdict = effects[0].name if effects else ("none" if consistent else "unexplained")
    aug.metadata["diagnosis"]["verdict"] = verdict
    notes = [
        f"{a['effect']} or {a['rival']}: equal within the noise; {a['experiment']}"
        for a in final.ambiguous
    ]
    if grid is not None and grid["changed"]:
        notes.append(grid["statement"])
    loops = (check or {}).get("minor_loops") or {}
    if check is not None and not (base_within and consistent):
        notes.append(check["statement"])
    elif loops.get("hints"):  # the statement is not shown: the loops' hint is
        notes.append(repeated_loops_text(loops, ctx.output_unit))
    start_note = _unknown_start_note(ctx, steps, names)
    if start_note:
        notes.append(start_note)
    if beside_note:
        notes.append(beside_note)
    if verdict == "none" and check is not None and not loops.get("pairs"):
        notes.append(
            "no recording repeats a minor loop, so congruency was tested only against the fine "
            "classical model, which a refit of the weights can bring close to a non-congruent "
            "device on these experiments; to test it directly, record the same minor loop at "
            "two output levels (a CML experiment: up to high, down to low, up to high, then "
            "past high to a peak and back through the same loop)"
        )
    if verdict in ("none", "unexplained"):
        notes.append(noise_test["nameable"]["statement"])
    if sel.refit_baseline is not None:
        notes.append(
            f"base refitted with every candidate; refitted base alone: held-out RMSE "
            f"{amount_text(sel.refit_baseline.rmse, ctx.output_unit, '.4g')}"
        )
    return DiagnosisReport(
        verdict=verdict,
        effects=effects,
        rmse_before=rmse_before,
        rmse_after=rmse_after,
        noise_sigma=sigma_hat,
        model=aug,
        before=before_a,
        after=after_a,
        candidates=candidate_table(steps),
        seconds=seconds,
        notes=notes,
        noise_test=noise_test,
        unexplained=unexplained,
        base_grid=grid,
        unit=ctx.output_unit,
        _recs=dsub,
        _pred_before=[base.pred[i] for i in diag],
        _pred_after=[pred_after[i] for i in diag],
        _res_after=[res_after[i] for i in diag],
    )
