"""``preisach demo``: the whole story of the thesis on the built-in virtual SS15 (no hardware).

Five stages, each printed on one line with its wall-clock time:

1. **Identification sweep** (thesis §3.3.1, Fig 3.17): the initialisation of §3.2 and the
   21-level FOD sweep at 1 Hz, played on the virtual SS15 rig of :mod:`preisach.daq` (the 1 Hz
   model of Table 3.1 between the Appendix B calibration and a noisy 14-bit ADC) and streamed
   to a recording file, exactly as on a real rig.
2. **Identification** (§3.3): Mayergoyz (Eq 2.12-2.14) on the FOD grid found in the recording,
   and the square-root surface of Eq 3.1-3.2 with its Table 3.1-style parameters next to the
   thesis's.
3. **Verification** (§3.3.4): wiping-out (Fig 3.6), congruent-minor-loop (Fig 3.13) and a
   multi-sine experiment recorded on the same rig, predicted by both models.
4. **Neutral states** (chapters 4-5): the neutral locus N(l) (Eq 2.18) of the identified model,
   the initial states psi_n, psi_a, psi_d for y_d = 1 V, dy/du at each (Appendix A), and a
   small sweep of the open-loop drift test (Fig 4.12) and the closed-loop PI test (Figs
   5.5-5.7, Table 5.1).
5. **Diagnosis** of recordings with a concealed effect: a virtual rig with a lightly damped
   structural mode after the hysteresis, a few times the noise (invisible on a loop plot);
   identify from its sweep, diagnose the other experiments, compare with the truth.

Everything goes into the output folder: recordings, models, figures, ``report.md`` (the figures
embedded, the key numbers) and ``report.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ._io import save_figure, write_json, write_text

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .daq import Device
    from .identify.fod_finder import CurveRecord
    from .model import PreisachModel
    from .recording import Recording

__all__ = ["add_parser", "run_demo"]

_STAGES = 5


class _Stages:
    """The demo's stages: a progress bar over them (stderr) and one result line per stage.

    The line ``[k/5] title ... detail (t s)`` goes to ``stream`` (stdout) when the stage ends.
    """

    def __init__(self, stream: IO[str] | None = None, *, progress: bool = True) -> None:
        from ._progress import progress_bar

        self.stream = stream if stream is not None else sys.stdout
        self.bar = progress_bar(_STAGES, "demo", enabled=progress, unit="stage", delay=0.0)
        self.k = 0
        self.detail = ""
        self.times: dict[str, float] = {}

    @contextmanager
    def stage(self, title: str) -> Iterator[_Stages]:
        self.k += 1
        self.detail = ""
        self.bar.set_description_str(f"demo [{self.k}/{_STAGES}] {title.split(':')[0][:40]}")
        t0 = time.perf_counter()
        yield self
        dt = time.perf_counter() - t0
        self.times[title] = dt
        line = f"[{self.k}/{_STAGES}] {title} ..." + (f" {self.detail}" if self.detail else "")
        self.bar.write(f"{line} ({dt:.1f} s)", file=self.stream)
        self.stream.flush()
        self.bar.update(1)
        if self.k == _STAGES:
            self.bar.close()


def _save(fig: Figure, path: Path, dpi: int = 100) -> str:
    save_figure(fig, path, dpi=dpi)
    return path.name


def _md_table(head: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def _aligned(rec: Recording) -> Recording:
    """Pair ``u[k]`` with ``y[k + 1]``: the clocked loop reads ``y[k]`` before writing ``u[k]``."""
    from .recording import Recording

    return Recording.from_arrays(
        t=rec.t[:-1],
        u=rec.u[:-1],
        y=rec.y[1:],
        experiment=str(rec.metadata.get("experiment", "recording")),
        metadata={"aligned": "y[k+1] paired with u[k]"},
    )


def _record(rig: Device, u: np.ndarray, path: Path, name: str) -> Recording:
    """Play ``u`` (V) on the rig, stream it to ``path``, and load the recording."""
    from .daq import run_trial
    from .recording import Recording

    res = run_trial(
        rig, u, path, sample_time=1e-3, metadata={"experiment": name}, overwrite=True, fsync=False
    )
    if not res.complete:
        raise RuntimeError(f"{path}: the virtual rig ended the run early: {res.end_status}")
    return Recording.load(path)


def run_demo(args: argparse.Namespace) -> int:
    """Run ``preisach demo`` with the parsed arguments; returns the exit status.

    BLAS is limited to one thread: the demo's linear algebra is many small solves, for which
    a threaded BLAS gains nothing and, on a busy machine, its spinning threads cost several
    times the run time.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _run_demo(args)


