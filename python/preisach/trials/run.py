"""Running a trial file on a device: one recording per step, the safety ramp, the summary."""

from __future__ import annotations

import errno
import json
import os
import re
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import daq
from .._io import write_json
from .._signals import StopSignals, stop_signals
from ..errors import TrialInterrupted
from .plan import _approach, _load_model, check_trial, step_waveform
from .schema import PlannedStep, TrialPlan


# ------------------------------------------------------------------------------------------
# run
# ------------------------------------------------------------------------------------------
@dataclass
class StepOutcome:
    """What one step did.

    Attributes
    ----------
    index, kind, name : int, str, str
        The step.
    file : str
        Its recording.
    result : preisach.daq.TrialResult
        The runner's result.
    info : dict
        Planning details (drive offset, approach samples, ...).

    """

    index: int
    kind: str
    name: str
    file: str
    result: daq.TrialResult
    info: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        d = {
            "index": self.index,
            "kind": self.kind,
            "name": self.name,
            "file": self.file,
            "info": self.info,
        }
        d.update({k: v for k, v in self.result.to_dict().items() if k not in ("path", "missed")})
        d["missed"] = self.result.missed[:100]
        return d


@dataclass
class TrialOutcome:
    """The result of :func:`run_trial_file`.

    Attributes
    ----------
    plan : TrialPlan
    device : str
        Device description.
    end_status : str
        ``"complete"``, or the ``end_status`` of the step that ended the trial.
    steps : list of StepOutcome
    summary_file : str
        The ``summary.json`` written.

    """

    plan: TrialPlan
    device: str
    end_status: str
    steps: list[StepOutcome]
    summary_file: str

    @property
    def complete(self) -> bool:
        """Whether every step completed."""
        return self.end_status == "complete"


def _make_device(plan: TrialPlan, device: str | None) -> Any:
    spec = device or plan.device["kind"]
    if spec == "sim":
        d = plan.device
        return daq.virtual_ss15(
            _load_model(d["model"]),
            d["state"],
            sample_time=plan.sample_time,
            input_blocks=d["input_blocks"],
            output_blocks=d["output_blocks"],
            moving_gain=d["moving_gain"],
            adc_noise=d["adc_noise"],
            adc_bits=d["adc_bits"],
            dac_bits=d["dac_bits"],
            output=plan.output,
            input=plan.input,
            seed=d["seed"],
        )
    if spec.startswith("comedi"):
        file = spec.partition(":")[2] or plan.device.get("file")
        if not file:
            raise ValueError("--device comedi needs a device file: comedi:/dev/comediN")
        return daq.comedi_device(
            file, [plan.output], [plan.input], calibration_file=plan.device["calibration_file"]
        )
    raise ValueError(f"device {spec!r}: expected 'sim' or 'comedi:/dev/comediN'")


#: The names this runner gives its files: recordings ``NN_<name>.csv`` and ``summary.json``.
_RUN_FILE = re.compile(r"^(\d{2}_[A-Za-z0-9_-]+\.csv|summary\.json)$")


def _previous_run(out: Path) -> list[Path]:
    """Return the files of an earlier run in ``out`` (``NN_<name>.csv``, ``summary.json``)."""
    if not out.is_dir():
        return []
    return sorted(p for p in out.iterdir() if _RUN_FILE.match(p.name) and not p.is_dir())


def _check_folder(out: Path, overwrite: bool) -> list[Path]:
    """Refuse an output folder that cannot take this run, before anything is written.

    Returns the files of an earlier run that ``overwrite`` will remove.
    """
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(
            errno.ENOTDIR, "the output folder is not a directory; nothing was written", str(out)
        )
    old = _previous_run(out)
    if old and not overwrite:
        names = ", ".join(p.name for p in old[:3]) + (", ..." if len(old) > 3 else "")
        raise FileExistsError(
            errno.EEXIST,
            f"the output folder holds an earlier run ({names}); nothing was written - use "
            "--overwrite (overwrite=True) to replace it, or another folder",
            str(out),
        )
    return old


def _ramp_file(out: Path, number: int, written: set[Path], overwrite: bool) -> Path:
    """``NN_ramp.csv`` in ``out``, or ``NN_ramp-2.csv``, ... when that name is taken."""
    file = out / f"{number:02d}_ramp.csv"
    k = 1
    while file in written or (file.exists() and not overwrite):
        k += 1
        file = out / f"{number:02d}_ramp-{k}.csv"
    return file


