"""The trial runner: a clocked sample loop in C++, streamed to a recording (``daq/runner.hpp``).

See :mod:`preisach.daq` for what a trial does at every sample and how it ends.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike

from .. import _core
from ..errors import StopSignal, TrialInterrupted
from ..recording import _check_metadata
from .channel import SafetyLimits
from .controller import WaveformController
from .device import Device

__all__ = ["PathLike", "TrialResult", "run_trial"]

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class TrialResult:
    """How a trial went (see :mod:`preisach.daq`).

    Attributes
    ----------
    path : str
        The recording file.
    end_status : str
        ``"complete"``, ``"interrupted"`` or ``"aborted: <reason>"`` (also in the file).
    reason : str
        Why the trial ended early (``""`` when complete).
    planned, samples, ramp_samples, dropped : int
        Samples planned; taken in the trial proper; recorded during the ramp to 0 V after an
        abort or stop; not recorded because a reading was NaN.
    missed_deadlines : int
        Samples whose I/O finished after the next sample's deadline (real time only).
    missed : list of int
        Indices of the first 1024 of them.
    max_lateness, mean_lateness : float
        Latest and mean start of a sample after its deadline (s).
    elapsed : float
        Wall-clock duration of the sample loop (s).
    final_output : float
        Actuator voltage when the trial ended (V).
    realtime : bool
        Whether the loop was paced by the clock.
    priority : str
        What happened to a SCHED_FIFO request.

    """

    path: str
    end_status: str
    reason: str
    planned: int
    samples: int
    ramp_samples: int
    dropped: int
    missed_deadlines: int
    missed: list[int] = field(repr=False)
    max_lateness: float
    mean_lateness: float
    elapsed: float
    final_output: float
    realtime: bool
    priority: str

    @property
    def complete(self) -> bool:
        """Whether every planned sample was taken and nothing went wrong."""
        return self.end_status == "complete"

    @classmethod
    def _from_core(cls, r: _core.DaqTrialResult) -> TrialResult:
        return cls(
            r.path,
            r.end_status,
            r.reason,
            int(r.planned),
            int(r.samples),
            int(r.ramp_samples),
            int(r.dropped),
            int(r.missed_deadlines),
            [int(i) for i in r.missed],
            float(r.max_lateness),
            float(r.mean_lateness),
            float(r.elapsed),
            float(r.final_output),
            bool(r.realtime),
            r.priority,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        return asdict(self)


def run_trial(
    device: Device,
    controller: _core.DaqController | ArrayLike,
    path: PathLike,
    *,
    sample_time: float,
    n_samples: int = 0,
    realtime: bool = False,
    safety: SafetyLimits | None = None,
    metadata: Mapping[str, Any] | None = None,
    output: int = 0,
    input: int = 0,  # noqa: A002
    overwrite: bool = False,
    fsync: bool = True,
    t0: float = 0.0,
    priority: int = 0,
    spin: float = 2e-4,
    ramp_at_end: bool = False,
    progress: Callable[[int, int], None] | None = None,
    poll: float = 0.1,
) -> TrialResult:
    """Run one trial on a device and stream it to a CSV recording.

    The loop runs in C++ on a worker thread with the GIL released; this thread waits for it,
    calls ``progress`` every ``poll`` seconds, and turns Ctrl-C (:class:`KeyboardInterrupt`)
    into a stop request: the runner ramps the output to 0 V, finishes the file with
    ``end_status: interrupted``, and then :class:`~preisach.errors.TrialInterrupted` (a
    ``KeyboardInterrupt`` carrying the :class:`TrialResult`) is raised.  A second Ctrl-C while
    the file is being finished is ignored.

    Parameters
    ----------
    device : VirtualRig or ComediDevice
        The device (:func:`virtual_ss15`, :func:`comedi_device`).
    controller : controller or array_like
        A :data:`WaveformController`, :data:`PIController` or :data:`CallbackController`, or
        an array of actuator voltages (V), played open loop.
    path : str or path-like
        Recording file (``.csv``); an existing file raises :class:`FileExistsError` unless
        ``overwrite``.
    sample_time : float
        Sample period (s).
    n_samples : int
        Samples to take; 0 (default) means the controller's length.
    realtime : bool
        Pace against the clock.  Always on for a real device.
    safety : SafetyLimits, optional
        Default ``SafetyLimits()``: +/-135 V, 10 kV/s slew, 500 V/s ramp, no input limits;
        abort after more than 20 deadlines missed in a row, no limit on the total
        (``max_missed_deadlines = -1``).  ``ramp_rate`` must not exceed ``slew_rate``.
    metadata : mapping, optional
        Leading metadata of the recording (``str``/``int``/``float``); it overrides the
        runner's own keys (``sample_time``, ``device``, ...).  ``end_status`` is reserved.
    output, input : int
        Index of the actuator output channel and of the primary input (column ``y``).
    overwrite, fsync : bool
        Replace an existing file; fsync every chunk written.
    t0 : float
        Time of the first sample in the file (s).
    priority : int
        Request SCHED_FIFO at this priority for the sample loop (needs privileges; the result
        says whether it was granted).
    spin : float
        Busy-wait before each deadline (s), after sleeping until then.
    ramp_at_end : bool
        Ramp the output to 0 V after a complete trial too.
    progress : callable, optional
        ``progress(samples_done, samples_planned)``, called from this thread.  If it raises,
        a stop is requested (the output ramps to 0 V, the file is finished with
        ``end_status: interrupted`` and an ``end_reason`` naming the exception) and the
        exception is re-raised once the worker has finished.
    poll : float
        Seconds between progress calls.

    Returns
    -------
    TrialResult
        Also when the trial was aborted (check :attr:`TrialResult.end_status`).

    Raises
    ------
    preisach.errors.TrialInterrupted
        After Ctrl-C, once the file is complete.
    Exception
        What a Python callback controller or the ``progress`` callback raised, or a device
        error, re-raised after the file was finished (``end_status``/``end_reason`` name it).

    """
    if not isinstance(controller, _core.DaqController):
        controller = WaveformController(np.ascontiguousarray(controller, dtype=float))
    meta = _check_metadata(metadata)
    if "end_status" in meta:
        raise ValueError("metadata key 'end_status' is reserved: the runner writes it")
    runner = _core.DaqTrialRunner()
    box: dict[str, Any] = {}
    done = threading.Event()
    # The worker starts the trial only once this thread waits in the ``try`` below: a Ctrl-C
    # arriving while ``Thread.start`` still waits for the thread must not escape with the
    # output live (the worker's own callback can interrupt this thread from sample one).
    go = threading.Event()

    def work() -> None:
        # polled: a Ctrl-C inside go.set() can land between setting the flag and notifying
        while not go.wait(0.05):
            pass
        if "cancelled" in box:  # stopped before the trial began: nothing to drive or write
            done.set()
            return
        try:
            box["result"] = runner.run(
                device,
                controller,
                os.fspath(path),
                float(sample_time),
                n_samples=int(n_samples),
                realtime=bool(realtime),
                output=int(output),
                input=int(input),
                overwrite=bool(overwrite),
                fsync=bool(fsync),
                metadata=meta,
                spin=float(spin),
                t0=float(t0),
                priority=int(priority),
                ramp_at_end=bool(ramp_at_end),
                safety=SafetyLimits() if safety is None else safety,
            )
        except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
            box["error"] = exc
        finally:
            done.set()

    # Wait on an Event, not Thread.join: a KeyboardInterrupt inside join() can leave the
    # thread marked finished while it still runs (CPython gh-90882).
    worker = threading.Thread(target=work, name="preisach-trial", daemon=True)
    interrupted = False

    def cancelled() -> bool:
        # Whether the trial had not begun; if so, let the worker (if it runs at all) return
        # at once, having driven and written nothing.
        if go.is_set():
            return False
        box["cancelled"] = True
        go.set()
        return True

    def finish() -> None:
        # Wait for the worker to ramp the output down and close the file, whatever happens.
        while not done.is_set():
            try:
                done.wait(0.05)
            except KeyboardInterrupt:  # a second Ctrl-C: finish the file first
                pass
        worker.join()

    try:
        worker.start()  # a Ctrl-C may land while it waits for the thread to start
        go.set()
        while not done.wait(poll):
            if progress is not None:
                progress(runner.progress, runner.planned)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP as a StopSignal
        if cancelled():  # nothing was driven or written; a signal keeps its name (exit code)
            if isinstance(exc, StopSignal):
                raise
            raise KeyboardInterrupt("interrupted before the trial began") from exc
        interrupted = True
        runner.request_stop(str(exc) or "interrupted by the user (KeyboardInterrupt)")
        finish()
    except BaseException as exc:
        if cancelled():
            raise
        # The progress callback (or anything else in this thread) failed: never leave the
        # worker running with the output live - stop it, let it finish the file, re-raise.
        runner.request_stop(f"stopped: {type(exc).__name__} in the calling thread: {exc}")
        finish()
        raise
    worker.join()
    if "error" in box:
        raise box["error"]
    result = TrialResult._from_core(box["result"])
    if progress is not None:
        progress(result.samples, result.planned)
    if interrupted:
        raise TrialInterrupted(
            f"trial interrupted after {result.samples} samples; "
            f"{result.path} is complete up to there",
            result,
        )
    return result