@dataclass
class _Demo:
    """What the stages share: where they write, the stage lines, and the report they build.

    ``md`` collects the lines of ``report.md``; ``key`` the numbers of ``report.json``.
    """

    out: Path
    prog: _Stages
    bars: bool  # progress bars of the long calls inside the stages
    seeds: int
    version: str
    md: list[str] = field(default_factory=list)
    key: dict[str, Any] = field(default_factory=dict)


def _run_demo(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")

    from . import __version__
    from .model import PreisachModel

    seeds = int(args.seeds)
    if seeds < 2:
        raise ValueError(f"--seeds: need at least 2 seeds for a spread, got {seeds}")
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    (out / "recordings").mkdir(exist_ok=True)
    t_start = time.perf_counter()
    print(f"preisach demo {__version__}: the virtual SS15, from identification to diagnosis")
    print(f"output folder: {out.resolve()}")
    quiet = bool(getattr(args, "quiet", False))
    ctx = _Demo(out, _Stages(progress=not quiet), not quiet, seeds, __version__)
    truth_model = PreisachModel.builtin("ss15-1hz")
    rig, sweep = _identification_sweep(ctx, truth_model)
    m_fod, m_srf = _identification(ctx, sweep)
    _verification(ctx, rig, m_fod, m_srf)
    _neutral_states(ctx, m_srf)
    _diagnosis(ctx)
    total = _write_report(ctx, t_start)
    print(
        f"done in {total:.1f} s; wrote {out / 'report.md'} (figures, recordings and models "
        f"in {out})"
    )
    return 0


def _identification_sweep(ctx: _Demo, truth_model: PreisachModel) -> tuple[Device, Recording]:
    """Stage 1: the initialisation and the 21-level FOD sweep, recorded on the virtual rig."""
    from .daq import virtual_ss15
    from .waveforms import concatenate, decaying_sine, fod_sweep

    with ctx.prog.stage("identification sweep on the virtual SS15 rig (Fig 3.17)") as st:
        rig = virtual_ss15(truth_model, "anhysteretic", adc_noise=0.5e-3, adc_bits=14, seed=1)
        sweep_in = concatenate(decaying_sine(12.0, 1.0, 100.0), fod_sweep(21, frequency=1.0))
        sweep = _record(rig, sweep_in.u, ctx.out / "recordings" / "fod_sweep.csv", "fod_sweep")
        st.detail = f"{sweep.u.size} samples, {sweep.duration:.0f} s at 1 kHz"
    ctx.key["sweep_samples"] = int(sweep.u.size)
    return rig, sweep


def _identification(ctx: _Demo, sweep: Recording) -> tuple[PreisachModel, PreisachModel]:
    """Stage 2: Mayergoyz and the square-root surface; report sections 1 and 2."""
    from . import plotting
    from .identify import format_table, identify_fod, identify_surface
    from .surface import TABLE_3_1

    out = ctx.out
    with ctx.prog.stage("identification: Mayergoyz and the square-root surface") as st:
        aligned = _aligned(sweep)
        r_fod = identify_fod(aligned, project=True, name="Mayergoyz, 21 levels")
        r_srf = identify_surface(aligned, frequency=1.0, name="square-root surface")
        m_fod, m_srf = r_fod.model, r_srf.model
        m_fod.save(out / "model_mayergoyz.npz")
        m_srf.save(out / "model_surface.npz")
        fd = r_fod.fod
        assert fd is not None and r_srf.surface_fit is not None and r_fod.node_residuals
        fig_fod = _save(plotting.plot_fod_data(fd, m_srf), out / "fod_curves.png")
        fig_id = _save(plotting.plot_identification(r_srf), out / "identification.png", dpi=80)
        st.detail = (
            f"{len(fd.used_curves)} FOD curves; node residual max "
            f"{r_fod.node_residuals.max_pct:.2f} % of range"
        )
    sf = r_srf.surface_fit
    ctx.key["fod_curves"] = len(fd.used_curves)
    ctx.key["surface"] = {
        k: float(getattr(sf.surface, k))
        for k in ("xbar4", "xbar5", "x7", "x8", "x9", "y_max", "y_min")
    }
    ctx.md += [
        "# preisach demo: the virtual SS15 from identification to diagnosis",
        "",
        f"Made by `preisach demo` (preisach {ctx.version}). The device is the *virtual SS15*: "
        "the thesis's 1 Hz Preisach model (Table 3.1 through Eq 3.2) between the amplifier "
        "calibration of Appendix B (V_in = -14.12 V_bin - 0.02) and a 14-bit ADC with 0.5 mV "
        "rms noise, run by the same clocked trial loop that drives a real rig "
        "(`preisach.daq`). Every recording below was streamed to `recordings/`.",
        "",
        "## 1. Identification sweep (thesis §3.3.1, Fig 3.17)",
        "",
        f"A 12 s decaying sinusoid (the initialisation of §3.2), then one first-order "
        f"descending (FOD) curve per level α = -100 + 10 i V at 1 Hz: {sweep.u.size} samples "
        f"({sweep.duration:.0f} s). The FOD finder used {len(fd.used_curves)} curves and "
        f"rejected {len(fd.rejected_curves)}" + _reasons(fd.rejected_curves) + ".",
        "",
        f"![FOD curves measured on the rig, with the identified surface]({fig_fod})",
        "",
        "## 2. Identified model (§3.3.2-3.3.3)",
        "",
        "The rig's clocked loop reads y[k] before it writes u[k], so y[k] answers u[k-1]; at "
        "1 Hz the input moves up to 0.6 V per sample, so the output is paired with the input "
        "one sample earlier before identifying (otherwise the falling branches read about 20 mV "
        "high).",
        "",
        f"* **Mayergoyz** (Eq 2.12-2.14) on the 21-level grid, projected to μ ≥ 0: "
        f"{r_fod.negative_cells} negative cells left; residual at the FOD nodes max "
        f"{r_fod.node_residuals.max_error * 1e3:.1f} mV "
        f"({r_fod.node_residuals.max_pct:.2f} % of the output range), rms "
        f"{r_fod.node_residuals.rms_error * 1e3:.2f} mV.",
        f"* **Square-root surface** (Eq 3.1-3.2), fitted FOD curve by FOD curve and "
        f"refined jointly: rms {sf.rmse * 1e3:.1f} mV, max {sf.max_error * 1e3:.1f} mV over "
        f"{sf.n_points} FOD points. Its parameters beside the thesis's 1 Hz column of "
        "Table 3.1 (the rig's truth; the error row is the root-sum-square over the points):",
        "",
        "```text",
        "identified (left) and Table 3.1, 1 Hz (right)",
        format_table([sf, TABLE_3_1[1]]),
        "```",
        "",
        f"![identification: FOD surface, weight density and kappa]({fig_id})",
        "",
    ]
    return m_fod, m_srf


def _verification(ctx: _Demo, rig: Device, m_fod: PreisachModel, m_srf: PreisachModel) -> None:
    """Stage 3: wiping-out, CML and multi-sine recordings predicted by both models."""
    from .verify import verify
    from .waveforms import cml_input, wiping_out_input

    with ctx.prog.stage("verification on wiping-out, CML and multi-sine recordings") as st:
        t_ms = np.arange(0.0, 8.0, 1e-3)
        multisine = (
            60.0 * np.sin(2 * np.pi * 0.5 * t_ms)
            + 25.0 * np.sin(2 * np.pi * 1.3 * t_ms + 1.0)
            + 10.0 * np.sin(2 * np.pi * 3.1 * t_ms + 2.0)
        )
        tests = {
            "wiping_out": wiping_out_input(frequency=1.0).u,
            "cml": cml_input(frequency=1.0).u,
            "multisine": np.r_[np.linspace(-100.0, multisine[0], 500), multisine],
        }
        recs = [_record(rig, u, ctx.out / "recordings" / f"{n}.csv", n) for n, u in tests.items()]
        v_fod = verify(m_fod, recs, delay=1)
        v_srf = verify(m_srf, recs, delay=1)
        fig_ver = _save(v_srf.plot(), ctx.out / "verification.png", dpi=80)
        st.detail = f"largest error {max(v_fod.max_pct, v_srf.max_pct):.2f} % of the output range"
    ctx.key["verification_max_pct"] = {"mayergoyz": v_fod.max_pct, "surface": v_srf.max_pct}
    rows = [
        [
            a.experiment,
            f"{a.max_pct:.2f}",
            f"{a.rms_pct:.2f}",
            f"{b.max_pct:.2f}",
            f"{b.rms_pct:.2f}",
        ]
        for a, b in zip(v_fod.rows, v_srf.rows)
    ]
    ctx.md += [
        "## 3. Verification on other experiments (§3.3.4)",
        "",
        "Each recording's input is simulated through the identified models (the rig's clocked "
        "loop reads y[k] before writing u[k], so the output is compared one sample later). "
        "Errors in % of the output range; the thesis measured 2.33 % (max) for the wiping-out "
        "test at 1 Hz on the real SS15 - the virtual rig has no unmodelled physics, so the "
        "errors here are the identification's own.",
        "",
        *_md_table(
            ["experiment", "Mayergoyz max %", "Mayergoyz rms %", "surface max %", "surface rms %"],
            rows,
        ),
        "",
        f"![measured and predicted outputs]({fig_ver})",
        "",
    ]


def _neutral_states(ctx: _Demo, m_srf: PreisachModel) -> None:
    """Stage 4: N(l), the three initial states, the drift and the closed-loop sweeps."""
    from . import plotting
    from .experiments import THESIS_GAINS, regulation_sweep
    from .neutral import check_mp, neutral_locus

    with ctx.prog.stage("neutral states, open-loop drift and closed-loop PI (small sweep)") as st:
        locus = neutral_locus(m_srf)
        mp = check_mp(m_srf)
        sweep_kw: dict[str, Any] = {"gains": THESIS_GAINS, "seeds": range(ctx.seeds), "y_d": 1.0}
        drift = regulation_sweep("drift", {1.0: m_srf}, **sweep_kw, progress=ctx.bars)
        effort = regulation_sweep("closed-loop", {1.0: m_srf}, **sweep_kw, progress=ctx.bars)
        inits = list(drift.states)
        fig_nl = _save(plotting.plot_initial_states(drift), ctx.out / "neutral_locus.png")
        fig_dr = _save(plotting.plot_drift_summary(drift), ctx.out / "drift.png")
        fig_ef = _save(plotting.plot_effort_summary(effort), ctx.out / "control_effort.png")
        fig_pc = _save(
            plotting.plot_effort_increase(effort), ctx.out / "control_effort_increase.png"
        )
        comp_d, comp_c = drift.comparisons(), effort.comparisons()
        n_ok_d = sum(c["n_smallest"] for c in comp_d)
        n_ok_c = sum(c["n_smallest"] for c in comp_c)
        st.detail = (
            f"psi_n drifts least at {n_ok_d}/{len(comp_d)} gains, needs least effort at "
            f"{n_ok_c}/{len(comp_c)}"
        )
    ctx.key["drift_n_smallest"] = f"{n_ok_d}/{len(comp_d)}"
    ctx.key["effort_n_smallest"] = f"{n_ok_c}/{len(comp_c)}"
    names = {"n": "ψn", "a": "ψa", "d": "ψd"}
    state_rows = [
        [
            names[s["state"]],
            f"{s['offset']:.2f}",
            f"{s['y_end']:.4f}",
            f"{s['dy_du_rising']:.4f}",
            f"{s['dy_du_falling']:.4f}",
            f"{s['residual_up'] * 1e3:+.1f} / {s['residual_down'] * 1e3:+.1f}",
        ]
        for s in inits
    ]
    drift_rows, effort_rows = [], []
    for g in drift.gains:
        cells = []
        for k in ("n", "a", "d"):
            v = drift.values(1.0, k, g)
            cells.append(f"{v.mean() * 1e3:+.1f} ± {v.std(ddof=1) * 1e3:.1f}")
        drift_rows.append([f"{g:.1f}", *cells])
        cells = []
        for k in ("n", "a", "d"):
            v = effort.values(1.0, k, g)
            cells.append(f"{v.mean():.2f} ± {v.std(ddof=1):.2f}")
        effort_rows.append([f"{g:.1f}", *cells])
    pct = effort.percentage_table()
    pct_rows = [[f"{r['normalised_gain']:.4f}", f"{r['a_1']:.1f}", f"{r['d_1']:.1f}"] for r in pct]
    ctx.key["table_5_1_percent"] = {"a": [r["a_1"] for r in pct], "d": [r["d_1"] for r in pct]}
    ctx.md += [
        "## 4. Neutral states, drift and control effort (chapters 4-5)",
        "",
        "For one desired output there are many states. The *neutral* state ψn (Eq 2.17) is "
        "the limit of an oscillation decaying about an offset l; N(l) (Eq 2.18) is its "
        f"output. On the identified model N(l) is {'' if locus.monotone else 'not '}monotone"
        f" and μ {'is' if mp.in_mp else 'is not'} in Mp. The three initial states of the "
        "regulation tests, all with output y_d = 1 V: ψn (Eq 4.1-4.2), ψa reached on an "
        "ascending branch (Eq 4.3) and ψd on a descending one (Eq 4.4). Appendix A explains "
        "the drift: at ψn the slopes up and down are equal, so zero-mean noise leaves no net "
        "output change; at ψa and ψd they differ.",
        "",
        *_md_table(
            [
                "state",
                "offset u (V)",
                "y at t1 (V)",
                "dy/du rising (V/V)",
                "dy/du falling (V/V)",
                f"left by one ±{drift.config['slope_amplitude']:.1f} V excursion up / down (mV)",
            ],
            state_rows,
        ),
        "",
        f"![major loop, N(l) and the initial states]({fig_nl})",
        "",
        f"**Open-loop drift** (§4.2, Fig 4.12): ȳ(8,10) - ȳ(0,2) in mV, mean ± std over "
        f"{ctx.seeds} noise seeds per noise gain K_n:",
        "",
        *_md_table(["K_n", "ψn", "ψa", "ψd"], drift_rows),
        "",
        f"|drift| from ψn is the smallest at {n_ok_d} of {len(comp_d)} gains; ψa drifts up "
        f"at {sum(c['a_up'] for c in comp_d)} and ψd down at "
        f"{sum(c['d_down'] for c in comp_d)} of {len(comp_d)} gains.",
        "",
        f"![drift against noise gain]({fig_dr})",
        "",
        "**Closed-loop PI** (§5.1, K_p = 1.5, K_i = 30, Figs 5.5-5.7): control effort "
        "n_c = ‖u_cn − ū_c‖₂ (Eq 5.3, DAQ volts), mean ± std over seeds:",
        "",
        *_md_table(["K_n", "ψn", "ψa", "ψd"], effort_rows),
        "",
        f"n_c from ψn is the smallest at {n_ok_c} of {len(comp_c)} gains. Extra effort "
        "relative to ψn in % (Table 5.1 layout, 1 Hz):",
        "",
        *_md_table(["K_n / max K_n", "ψa (%)", "ψd (%)"], pct_rows),
        "",
        f"![control effort against noise gain]({fig_ef})",
        f"![extra effort from psi_a and psi_d]({fig_pc})",
        "",
    ]


def _diagnosis(ctx: _Demo) -> None:
    """Stage 5: diagnose recordings of a rig with a concealed structural mode."""
    from . import plotting
    from .diagnose import diagnose
    from .studies.diagnosis_cases import make_case

    with ctx.prog.stage("diagnosis of recordings with a concealed structural mode") as st:
        case = make_case(
            "structural_resonance", seed=31, scale=0.3, effect_size=3.5, generator="rig"
        )
        base = case.identify()
        rep = diagnose(base, case.recordings, identification=case.identification, progress=ctx.bars)
        rep.to_json(ctx.out / "diagnosis.json")
        fig_dg = _save(plotting.plot_diagnosis(rep), ctx.out / "diagnosis.png", dpi=75)
        fig_rm = _save(
            plotting.plot_residual_map(base, case.recordings),
            ctx.out / "residual_map.png",
        )
        st.detail = f"verdict: {rep.verdict}"
    blocks = case.truth.get("params", {}).get("output_blocks", [])
    truth_text = ", ".join(
        f"{b['kind']} " + ", ".join(f"{k} = {v:.4g}" for k, v in b.items() if k != "kind")
        for b in blocks
    ) or json.dumps(case.truth.get("params", {}))
    ctx.key["diagnosis"] = {
        "truth": case.kind,
        "verdict": rep.verdict,
        "rmse_before_mV": rep.rmse_before * 1e3,
        "rmse_after_mV": rep.rmse_after * 1e3,
    }
    effect_lines = [f"* **{e.name}**: {e.statement}. {e.evidence}" for e in rep.effects] or [
        "* no effect improved the held-out error clearly beyond the noise"
    ]
    ctx.md += [
        "## 5. Diagnosis of a concealed effect",
        "",
        "A second virtual rig carries one effect the classical Preisach model leaves out: "
        f"{truth_text} after the hysteresis (the truth, hidden from the diagnosis). Its size "
        f"is {case.truth.get('effect_size', float('nan')):.1f} × the 1 mV noise once the best "
        "Preisach fit has absorbed what it can: invisible on a loop plot. A model is "
        "identified from that rig's FOD sweep (which carries the effect too), and "
        f"{len(case.recordings)} other experiments ("
        + ", ".join(str(r.metadata.get("experiment")) for r in case.recordings)
        + ") are diagnosed: candidate physics blocks are fitted on part of the data and "
        "kept only when they lower the held-out error clearly.",
        "",
        f"**Verdict: `{rep.verdict}`** (truth: `{case.kind}`). RMSE "
        f"{rep.rmse_before * 1e3:.2f} mV with the identified model → "
        f"{rep.rmse_after * 1e3:.2f} mV held out with the augmented model; noise "
        f"{rep.noise_sigma * 1e3:.2f} mV.",
        "",
        *effect_lines,
        "",
        f"![residual of the identified model over input level and rate]({fig_rm})",
        f"![diagnosis: residual maps, spectra, held-out fit]({fig_dg})",
        "",
    ]


def _write_report(ctx: _Demo, t_start: float) -> float:
    """Add the closing section, write ``report.md`` and ``report.json``; return the run time (s)."""
    total = time.perf_counter() - t_start
    ctx.key["seconds"] = {
        **{k: round(v, 2) for k, v in ctx.prog.times.items()},
        "total": round(total, 2),
    }
    ctx.md += [
        "## Files and the full studies",
        "",
        "`recordings/*.csv` (the rig's recordings, `preisach.Recording.load`), "
        "`model_mayergoyz.npz`, `model_surface.npz` (`preisach.PreisachModel.load`), "
        "`diagnosis.json` (the diagnosis report), `report.json` (the numbers above).",
        "",
        "The full studies behind stages 2-5 (all frequencies, 20 seeds, the randomised "
        "diagnosis proof) are `python scripts/identify_study.py`, "
        "`python scripts/regulation_study.py` and `python scripts/diagnosis_study.py` in the "
        "source tree, or `preisach experiment drift|closed-loop --model ss15 --json OUT`.",
        "",
        f"Run time: {total:.1f} s ("
        + ", ".join(f"stage {i + 1} {t:.1f} s" for i, t in enumerate(ctx.prog.times.values()))
        + ").",
        "",
    ]
    write_text(ctx.out / "report.md", "\n".join(ctx.md), what="report")
    write_json(ctx.out / "report.json", _finite(ctx.key), indent=2, what="report")
    return total


def _reasons(curves: list[CurveRecord]) -> str:
    """`` (3 because ...; 1 because ...)`` from the finder's reasons, grouped by their cause."""
    counts: dict[str, int] = {}
    for c in curves:
        cause = str(getattr(c, "reason", "")).split(":")[0].strip() or "no reason given"
        counts[cause] = counts.get(cause, 0) + 1
    if not counts:
        return ""
    return " (" + "; ".join(f"{n}: {cause}" for cause, n in counts.items()) + ")"


def _finite(o: Any) -> Any:
    """JSON-safe copy: NaN and inf become None."""
    if isinstance(o, dict):
        return {str(k): _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``preisach demo``."""
    d = subparsers.add_parser(
        "demo",
        help="run the whole story on the built-in virtual SS15 (no hardware)",
        description="On the built-in virtual SS15 rig: record an FOD identification sweep, "
        "identify (Mayergoyz and the square-root surface), verify on other recorded "
        "experiments, compare the neutral state with psi_a/psi_d in open-loop drift and "
        "closed-loop PI tests, and diagnose recordings with a concealed effect.  Writes "
        "figures, recordings, models and report.md into OUTPUT (about a minute).",
    )
    d.add_argument(
        "-o", "--output", default="preisach-demo", help="output folder (default: %(default)s)"
    )
    d.add_argument(
        "--seeds",
        type=int,
        default=10,
        help="noise seeds per state and gain in the regulation sweeps (default: %(default)s; "
        "the thesis-scale study uses 20)",
    )
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    d.set_defaults(func=run_demo)
    return d