def _ramp_to_zero(
    dev: daq.Device,
    plan: TrialPlan,
    safety: daq.SafetyLimits,
    file: Path,
    *,
    t0: float,
    realtime: bool,
    fsync: bool,
    priority: int,
) -> dict[str, Any] | None:
    """Ramp the actuator from its last output to 0 V at ``safety.ramp_rate``, recorded.

    Used when a trial stops between steps (or a step raises): the runner's own ramp only
    runs inside a trial.  Returns what happened, for the summary (``None`` when the output
    is already at 0 V); never raises, so the caller can re-raise what stopped the trial.
    """
    try:
        u = float(dev.outputs[0].physical(dev.last_output(0)))
    except Exception as exc:  # noqa: BLE001 - reported in the summary
        return {"error": f"cannot read the output: {type(exc).__name__}: {exc}"}
    if abs(u) < 1e-9:
        return None
    ts = plan.sample_time
    wave = np.append(_approach(u, 0.0, safety.ramp_rate, ts), 0.0)
    doc: dict[str, Any] = {"file": str(file), "from": u, "ramp_rate": safety.ramp_rate}
    try:
        res = daq.run_trial(
            dev,
            wave,
            file,
            sample_time=ts,
            realtime=realtime,
            safety=safety,
            metadata={"experiment": "safety_ramp", "trial": plan.name, "ramp_from": u},
            overwrite=True,
            fsync=fsync,
            t0=t0,
            priority=priority,
            ramp_at_end=True,
        )
    except TrialInterrupted as exc:  # Ctrl-C during the ramp: the runner still ramped down
        if not isinstance(exc.result, daq.TrialResult):  # pragma: no cover
            doc["error"] = f"TrialInterrupted: {exc}"
            return doc
        res = exc.result
    except BaseException as exc:  # noqa: BLE001 - reported; the caller re-raises its own
        doc["error"] = f"{type(exc).__name__}: {exc}"
        return doc
    doc.update(
        end_status=res.end_status,
        samples=res.samples,
        ramp_samples=res.ramp_samples,
        final_output=res.final_output,
    )
    return doc


def run_trial_file(
    path: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    *,
    device: str | None = None,
    realtime: bool = False,
    overwrite: bool = False,
    fsync: bool = True,
    priority: int = 0,
    progress: Callable[[int, int, PlannedStep, int, int], None] | None = None,
) -> TrialOutcome:
    """Check and run a trial file; one recording per step plus ``summary.json`` in ``outdir``.

    Parameters
    ----------
    path : str or path-like
        The trial file.
    outdir : str or path-like
        Output folder (created).
    device : str, optional
        ``"sim"`` or ``"comedi:/dev/comediN"`` to override the file's ``[device] kind``.
    realtime : bool
        Pace a simulated device in real time (a real one always is).
    overwrite : bool
        Reuse a folder that holds an earlier run: its ``summary.json`` and ``NN_<name>.csv``
        recordings are removed first (other files are kept), so the folder holds this run
        only.  Without it such a folder raises :class:`FileExistsError` before anything is
        written or the device is opened.
    fsync : bool
        fsync the recordings as they are written.
    priority : int
        SCHED_FIFO priority to request for the sample loop (0: none).
    progress : callable, optional
        ``progress(done, planned, step, step_number, n_steps)`` during each step.

    Returns
    -------
    TrialOutcome
        Its ``end_status`` is not ``"complete"`` when a step aborted (later steps are skipped).

    Raises
    ------
    TrialFileError
        If the file does not pass :func:`check_trial`.
    preisach.errors.TrialInterrupted
        On Ctrl-C during a step - or SIGTERM/SIGHUP, handled the same way while the trial runs
        (``signum`` says which; the summary's ``stop_signal`` too) - after the output was
        ramped to 0 V and the current recording and the summary were written.
    BaseException
        Anything else raised once the device is open - a Ctrl-C between steps, an error while
        planning a step, a device error - is re-raised after the output was ramped from its
        last value to 0 V at the safety ``ramp_rate`` (a recorded run of the same runner,
        ``NN_ramp.csv``, ``NN`` the number of the step in progress, listed as
        ``safety_ramp`` in the summary) and ``summary.json`` was written with ``end_status``
        ``"interrupted"`` (:class:`KeyboardInterrupt`) or ``"aborted: <ExcType: message>"``.

    """
    plan = check_trial(path)
    out = Path(outdir)
    old = _check_folder(out, overwrite)
    dev = _make_device(plan, device)
    out.mkdir(parents=True, exist_ok=True)
    for f in old:  # --overwrite: the folder holds this run only
        f.unlink()
    with stop_signals() as stops:
        return _run(plan, dev, out, stops, realtime, overwrite, fsync, priority, progress)


