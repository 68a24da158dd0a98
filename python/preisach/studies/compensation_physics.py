"""Compensation with physics: the diagnosed (augmented) inverse against the classical one.

The virtual SS15 rig (:func:`preisach.daq.virtual_ss15`) is run with physics blocks after the
hysteresis (by default a 120 Hz bending mode, logarithmic creep and a 2-sample measurement
delay; the thesis's 37.62 Hz mode at full participation rings the rig's +/-5 V sensor out
of range at the identification sweep's reversals, which aborts the trial).  Everything
about the rig is then learned from the rig, as in the laboratory:

1. a classical model is identified from an FOD sweep recorded on the rig
   (:func:`preisach.compensate.rig.identify_from_device`; the sweep carries the physics too);
2. diagnosis experiments (wiping-out, CML, minor loops, multi-sine, step-and-hold, filtered
   noise: :func:`preisach.studies.diagnosis_cases.case_inputs`) are recorded on the rig, each
   from negative saturation, and :func:`preisach.diagnose` names the missing physics and fits
   it: the augmented model ``Preisach -> blocks``;
3. each reference of :func:`preisach.compensate.tracking.tracking_references` is tracked on
   the rig through the feedforward of the classical model (its exact inverse) and of the
   augmented one (:func:`preisach.compensate.augmented.invert_augmented`: a delay by preview
   of the reference, a mode by a stable inverse filter with its band limit stated, creep by
   its exact recursion, then the hysteresis), and through a linear gain for scale.

The result states, per reference, the max and RMS tracking error in % of the stroke of each,
and how many times smaller the augmented one's maximum error is.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..model import State
from ..recording import Recording

__all__ = ["DEFAULT_BLOCKS", "PhysicsCompensation", "physics_compensation"]

#: Output blocks of the rig: a bending mode, creep and a measurement delay.
DEFAULT_BLOCKS: tuple[dict[str, Any], ...] = (
    {"kind": "structural_mode", "frequency": 120.0, "damping": 0.05},
    {"kind": "creep", "rate": 0.01, "tau_min": 0.1, "tau_max": 100.0},
    {"kind": "delay", "samples": 2},
)


@dataclass
class PhysicsCompensation:
    """Result of :func:`physics_compensation`.

    Attributes
    ----------
    table : list of dict
        One row per reference: ``reference``, ``uncompensated``, ``classical`` and
        ``augmented`` as ``(max, rms)`` tracking error in % of the stroke, and ``ratio``
        (classical max / augmented max).
    effects : list of str
        The effects diagnosis kept (names of :data:`preisach.diagnose.CANDIDATES`).
    blocks : list of str
        The augmented model's blocks, described.
    bandwidth_hz : float or None
        Band limit of the augmented inverse's mode filter (None: exact up to Nyquist).
    stroke : float
        Output range (V) of the classical model, the unit of the errors.
    rig_blocks : list of dict
        The rig's true output blocks.
    tracking : dict
        The two :class:`~preisach.compensate.tracking.TrackingResult` (``classical`` and
        ``augmented``) with the samples, for plots.

    """

    table: list[dict[str, Any]]
    effects: list[str]
    blocks: list[str]
    bandwidth_hz: float | None
    stroke: float
    rig_blocks: list[dict[str, Any]]
    tracking: dict[str, Any]

    def markdown(self) -> str:
        """Return the table in Markdown (errors in % of the stroke, max / RMS)."""
        lines = [
            "| reference | uncompensated max / rms % | classical inverse max / rms % "
            "| augmented inverse max / rms % | classical / augmented (max) |",
            "|---|---|---|---|---|",
        ]
        for r in self.table:
            cells = [
                f"{r[k][0]:.2f} / {r[k][1]:.2f}"
                for k in ("uncompensated", "classical", "augmented")
            ]
            lines.append(f"| {r['reference']} | " + " | ".join(cells) + f" | {r['ratio']:.1f} |")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly result (without the samples)."""
        return {
            "table": self.table,
            "effects": self.effects,
            "blocks": self.blocks,
            "bandwidth_hz": self.bandwidth_hz,
            "stroke": self.stroke,
            "rig_blocks": self.rig_blocks,
        }


def _record(rig: Any, u: NDArray[np.float64], folder: str, name: str, dt: float) -> Recording:
    """Play ``u`` on the rig; ``y[k]`` is the reading after ``u[k]``."""
    from ..daq import WaveformController, run_trial

    path = os.path.join(folder, f"{name}.csv")
    res = run_trial(
        rig,
        WaveformController(np.append(u, u[-1])),
        path,
        sample_time=dt,
        n_samples=u.size + 1,
        metadata={"experiment": name},
        overwrite=True,
        fsync=False,
    )
    if not res.complete:
        raise RuntimeError(f"{path}: the run ended early: {res.end_status}")
    rec = Recording.load(path)
    return Recording.from_arrays(t=rec.t[:-1], u=rec.u[:-1], y=rec.y[1:], experiment=name)


