r"""Tracking experiment: how well the actuator follows a reference output, four ways.

Each reference (a desired output ``r(t)``, V) is run four ways on the same plant:

``uncompensated``
    A linear gain: ``u = u_min + (r - y_min) (u_max - u_min) / (y_max - y_min)`` with the
    model's input and output ranges -- what a piezo stage does without a hysteresis model.
``feedforward``
    ``u`` = the exact inverse of the model (:func:`preisach.compensate.invert`) for ``r``,
    computed from the state the run starts in (negative saturation, see below).
``pi``
    The chapter 5 PI loop alone (Eq 5.2) with a moving setpoint: ``u(k) = g u_c(k)``,
    ``u_c(k) = K_p e(k-1) + K_i T_s \sum_{j<k} e(j)``, ``e(j) = r(j) - y(j)``: the input of
    sample ``k`` uses the reading of sample ``k - 1`` (one sample of computation delay, as
    in :class:`preisach.experiments.PIConfig`).  Thesis gains ``K_p = 1.5``, ``K_i = 30`` in
    DAQ volts, ``g = 14.12`` model-input volts per DAQ volt.
``pi+feedforward``
    Both: ``u(k) = u_ff(k) + g u_c(k)``.

Every run has the same frame: a ramp of the input from 0 V to ``u_min`` and a hold (the
plant is then in negative saturation, whatever came before), a lead-in that moves the
reference from the saturated output to the reference's first value (not scored), the
reference (scored), and a ramp of the input back to 0 V.  Scores: the maximum and RMS of
``r - y`` over the reference as a percentage of the **stroke** (the model's output range
``y_max - y_min``), and for the PI runs the control effort ``n_c = ||u_c - ubar_c||_2``
(Eq 5.3; controller units = DAQ volts) over the reference, ``ubar_c`` the mean of ``u_c``
over the hold before the lead-in (0: the loop starts at rest).

Plants: a :class:`~preisach.PreisachModel` (optionally with physics blocks, simulated
sample by sample) or a DAQ device (the virtual SS15 rig, a Comedi card); on a device every
run is a trial of :func:`preisach.daq.run_trial` with its safety limits, and ``y(k)`` is the
reading that follows ``u(k)``.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import weakref
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..model import PreisachModel, State
from .inverse import invert

__all__ = [
    "MODES",
    "Reference",
    "TrackingResult",
    "TrackingRun",
    "format_tracking_table",
    "model_loop",
    "device_loop",
    "run_tracking",
    "tracking_references",
]

#: The four ways every reference is run.
MODES: tuple[str, ...] = ("uncompensated", "feedforward", "pi", "pi+feedforward")

#: Thesis PI gains (DAQ volts) and the SS15 drive gain (model-input V per DAQ V, Eq B.2).
_KP, _KI, _GAIN = 1.5, 30.0, 14.12

# A run's loop: given the open-loop input (model-input V) and, for a closed loop, the
# reference and the controller, it returns (u applied, y, u_c) with y[k] the output after u[k].
Loop = Callable[..., tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]


@dataclass
class Reference:
    """A desired output ``y`` (V) sampled every ``sample_time`` (s), with its kind."""

    name: str
    kind: str
    y: NDArray[np.float64]
    sample_time: float
    frequency: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly summary (without the samples)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "frequency": None if math.isnan(self.frequency) else self.frequency,
            "samples": int(self.y.size),
            "duration": float(self.y.size * self.sample_time),
        }


@dataclass
class TrackingRun:
    """One reference run one way.  Errors in % of the stroke; effort in controller units."""

    reference: str
    mode: str
    max_error_pct: float
    rms_error_pct: float
    effort: float | None
    unreachable: int
    max_drive: float
    t: NDArray[np.float64] = field(repr=False)
    r: NDArray[np.float64] = field(repr=False)
    u: NDArray[np.float64] = field(repr=False)
    y: NDArray[np.float64] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly scores (without the samples)."""
        d = asdict(self)
        for k in ("t", "r", "u", "y"):
            d.pop(k)
        return d