def _run(
    plan: TrialPlan,
    dev: daq.Device,
    out: Path,
    stops: StopSignals,
    realtime: bool,
    overwrite: bool,
    fsync: bool,
    priority: int,
    progress: Callable[[int, int, PlannedStep, int, int], None] | None,
) -> TrialOutcome:
    safety = plan.safety_limits()
    outcomes: list[StepOutcome] = []
    end_status = "complete"
    u_now = float(dev.outputs[0].physical(dev.last_output(0)))
    t0 = 0.0
    started = time.time()
    summary = out / "summary.json"
    interrupted: TrialInterrupted | None = None
    number = 1  # of the step in progress
    written: set[Path] = set()  # recordings of this run, never overwritten by the safety ramp
    safety_ramp: dict[str, Any] | None = None
    error: BaseException | None = None
    try:
        for i, step in enumerate(plan.steps):
            number = i + 1
            u, info = step_waveform(plan, step, u_now)
            last = i == len(plan.steps) - 1
            meta: dict[str, Any] = {
                "experiment": step.kind,
                "trial": plan.name,
                "step": step.index,
                "step_name": step.name,
                "step_params": json.dumps(step.params, sort_keys=True),
            }
            meta.update(
                {
                    f"plan_{k}": v
                    for k, v in info.items()
                    if isinstance(v, (int, float, str)) and not isinstance(v, bool)
                }
            )
            if step.kind == "pi":
                p = step.params
                g = p["input_gain"]
                controller: Any = daq.PIController(
                    p["kp"] * g,
                    p["ki"] * g,
                    p["setpoint"],
                    plan.sample_time,
                    u,
                    enable_at=info["approach_samples"]
                    + int(round(p["enable_after"] / plan.sample_time)),
                    average=max(1, int(round(p["average"] / plan.sample_time))),
                )
            else:
                controller = daq.WaveformController(u)
            file = out / step.file_name

            def report(done: int, planned: int, _s: PlannedStep = step, _i: int = i) -> None:
                if progress is not None:
                    progress(done, planned, _s, _i + 1, len(plan.steps))

            written.add(file)
            try:
                res = daq.run_trial(
                    dev,
                    controller,
                    file,
                    sample_time=plan.sample_time,
                    realtime=realtime,
                    safety=safety,
                    metadata=meta,
                    overwrite=overwrite,
                    fsync=fsync,
                    t0=t0,
                    priority=priority,
                    ramp_at_end=last,
                    progress=report,
                )
            except TrialInterrupted as exc:
                interrupted = exc
                if not isinstance(exc.result, daq.TrialResult):  # pragma: no cover
                    raise
                res = exc.result
            outcomes.append(StepOutcome(step.index, step.kind, step.name, str(file), res, info))
            u_now = res.final_output
            t0 += (res.samples + res.ramp_samples) * plan.sample_time
            if interrupted is not None or not res.complete:
                end_status = res.end_status
                break
    except BaseException as exc:
        error = exc
        end_status = (
            "interrupted"
            if isinstance(exc, KeyboardInterrupt)
            else f"aborted: {type(exc).__name__}: {exc}"
        )
        safety_ramp = _ramp_to_zero(
            dev,
            plan,
            safety,
            _ramp_file(out, number, written, overwrite),
            t0=t0,
            realtime=realtime,
            fsync=fsync,
            priority=priority,
        )
    finally:
        doc = {
            "trial": plan.name,
            "file": plan.path,
            "description": plan.description,
            "device": dev.description,
            "realtime": bool(realtime or not dev.simulated),
            "sample_time": plan.sample_time,
            "end_status": end_status,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(started)),
            "elapsed": time.time() - started,
            "steps_planned": len(plan.steps),
            "steps_run": len(outcomes),
            "steps": [o.to_dict() for o in outcomes],
        }
        if safety_ramp is not None:
            doc["safety_ramp"] = safety_ramp
        try:  # what the actuator was left at: 0 V unless the device itself failed
            doc["final_output"] = float(dev.outputs[0].physical(dev.last_output(0)))
        except Exception as exc:  # noqa: BLE001 - reported in the summary
            doc["final_output"] = f"unknown: {type(exc).__name__}: {exc}"
        if stops.received is not None:
            doc["stop_signal"] = signal.Signals(stops.received).name
        try:
            write_json(summary, doc, indent=2, what="trial summary")
        except OSError as exc:
            if error is None and interrupted is None:
                raise
            # What stopped the run matters more; the summary's failure goes with it.
            msg = f"the summary was not written: {exc}"
            pending = error if error is not None else interrupted
            if sys.version_info >= (3, 11) and pending is not None:
                pending.add_note(msg)
            print(f"preisach trial: {msg}", file=sys.stderr)
    if error is not None:
        raise error
    outcome = TrialOutcome(plan, dev.description, end_status, outcomes, str(summary))
    if interrupted is not None:
        if stops.received is not None:
            raise TrialInterrupted(
                f"{interrupted} (stopped by {doc['stop_signal']})", outcome, signum=stops.received
            )
        raise TrialInterrupted(str(interrupted), outcome)
    return outcome