def physics_compensation(
    *,
    blocks: Sequence[Mapping[str, Any]] = DEFAULT_BLOCKS,
    frequencies: Sequence[float] = (1.0, 2.0, 5.0, 10.0),
    scale: float = 0.35,
    levels: int = 21,
    candidates: Sequence[str] | None = None,
    seed: int = 0,
    sample_time: float = 1e-3,
    progress: Callable[[str], None] | None = None,
) -> PhysicsCompensation:
    """Run the comparison (see the module docstring) on a fresh virtual rig.

    Parameters
    ----------
    blocks : sequence of mapping
        The rig's output blocks (``{"kind": ..., **params}``, :mod:`preisach.daq.blocks`).
    frequencies : sequence of float
        Sine reference frequencies (Hz); a triangle, random reversals and the FOD pattern
        are tracked too.
    scale : float
        Length of the diagnosis experiments (1: 3-12 s each; 0.35: a quick run).
    levels : int
        FOD levels of the identification sweep.
    candidates : sequence of str, optional
        Candidates diagnosis tests (default all).
    seed : int
        Seed of the rig's ADC noise and of the experiments.
    sample_time : float
        Sample time (s) of the rig and of every run.
    progress : callable, optional
        Called with a short message before each stage.

    Returns
    -------
    PhysicsCompensation

    """
    from ..compensate.augmented import invert_augmented
    from ..compensate.rig import identify_from_device
    from ..compensate.tracking import device_loop, run_tracking, tracking_references
    from ..daq import virtual_ss15
    from ..diagnose import diagnose
    from .diagnosis_cases import case_inputs

    say = progress or (lambda _msg: None)
    dt = float(sample_time)

    def new_rig(k: int) -> Any:  # a fresh rig (at rest at 0 V, anhysteretic) per recording
        return virtual_ss15(
            "ss15-1hz", "anhysteretic", sample_time=dt, output_blocks=list(blocks), seed=seed + k
        )

    with tempfile.TemporaryDirectory(prefix="preisach-physics-") as folder:
        say("identification sweep")
        sweep_path = os.path.join(folder, "sweep.csv")
        classical, _ = identify_from_device(
            new_rig(0), sample_time=dt, levels=levels, record=sweep_path
        )
        sweep = Recording.load(sweep_path)
        ident = Recording.from_arrays(
            t=sweep.t[:-1], u=sweep.u[:-1], y=sweep.y[1:], experiment="fod_sweep"
        )
        rng = np.random.default_rng(seed)
        _, exps = case_inputs(scale, rng=rng, u_min=classical.u_min, u_max=classical.u_max, dt=dt)
        recs = []
        for i, (name, u) in enumerate(exps):
            say(f"record {name}")
            # from the rig's rest at 0 V down to u_min and a hold there (negative saturation)
            lead = np.linspace(0.0, classical.u_min, max(int(round(0.5 / dt)), 2))
            hold = np.full(int(round(0.3 / dt)), classical.u_min)
            rec = _record(new_rig(1 + i), np.concatenate([lead, hold, u]), folder, name, dt)
            k0 = lead.size  # from the hold on
            recs.append(
                Recording.from_arrays(
                    t=rec.t[k0:] - rec.t[k0], u=rec.u[k0:], y=rec.y[k0:], experiment=name
                )
            )
        say("diagnosis")
        report = diagnose(
            classical,
            recs,
            identification=[ident],
            candidates=list(candidates) if candidates is not None else None,
            initial_states=["negative_saturation"] * len(recs),
            progress=False,
        )
        aug = report.model
        refs = tracking_references((classical.y_min, classical.y_max), frequencies=frequencies)
        loop = device_loop(new_rig(100), dt, record_dir=os.path.join(folder, "tracking"))
        extra: dict[str, Any] = {}

        def augmented_drive(r: NDArray[np.float64], state: State) -> NDArray[np.float64]:
            res = invert_augmented(aug, r, state, sample_time=dt)
            if "bandwidth_hz" in res.extra:
                extra["bandwidth_hz"] = res.extra["bandwidth_hz"]
            return res.input

        say("tracking: classical inverse")
        res_c = run_tracking(classical, loop, refs, modes=("uncompensated", "feedforward"))
        say("tracking: augmented inverse")
        res_a = run_tracking(
            classical, loop, refs, modes=("feedforward",), feedforward=augmented_drive
        )
    table = []
    for ref in refs:
        u_, c_, a_ = (
            res_c.get(ref.name, "uncompensated"),
            res_c.get(ref.name, "feedforward"),
            res_a.get(ref.name, "feedforward"),
        )
        table.append(
            {
                "reference": ref.name,
                "uncompensated": (u_.max_error_pct, u_.rms_error_pct),
                "classical": (c_.max_error_pct, c_.rms_error_pct),
                "augmented": (a_.max_error_pct, a_.rms_error_pct),
                "ratio": c_.max_error_pct / a_.max_error_pct if a_.max_error_pct > 0 else math.inf,
            }
        )
    return PhysicsCompensation(
        table=table,
        effects=[e.name for e in report.effects],
        blocks=[b.describe() for b in [*aug.input_blocks, *aug.output_blocks]],
        bandwidth_hz=extra.get("bandwidth_hz"),
        stroke=float(classical.y_max - classical.y_min),
        rig_blocks=[dict(b) for b in blocks],
        tracking={"classical": res_c, "augmented": res_a},
    )