@dataclass
class TrackingResult:
    """All runs of :func:`run_tracking`, with the references, the stroke and the settings."""

    runs: list[TrackingRun]
    references: list[Reference]
    stroke: float
    settings: dict[str, Any]

    def get(self, reference: str, mode: str) -> TrackingRun:
        """Return the run of ``reference`` done ``mode``."""
        for r in self.runs:
            if r.reference == reference and r.mode == mode:
                return r
        raise KeyError(f"no run of {reference!r} done {mode!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly result."""
        return {
            "stroke": self.stroke,
            "settings": self.settings,
            "references": [r.to_dict() for r in self.references],
            "runs": [r.to_dict() for r in self.runs],
        }

    def table(self) -> str:
        """Return the result as a Markdown table (see :func:`format_tracking_table`)."""
        return format_tracking_table(self)

    def _repr_html_(self) -> str:
        from .._display import _e, _g, _table

        modes = [m for m in MODES if any(r.mode == m for r in self.runs)]
        header = ["reference", *(f"{_e(m)}<br>max / RMS %" for m in modes)]
        pi_modes = [m for m in ("pi", "pi+feedforward") if m in modes]
        header += [f"n<sub>c</sub> {_e(m)}" for m in pi_modes]
        rows = []
        for ref in self.references:
            runs = [self.get(ref.name, m) for m in modes]
            row = [_e(ref.name)]
            row += [f"{_g(r.max_error_pct, '.3g')} / {_g(r.rms_error_pct, '.3g')}" for r in runs]
            row += [_g(self.get(ref.name, m).effort, ".3g") for m in pi_modes]
            rows.append(row)
        cap = f"Tracking error in % of the {self.stroke:.4g} V stroke"
        return _table(header, rows, caption=_e(cap))

    def plot(self, reference: str | None = None) -> Any:
        """Plot reference vs output, error vs time, max error vs frequency; return the figure."""
        from .plots import plot_tracking

        return plot_tracking(self, reference)


def tracking_references(
    y_range: tuple[float, float],
    *,
    sample_time: float = 1e-3,
    frequencies: Sequence[float] = (0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0),
    periods: float = 2.0,
    fill: float = 0.8,
    seed: int = 0,
) -> list[Reference]:
    """Build the reference set: sines, a triangle, random reversals and the FOD pattern.

    Parameters
    ----------
    y_range : (float, float)
        Output range (V) of the model; the references span the middle ``fill`` of it.
    sample_time : float
        Sampling period (s).
    frequencies : sequence of float
        Frequencies (Hz) of the sines; each starts at its minimum (``r = mid - A cos``).
    periods : float
        Periods per sine and triangle.
    fill : float
        Fraction of the output range covered.
    seed : int
        Seed of the random-reversal reference.

    Returns
    -------
    list of Reference
        ``sine-<f>Hz`` for each frequency, ``triangle-1Hz``, ``random-reversals`` (5 s,
        20 random turning points), ``fod-pattern`` (the thesis's Fig 3.17 identification
        input, 11 curves at 2 Hz, scaled to the output range).

    """
    lo0, hi0 = float(y_range[0]), float(y_range[1])
    if not (math.isfinite(lo0) and math.isfinite(hi0) and hi0 > lo0):
        raise ValueError(f"y_range: need finite y_min < y_max, got {y_range!r}")
    if not 0 < fill <= 1:
        raise ValueError(f"fill: must be in (0, 1], got {fill}")
    mid, amp = 0.5 * (lo0 + hi0), 0.5 * fill * (hi0 - lo0)
    lo, hi = mid - amp, mid + amp
    ts = float(sample_time)
    refs: list[Reference] = []
    for f in frequencies:
        n = max(int(round(periods / (f * ts))), 2)
        t = np.arange(n) * ts
        refs.append(
            Reference(f"sine-{f:g}Hz", "sine", mid - amp * np.cos(2 * np.pi * f * t), ts, float(f))
        )
    n = int(round(periods / ts))
    phase = (np.arange(n) * ts) % 1.0
    refs.append(
        Reference("triangle-1Hz", "triangle", lo + (hi - lo) * (1 - np.abs(2 * phase - 1)), ts, 1.0)
    )
    rng = np.random.default_rng(seed)
    pts = np.r_[lo, rng.uniform(lo, hi, 20)]
    legs = [
        np.linspace(a, b, max(int(abs(b - a) / (hi - lo) * 0.5 / ts), 2), endpoint=False)
        for a, b in zip(pts[:-1], pts[1:])
    ]
    refs.append(Reference("random-reversals", "random", np.concatenate(legs), ts))
    from ..waveforms import fod_sweep

    sweep = fod_sweep(11, frequency=2.0, sample_time=ts)
    refs.append(
        Reference("fod-pattern", "fod", lo + (hi - lo) * (sweep.u + 100.0) / 200.0, ts, 2.0)
    )
    return refs


def model_loop(plant: Any, sample_time: float = 1e-3) -> Loop:
    """Return a loop on a simulated plant, run sample by sample.

    The plant is a :class:`PreisachModel` or anything with ``reset()`` and ``step(u) -> y``
    (e.g. a :mod:`preisach.daq.blocks` chain).

    The model starts each run from its anhysteretic state (the frame saturates it anyway).
    """
    if isinstance(plant, PreisachModel):
        sim = plant.simulator()
        reset: Callable[[], None] = lambda: sim.reset(plant.anhysteretic_state())  # noqa: E731
        step: Callable[[float], float] = sim.step
        u_lo, u_hi = plant.u_min, plant.u_max
    else:
        reset, step = plant.reset, plant.step
        u_lo, u_hi = -np.inf, np.inf

    def run(
        u_open: NDArray[np.float64],
        r: NDArray[np.float64] | None = None,
        pi: tuple[float, float, float, int, int] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        reset()
        n = u_open.size
        u, y, uc = np.empty(n), np.empty(n), np.zeros(n)
        if pi is None or r is None:
            for k in range(n):
                u[k] = min(max(u_open[k], u_lo), u_hi)
                y[k] = step(u[k])
            return u, y, uc
        kp, ki, gain, on, off = pi
        integ, c = 0.0, 0.0
        for k in range(n):
            u[k] = min(max(u_open[k] + gain * c, u_lo), u_hi)
            y[k] = step(u[k])
            if on <= k < off:
                e = r[k] - y[k]
                integ += ki * sample_time * e
                c = kp * e + integ
            uc[k] = c
        return u, y, uc

    return run


def device_loop(
    device: Any,
    sample_time: float,
    *,
    record_dir: str | os.PathLike[str] | None = None,
    safety: Any = None,
    realtime: bool = False,
) -> Loop:
    """Return a loop on a DAQ device: each run is a trial (:func:`preisach.daq.run_trial`).

    Each run takes one extra sample so that ``y[k]`` is the reading after ``u[k]``; the PI
    runs use a callback controller that sees the reading of sample ``k`` (the output after
    ``u[k-1]``) and sets ``u[k]``.  Recordings go to ``record_dir`` (default a temporary
    folder).  A run that does not complete raises :class:`RuntimeError`.
    """
    from .. import daq
    from ..recording import Recording

    own = record_dir is None
    folder = (
        tempfile.mkdtemp(prefix="preisach-tracking-")
        if record_dir is None
        else os.fspath(record_dir)
    )
    os.makedirs(folder, exist_ok=True)
    count = [0]

    def run(
        u_open: NDArray[np.float64],
        r: NDArray[np.float64] | None = None,
        pi: tuple[float, float, float, int, int] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        count[0] += 1
        path = os.path.join(folder, f"tracking_{count[0]:04d}.csv")
        n = u_open.size
        ff = np.append(u_open, u_open[-1])
        uc = np.zeros(n + 1)
        if pi is None or r is None:
            controller: Any = daq.WaveformController(ff)
        else:
            kp, ki, gain, on, off = pi
            state = {"integ": 0.0, "c": 0.0}

            def func(k: int, _t: float, y: float) -> float:
                if k >= 1 and on <= k - 1 < off:  # y is the output after u[k-1]
                    e = float(r[min(k - 1, n - 1)]) - y
                    state["integ"] += ki * sample_time * e
                    state["c"] = kp * e + state["integ"]
                c = state["c"]
                uc[k] = c
                return float(ff[k] + gain * c)

            controller = daq.CallbackController(func, n + 1)
        res = daq.run_trial(
            device,
            controller,
            path,
            sample_time=sample_time,
            n_samples=n + 1,
            realtime=realtime,
            safety=safety,
            metadata={"experiment": "tracking"},
            overwrite=True,
            fsync=False,
        )
        if not res.complete:
            raise RuntimeError(f"{path}: the tracking run ended early: {res.end_status}")
        rec = Recording.load(path)
        # u_c[k+1] was computed from y after u[k]: shift it to the sample whose error it saw
        return rec.u[:n], rec.y[1 : n + 1], uc[1 : n + 1]

    if own:  # the temporary folder goes with the loop
        weakref.finalize(run, shutil.rmtree, folder, True)
    return run


def _frame(
    model: PreisachModel, ts: float, ramp: float = 0.3, hold: float = 0.1, lead: float = 0.3
) -> tuple[NDArray[np.float64], int, int]:
    """Input ramp 0 -> u_min and hold (samples), and the lead-in length (samples)."""
    n_ramp, n_hold, n_lead = (max(int(round(x / ts)), 1) for x in (ramp, hold, lead))
    pre = np.r_[np.linspace(0.0, model.u_min, n_ramp), np.full(n_hold, model.u_min)]
    return pre, n_hold, n_lead


def run_tracking(
    model: PreisachModel,
    loop: Loop,
    references: Sequence[Reference],
    *,
    modes: Sequence[str] = MODES,
    kp: float = _KP,
    ki: float = _KI,
    input_gain: float = _GAIN,
    progress: Callable[[str], None] | None = None,
    feedforward: Callable[[NDArray[np.float64], State], NDArray[np.float64]] | None = None,
) -> TrackingResult:
    """Run every reference every way on ``loop`` and score it.

    Parameters
    ----------
    model : PreisachModel
        The model used for the feedforward inverse and for the linear gain (its input and
        output ranges).  On a rig, a model identified from the rig's own recordings.
    loop : callable
        From :func:`model_loop` or :func:`device_loop`.
    references : sequence of Reference
        From :func:`tracking_references`; all with one sample time.
    modes : sequence of str
        A subset of :data:`MODES`.
    kp, ki : float
        PI gains (controller units per output volt, per volt-second).
    input_gain : float
        Model-input volts per controller unit.
    progress : callable, optional
        Called with ``"reference mode"`` before each run.
    feedforward : callable, optional
        ``feedforward(r, state)`` returns the drive (model-input V) that makes the plant
        follow ``r`` (V) from ``state`` (negative saturation), for the feedforward modes;
        default the exact inverse of ``model``.  E.g. the inverse of a diagnosed augmented
        model (:func:`preisach.compensate.augmented.invert_augmented`).  Its drive is
        clamped to the model's input range; ``unreachable`` is then not counted (0).

    Returns
    -------
    TrackingResult

    """
    bad = [m for m in modes if m not in MODES]
    if bad:
        raise ValueError(f"modes: unknown mode {bad[0]!r}; choose from {', '.join(MODES)}")
    if not references:
        raise ValueError("references: need at least one reference")
    ts = references[0].sample_time
    if any(not math.isclose(r.sample_time, ts) for r in references):
        raise ValueError("references: all references need the same sample_time")
    stroke = model.y_max - model.y_min
    gain_lin = (model.u_max - model.u_min) / stroke
    pre, n_hold, n_lead = _frame(model, ts)
    s_neg = model.negative_saturation()
    runs: list[TrackingRun] = []
    for ref in references:
        lead = np.linspace(model.y_min, ref.y[0], n_lead, endpoint=False)
        r_all = np.r_[lead, ref.y]  # the reference after the input frame
        if feedforward is None:
            inv = invert(model, r_all, s_neg)
            ff_u, ff_unreachable = inv.input, int(inv.unreachable)
        else:
            ff_u = np.clip(
                np.asarray(feedforward(r_all, s_neg), dtype=float), model.u_min, model.u_max
            )
            if ff_u.shape != r_all.shape:
                raise ValueError(
                    f"feedforward: returned shape {ff_u.shape}, expected {r_all.shape}"
                )
            ff_unreachable = 0
        lin = model.u_min + (r_all - model.y_min) * gain_lin
        for mode in modes:
            if progress is not None:
                progress(f"{ref.name} {mode}")
            drive = lin if mode in ("uncompensated", "pi") else ff_u
            if mode == "pi":
                drive = np.full_like(lin, model.u_min)  # the loop alone, from the hold
            u_body = np.r_[pre, drive]
            tail = np.linspace(u_body[-1], 0.0, max(int(round(0.3 / ts)), 2))
            u_open = np.r_[u_body, tail]
            r_full = np.r_[np.full(pre.size, model.y_min), r_all, np.full(tail.size, r_all[-1])]
            k0 = pre.size  # first lead-in sample
            s0, s1 = k0 + n_lead, k0 + r_all.size
            if mode.startswith("pi"):
                # the PI loop acts from the lead-in to the end of the reference; u_c holds after
                u, y, uc = loop(u_open, r_full, (kp, ki, input_gain, k0, s1))
            else:
                u, y, uc = loop(u_open, None, None)
            err = (r_full - y)[s0:s1]
            effort = None
            if mode.startswith("pi"):
                base = float(np.mean(uc[k0 - n_hold : k0]))
                effort = float(np.linalg.norm(uc[s0:s1] - base))
            runs.append(
                TrackingRun(
                    reference=ref.name,
                    mode=mode,
                    max_error_pct=float(100 * np.max(np.abs(err)) / stroke),
                    rms_error_pct=float(100 * np.sqrt(np.mean(err**2)) / stroke),
                    effort=effort,
                    unreachable=ff_unreachable if "feedforward" in mode else 0,
                    max_drive=float(np.max(np.abs(u[s0:s1]))),
                    t=np.arange(s1 - s0) * ts,
                    r=r_full[s0:s1],
                    u=u[s0:s1],
                    y=y[s0:s1],
                )
            )
    settings = {"kp": kp, "ki": ki, "input_gain": input_gain, "sample_time": ts}
    return TrackingResult(runs, list(references), float(stroke), settings)


def format_tracking_table(result: TrackingResult) -> str:
    """Markdown table: one row per reference, max / RMS error (% of stroke) per mode."""
    modes = [m for m in MODES if any(r.mode == m for r in result.runs)]
    head = "| reference | " + " | ".join(f"{m} max / rms %" for m in modes) + " |"
    if "pi" in modes or "pi+feedforward" in modes:
        head += " PI effort n_c (pi, pi+ff) |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for ref in result.references:
        cells = []
        for m in modes:
            run = result.get(ref.name, m)
            cells.append(f"{run.max_error_pct:.2f} / {run.rms_error_pct:.2f}")
        row = f"| {ref.name} | " + " | ".join(cells) + " |"
        if "pi" in modes or "pi+feedforward" in modes:
            eff = [
                f"{result.get(ref.name, m).effort:.3g}"
                for m in ("pi", "pi+feedforward")
                if m in modes
            ]
            row += " " + ", ".join(eff) + " |"
        lines.append(row)
    return "\n".join(lines)
