"""The diagnosis report: verdict, effects with evidence, parameters and the augmented model."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Union, cast

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from .._io import write_text
from .augmented import AugmentedModel
from .locate import ResidualAnalysis, display_unit, motion_features
from .selection import IMPLAUSIBLE, NOT_SIGNIFICANT

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .data import Rec
    from .selection import StepResult

__all__ = ["DiagnosisReport", "EffectReport", "output_unit"]

Array = NDArray[np.float64]
PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class EffectReport:
    """One kept effect.

    Attributes
    ----------
    name : str
        Effect name (``"delay"``, ``"creep"``, ...).
    statement : str
        One line of physics a user can act on.
    evidence : str
        The numbers that justify keeping it.
    where : dict
        Where its correction acts: recordings, input range and direction, near reversals,
        frequency band (shares of the correction's power).
    parameters : dict
        ``{name: {"value", "std", "unit"}}``; ``std`` is the standard uncertainty.
    heldout_rmse_before, heldout_rmse_after : float
        Held-out RMSE (V) of the chain without and with this effect.  For a sensor drift
        named from its wander within the holds (no curve is subtracted): the held-out RMS of
        the hold stretches predicted as a still output and from their neighbours; for one
        named from the fine classical model of the resolution check: that model's held-out
        RMSE on interleaved stretches without and with the drift.
    holds : dict or None
        For an effect that acts in time (creep, sensor drift) on recordings that hold the
        input: its held-out evidence within the holds, each hold's mean removed
        (:class:`~preisach.diagnose.holds.HoldEvidence`; ``qualified`` when the holds alone
        made it qualify).

    """

    name: str
    statement: str
    evidence: str
    where: dict[str, Any]
    parameters: dict[str, dict[str, Any]]
    heldout_rmse_before: float
    heldout_rmse_after: float
    holds: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """Return the issue's schema for one effect (the statement leads the evidence)."""
        out = {
            "name": self.name,
            "evidence": f"{self.statement}. {self.evidence}",
            "where": self.where,
            "parameters": self.parameters,
            "heldout_rmse_before": self.heldout_rmse_before,
            "heldout_rmse_after": self.heldout_rmse_after,
        }
        if self.holds is not None:
            out["holds"] = self.holds
        return out


@dataclass
class DiagnosisReport:
    """Result of :func:`preisach.diagnose.diagnose`.

    Attributes
    ----------
    verdict : str
        Name of the most important effect; ``"none"`` when nothing was kept and the held-out
        residual is consistent with the noise (its RMS at most ``noise_ratio`` times the
        noise, or - with a refitted base - a classical Preisach model on a fine grid predicts
        interleaved held-out stretches within that bound: the residual is the base's
        resolution, see :attr:`noise_test`); ``"unexplained"`` when nothing was kept although
        the residual is clearly above the noise (:attr:`unexplained` says where it lives).
    effects : list of EffectReport
        Kept effects, most important first (the order of the forward selection).
    rmse_before : float
        RMSE (V) of the given model on the usable samples.
    rmse_after : float
        Held-out RMSE (V) of the augmented model on the same samples (every sample is
        predicted by the fit on the other fold).
    noise_sigma : float
        Measurement noise standard deviation (V) estimated from the data.
    model : AugmentedModel
        The base model with the kept blocks, fitted on all usable samples.
    before, after : ResidualAnalysis
        Residual analysis of the given model and of the augmented model (held-out).
    candidates : list of dict
        Every candidate in every selection step (:func:`candidate_table`): ``step``, ``name``
        (the form's key), ``heldout_rmse`` and the step's ``baseline_rmse`` (V), ``gain``
        (relative), ``explained_noise_variances``, ``p_value``, ``n_params``, ``kept`` and
        ``decision`` (why it was or was not kept).
    noise_test : dict
        ``ratio`` (held-out RMSE after the kept effects over the noise), ``threshold``,
        ``classical`` (None, or when nothing was kept above the bound with a refitted base:
        the resolution check of :func:`~preisach.diagnose.selection.resolution_check` -
        ``ratio``, ``heldout_rmse``, ``levels``, ``smoothing``, ``stretch_s``, ``seconds``,
        ``consistent``, ``statement``, ``output_curve`` and ``drift``: what a static output
        curve and a drift in time add to the fine model, in noise variances, with ``p``),
        ``loops_beside`` (None, or when effects other than ``non_congruence`` were kept: the
        repeated minor loops compared against their prediction, as ``minor_loops`` with
        ``moves``, whether the holds moved; a note, naming no effect, says so when its height
        test passes and the holds do not move), ``consistent`` (``ratio <=
        threshold``, or the classical check's verdict) and ``nameable``: ``rms`` (V) and
        ``ratio`` of the smallest part of the held-out residual an effect (a further one when
        effects were kept) must explain to pass the selection's gain and noise bars, with a
        ``statement`` (a note on ``none`` and ``unexplained``: smaller effects are not
        excluded).
    unexplained : dict or None
        When the final held-out residual is above ``threshold`` times the noise: ``ratio``,
        ``statement`` (the localisation in words), ``where`` (recordings, input range,
        direction, band) and ``follows`` (significant covariates); else None.
    base_grid : dict or None
        When the refitted base was tried on a finer grid (its held-out error at the model's
        grid was above the noise bound): ``model_levels``, ``levels`` (the grid used),
        ``heldout_rmse`` per grid tried (V), ``ratio`` (held-out RMSE over the noise, per
        grid), ``p_value`` (sign-flip test of the finer grid over held-out blocks) and
        ``statement``; else None.
    unit : str
        The recordings' output unit (their ``output_units`` metadata, ``"V"`` by default): the
        unit of every output amount above.  The text, the HTML and the figure show volts in
        mV and any other unit as it is.

    """

    verdict: str
    effects: list[EffectReport]
    rmse_before: float
    rmse_after: float
    noise_sigma: float
    model: AugmentedModel
    before: ResidualAnalysis
    after: ResidualAnalysis
    candidates: list[dict[str, Any]]
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)
    noise_test: dict[str, Any] = field(default_factory=dict)
    unexplained: dict[str, Any] | None = None
    base_grid: dict[str, Any] | None = None
    unit: str = "V"
    _recs: list[Any] = field(default_factory=list, repr=False)
    _pred_before: list[Array] = field(default_factory=list, repr=False)
    _pred_after: list[Array] = field(default_factory=list, repr=False)
    _res_after: list[Array] = field(default_factory=list, repr=False)

    # ------------------------------------------------------------------ output
    def display_unit(self) -> tuple[float, str]:
        """Return the factor and name the output amounts are shown in (mV for volts)."""
        return display_unit(self.unit)

    def to_dict(self) -> dict[str, Any]:
        """Return the report in the issue's JSON schema (the output's unit, volts by default)."""
        return {
            "verdict": self.verdict,
            "effects": [e.to_dict() for e in self.effects],
            "rmse_before": self.rmse_before,
            "rmse_after": self.rmse_after,
            "noise_sigma": self.noise_sigma,
            "noise_test": self.noise_test,
            "unexplained": self.unexplained,
            "base_grid": self.base_grid,
            "candidates": self.candidates,
        }

    def to_json(self, path: PathLike | None = None, *, indent: int = 2) -> str:
        """JSON text of :meth:`to_dict`; also written to ``path`` when given."""
        text = json.dumps(_jsonable(self.to_dict()), indent=indent)
        if path is not None:
            write_text(path, text + "\n", what="JSON report")
        return text

    def details(self) -> dict[str, Any]:
        """Everything: the schema plus noise, residual analyses and the candidate table."""
        d = self.to_dict()
        d.update(
            {
                "noise_sigma": self.noise_sigma,
                "statements": [e.statement for e in self.effects],
                "before": self.before.to_dict(),
                "after": self.after.to_dict(),
                "model": self.model.describe(),
                "seconds": self.seconds,
                "notes": self.notes,
                "unit": self.unit,
            }
        )
        return cast("dict[str, Any]", _jsonable(d))

    def summary(self) -> str:
        """Readable text: verdict, statements, evidence, candidate table, residual analysis."""
        k, unit = self.display_unit()
        lines = [
            f"verdict: {self.verdict}",
            f"RMSE {k * self.rmse_before:.4g} {unit} (given model) -> "
            f"{k * self.rmse_after:.4g} {unit} (augmented, held-out); "
            f"noise {k * self.noise_sigma:.3g} {unit}",
        ]
        if self.noise_test:
            nt = self.noise_test
            lines.append(
                f"held-out RMSE / noise = {nt['ratio']:.3g} "
                f"({'within' if nt['ratio'] <= nt['threshold'] else 'above'} the "
                f"{nt['threshold']:g} x bound)"
            )
        if self.unexplained is not None:
            lines.append(f"unexplained: {self.unexplained['statement']}")
        lines += [f"note: {n}" for n in self.notes]
        for j, e in enumerate(self.effects, 1):
            lines.append(f"{j}. {e.name}: {e.statement}")
            lines.append(f"   {e.evidence}")
        lines.append("candidates (held-out RMSE per selection step):")
        for c in self.candidates:
            lines.append(
                f"  step {c['step']}: {c['name']:<21} {k * c['heldout_rmse']:8.4g} {unit}  "
                f"gain {100 * c['gain']:6.1f} %  p {c['p_value']:.3g}  k {c['n_params']:>3}  "
                f"{'KEPT' if c['kept'] else c['decision']}"
            )
        lines.append("where the given model's residual lives:")
        lines += ["  " + s for s in self.before.summary(self.unit)]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """HTML for Jupyter: verdict, effects with uncertainties, held-out RMSE, the figure."""
        from .._display import diagnosis_html

        return diagnosis_html(self)

    def __str__(self) -> str:
        return self.summary()

    # ------------------------------------------------------------------ figure
    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Residual maps, spectra and the held-out fit before/after; returns the Figure."""
        from ..plotting.diagnose import plot_diagnosis

        return plot_diagnosis(self, fig=fig)


def output_unit(recordings: Sequence[Any]) -> str:
    """Return the recordings' common output unit (``output_units`` metadata, else ``"V"``).

    Raises
    ------
    ValueError
        When the recordings name different output units: one diagnosis compares their
        outputs with one model's.
    """
    units = sorted({str(r.metadata.get("output_units", "V")) for r in recordings})
    if len(units) > 1:
        raise ValueError(f"recordings: the outputs are in different units ({', '.join(units)})")
    return units[0] if units else "V"


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [_jsonable(v) for v in x.tolist()]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def where_of(recs: list[Rec], correction: list[Array], u_span: float) -> dict[str, Any]:
    """Where a correction signal acts (shares of its power)."""
    tol = 5e-4 * u_span
    tot = (
        sum(float(np.sum(np.where(r.usable, c, 0.0) ** 2)) for r, c in zip(recs, correction)) or 1.0
    )
    per_rec: dict[str, float] = {}
    dirs = {"rising": 0.0, "falling": 0.0, "holding": 0.0}
    near_rev_power = near_rev_time = 0.0
    n_use = 0
    us, ps = [], []
    spec_acc: Array | None = None
    f_axis: Array | None = None
    for r, c in zip(recs, correction):
        c = np.where(r.usable, c, 0.0)
        p = c * c
        per_rec[r.name] = per_rec.get(r.name, 0.0) + float(p.sum()) / tot
        f = motion_features(r.u, r.dt, tol)
        dirs["rising"] += float(p[f["direction"] > 0].sum()) / tot
        dirs["falling"] += float(p[f["direction"] < 0].sum()) / tot
        dirs["holding"] += float(p[f["direction"] == 0].sum()) / tot
        near = np.nan_to_num(f["since_reversal"], nan=np.inf) < 0.05
        near_rev_power += float(p[near & r.usable].sum()) / tot
        near_rev_time += float(np.count_nonzero(near & r.usable))
        n_use += int(r.usable.sum())
        us.append(r.u[r.usable])
        ps.append(p[r.usable])
        if c.size >= 64:
            nper = int(
                min(c.size, 2 ** int(math.floor(math.log2(max(64, min(c.size, 2.0 / r.dt))))))
            )
            ff, pc = signal.welch(c, fs=1 / r.dt, nperseg=nper)
            if f_axis is None:
                f_axis, spec_acc = ff, pc * c.size
            else:
                spec_acc = spec_acc + np.interp(f_axis, ff, pc) * c.size
    u = np.concatenate(us) if us else np.zeros(0)
    p = np.concatenate(ps) if ps else np.zeros(0)
    where: dict[str, Any] = {
        "recordings": {k: round(v, 4) for k, v in sorted(per_rec.items(), key=lambda kv: -kv[1])}
    }
    if u.size:
        order = np.argsort(u)
        cp = np.cumsum(p[order])
        if cp[-1] > 0:
            cp = cp / cp[-1]
            lo = float(u[order][int(np.searchsorted(cp, 0.1))])
            hi = float(u[order][min(int(np.searchsorted(cp, 0.9)), u.size - 1)])
            where["input_range_V"] = [lo, hi]
    where["direction"] = {k: round(v, 4) for k, v in dirs.items()}
    where["near_reversals"] = {
        "power_share": round(near_rev_power, 4),
        "time_share": round(near_rev_time / max(n_use, 1), 4),
        "window_s": 0.05,
    }
    if f_axis is not None and spec_acc is not None and spec_acc.sum() > 0:
        cum = np.cumsum(spec_acc) / spec_acc.sum()
        where["band_Hz"] = [
            float(f_axis[int(np.searchsorted(cum, 0.1))]),
            float(f_axis[min(int(np.searchsorted(cum, 0.9)), f_axis.size - 1)]),
        ]
        where["peak_Hz"] = float(f_axis[int(np.argmax(spec_acc))])
    return where


def _when(recs: list[Rec], res: list[Array]) -> dict[str, Any] | None:
    """When a residual's power sits in a short stretch of one recording (None otherwise).

    The recording holding most of the power; the stretch from its 10th to its 90th
    percentile of cumulative power, reported when it is shorter than a fifth of the
    recording; ``at_start`` when that stretch begins in the recording's first 5 %.
    """
    power = [float(np.sum(x * x)) for x in res]
    if not power or max(power) <= 0:
        return None
    k = int(np.argmax(power))
    r, x = recs[k], res[k]
    cum = np.cumsum(x * x)
    cum = cum / cum[-1]
    i0 = int(np.searchsorted(cum, 0.1))
    i1 = min(int(np.searchsorted(cum, 0.9)), r.n - 1)
    t = r.t - r.t[0]
    dur = float(t[-1]) if r.n > 1 else 0.0
    if dur <= 0 or t[i1] - t[i0] > 0.2 * dur:
        return None
    return {
        "recording": r.name,
        "from": float(t[i0]),
        "to": float(t[i1]),
        "share_of_duration": float((t[i1] - t[i0]) / dur),
        "at_start": bool(t[i0] <= 0.05 * dur),
    }


def unexplained_of(
    recs: list[Rec],
    residual: list[Array],
    analysis: ResidualAnalysis,
    u_span: float,
    ratio: float,
    threshold: float,
) -> dict[str, Any]:
    """Localise a residual that no candidate explains, in numbers and in words."""
    res = [np.nan_to_num(np.where(r.usable, x, np.nan)) for r, x in zip(recs, residual)]
    where = where_of(recs, res, u_span)
    follows = [
        {"covariate": c.name, "eta2": c.eta2, "p_value": c.p_value}
        for c in analysis.strongest(3, alpha=0.01)
    ]
    words = [f"the held-out residual is {ratio:.3g} x the noise (bound {threshold:g} x)"]
    recs_share = where.get("recordings", {})
    if recs_share:
        top = list(recs_share.items())[:2]
        words.append(
            "mostly in " + " and ".join(f"{k!r} ({100 * v:.0f} % of its power)" for k, v in top)
        )
    if "input_range_V" in where:
        lo, hi = where["input_range_V"]
        words.append(f"80 % of it at inputs {lo:.3g}-{hi:.3g} V")
    d = where.get("direction", {})
    if d:
        k = max(d, key=lambda q: d[q])
        words.append(f"{100 * d[k]:.0f} % while {k}")
    if "band_Hz" in where:
        a, b = where["band_Hz"]
        words.append(f"80 % of its power in {a:.3g}-{b:.3g} Hz (peak {where['peak_Hz']:.3g} Hz)")
    nr = where.get("near_reversals", {})
    if nr and nr.get("time_share", 0) > 0 and nr["power_share"] > 2 * nr["time_share"]:
        words.append(
            f"{100 * nr['power_share']:.0f} % of it within 50 ms after reversals "
            f"({100 * nr['time_share']:.0f} % of the time)"
        )
    when = _when(recs, res)
    if when is not None:
        where["time_s"] = when
        span = f"t = {when['from']:.3g}-{when['to']:.3g} s of {when['recording']!r}"
        if when["at_start"]:
            span += " (at its start: a start-up transient, e.g. a ring after the first step)"
        words.append(f"80 % of its power within {span}")
    if follows:
        words.append(
            "follows "
            + ", ".join(
                f"{f['covariate']} (eta^2 {f['eta2']:.2f}, p {f['p_value']:.2g})" for f in follows
            )
        )
    else:
        words.append("follows none of the tested covariates significantly")
    return {
        "ratio": ratio,
        "statement": "; ".join(words),
        "where": where,
        "follows": follows,
    }


def nearest_rejected(step: StepResult, n: int = 2) -> list[dict[str, Any]]:
    """Return the ``n`` best fits of a selection step that came near to being named.

    A candidate whose fit lowered the held-out error by the gain and significance a kept
    effect needs, but contradicts its name (a mode that does not ring, an after-effect over
    within a second), or one that met the gain bars with a gain not significant over the
    held-out blocks (it sits in a few of them: blind seed 42's two-mode case 000, a mode
    27 % lower at p 0.07), is the nearest explanation of a residual nothing explains: the
    user is told what predicted it and why it was not named.  One per effect name, best gain
    first.
    """
    out: list[dict[str, Any]] = []
    for key in sorted(step.reasons, key=lambda k: -step.gains[k]):
        name = key.split("/")[0]
        why = step.reasons[key]
        # the reasons list the gain bars first: one that starts with the significance met them
        near = why.startswith(IMPLAUSIBLE) or (why.startswith(NOT_SIGNIFICANT) and "; " not in why)
        if near and step.gains[key] > 0 and all(o["effect"] != name for o in out):
            why = why.removeprefix(IMPLAUSIBLE)
            out.append({"effect": name, "form": key, "gain": step.gains[key], "why_not": why})
    return out[:n]


def candidate_table(steps: list[StepResult]) -> list[dict[str, Any]]:
    """One row per candidate and selection step."""
    rows = []
    for k, st in enumerate(steps, 1):
        for name, sc in sorted(st.scores.items(), key=lambda kv: kv[1].mse):
            rows.append(
                {
                    "step": k,
                    "name": name,
                    "heldout_rmse": sc.rmse,
                    "baseline_rmse": st.baseline.rmse,
                    "gain": st.gains[name],
                    "explained_noise_variances": st.explained[name],
                    "p_value": st.p_values[name],
                    "n_params": st.n_params[name],
                    "kept": st.chosen == name,
                    "decision": st.reasons[name],
                }
            )
    return rows
