"""The DAQ layer: devices, controllers and the trial runner (C++ through pybind11).

A *trial* is a clocked sample loop run in C++ with the GIL released.  At every sample ``k``
(time ``t_k = k * sample_time``) the runner

1. reads every input channel (connector volts) and converts it to physical units with the
   channel's linear calibration (``physical = gain * connector + offset``, Appendix B);
2. checks the readings: NaN (a converter at the end of its range) or a primary reading outside
   ``[y_min, y_max]`` aborts the trial;
3. asks the controller for the actuator voltage (open-loop waveform, PI regulator, or a Python
   callback that gets the GIL only for the call);
4. applies the safety limits - clamp to ``[u_min, u_max]`` (default +/-135 V, what the SA11
   amplifier delivers, thesis section 3.1), slew-rate limit, then the output channel's range -
   converts to connector volts with the inverse calibration and writes it;
5. pushes the sample into a preallocated ring buffer that a writer thread streams to the
   recording file in chunks.

With ``realtime=True`` (always, for a real device) each sample starts at an absolute deadline
(``steady_clock``; sleep until shortly before, then spin); a sample whose I/O ends after the
next deadline is a *missed deadline*; every one is counted (``TrialResult.missed_deadlines``,
the first 1024 indices in ``TrialResult.missed``) and the per-sample lateness is a column of
the recording.  A simulated device otherwise runs as fast as it can.

A NaN or out-of-range reading, a controller error, a non-finite command, more deadlines missed
in a row than ``SafetyLimits.max_consecutive_missed`` (default 20: a stall of 20 ms at 1 kHz) or
in total than ``SafetyLimits.max_missed_deadlines`` (default: no limit; a lone late sample only
holds the previous output one period longer), or a stop request ends the trial early: the output
is ramped to 0 V at ``ramp_rate`` (still sampling and recording), and the file is closed with
``end_status`` ``"interrupted"`` (stop request, Ctrl-C) or ``"aborted: <reason>"``.  In every
case the file holds every sample taken and loads with :meth:`preisach.Recording.load`.

Recording columns: ``t`` (s), ``u`` (V at the actuator, after the limits), ``y`` (primary
input, physical), ``u_cmd`` (the controller's request), ``u_dac`` (connector volts written),
``y_adc`` (connector volts read), further input channels by name, ``lateness`` (s).  Note the
clocked-loop causality: ``y[k]`` is read at ``t_k`` *before* ``u[k]`` is written, so it
responds to the inputs up to ``u[k-1]``.

Devices: :func:`virtual_ss15` (the embedded default: a Preisach plant between the Appendix B
calibration and a noisy 14-bit ADC, with optional physics blocks) and :func:`comedi_device`
(real cards on Linux through comedilib; :func:`comedi_available` tells whether this build has
it).
"""

from __future__ import annotations

import itertools
import math
import os
import tempfile
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _core
from .blocks import Block, BlockChain, make_block
from .calibration import SS15_CHANNEL_B, LinearCalibration
from .errors import TrialInterrupted
from .model import PreisachModel, State
from .recording import Recording, _check_metadata

__all__ = [
    "CallbackController",
    "Channel",
    "DevicePlant",
    "PIController",
    "SafetyLimits",
    "TrialResult",
    "WaveformController",
    "channel",
    "comedi_available",
    "comedi_device",
    "run_trial",
    "ss15_input_channel",
    "ss15_output_channel",
    "virtual_ss15",
]

Channel = _core.DaqChannel
SafetyLimits = _core.DaqSafety
WaveformController = _core.DaqWaveformController
PIController = _core.DaqPIController
CallbackController = _core.DaqCallbackController
comedi_available = _core.comedi_available

Device = Union[_core.VirtualRig, _core.ComediDevice, _core.DaqDevice]
PathLike = Union[str, "os.PathLike[str]"]


def channel(
    name: str,
    number: int,
    range: tuple[float, float],  # noqa: A002 - the DAQ term
    calibration: LinearCalibration | None = None,
    *,
    unit: str = "V",
    subdevice: int = -1,
    aref: int = 0,
) -> Channel:
    """Describe an analog channel with a :class:`~preisach.calibration.LinearCalibration`.

    Parameters
    ----------
    name : str
        Channel name (the recording's column for inputs other than the primary one).
    number : int
        Channel number on the card.
    range : (float, float)
        Connector-volt range the converter is set to, e.g. ``(-10, 10)``.
    calibration : LinearCalibration, optional
        ``physical = gain * connector + offset``; default the identity.
    unit : str
        Physical unit (``"V"``).
    subdevice : int
        Comedi subdevice; -1 picks the first analog output/input subdevice.
    aref : int
        Comedi analog reference: 0 ground, 1 common, 2 differential.

    """
    cal = calibration if calibration is not None else LinearCalibration(1.0, 0.0)
    return Channel(
        name,
        int(number),
        (float(range[0]), float(range[1])),
        cal.gain,
        cal.offset,
        unit,
        int(subdevice),
        int(aref),
    )


def ss15_output_channel() -> Channel:
    """Return the SS15 drive: Quanser DAC CH 1 (+/-10 V) into SA11 channel B, Eq B.1b/B.2.

    ``V_in = -14.12 V_bin - 0.02`` (:data:`preisach.calibration.SS15_CHANNEL_B`).
    """
    return channel("V_in", 1, (-10.0, 10.0), SS15_CHANNEL_B)


def ss15_input_channel() -> Channel:
    """Return the SS15 strain-gauge output: Quanser ADC Ch 1 (+/-5 V), identity calibration.

    Table B.1 shows the ADC reads the connector voltage to within 0.03 V, so the thesis
    used no ADC equation; neither do we.
    """
    return channel("V_out", 1, (-5.0, 5.0))


def _as_blocks(blocks: Iterable[Block | Mapping[str, Any]], dt: float) -> list[Block]:
    out: list[Block] = []
    for i, b in enumerate(blocks):
        if isinstance(b, Block):
            if not math.isclose(b.dt, dt, rel_tol=1e-12):
                raise ValueError(
                    f"block {i} ({b.kind}) has dt = {b.dt} s but the rig samples every {dt} s"
                )
            out.append(b)
        elif isinstance(b, Mapping):
            out.append(make_block(b, dt))
        else:
            raise TypeError(
                f"block {i}: expected a preisach block or a mapping, got {type(b).__name__}"
            )
    return out


def _start_state(model: PreisachModel, state: State | str | None) -> State:
    if state is None or isinstance(state, str):
        name = "anhysteretic" if state is None else state
        makers = {
            "anhysteretic": model.anhysteretic_state,
            "negative_saturation": model.negative_saturation,
            "positive_saturation": model.positive_saturation,
        }
        if name not in makers:
            raise ValueError(f"state: expected a State or one of {sorted(makers)}, got {name!r}")
        return makers[name]()
    return state


def virtual_ss15(
    model: PreisachModel | str = "ss15-1hz",
    state: State | str | None = None,
    *,
    sample_time: float = 1e-3,
    input_blocks: Sequence[Block | Mapping[str, Any]] = (),
    output_blocks: Sequence[Block | Mapping[str, Any]] = (),
    moving_gain: float = 0.0,
    adc_noise: float = 0.5e-3,
    adc_bits: int = 14,
    dac_bits: int = 0,
    amplifier: LinearCalibration = SS15_CHANNEL_B,
    amp_limit: float = 150.0,
    output: Channel | None = None,
    input: Channel | None = None,  # noqa: A002
    seed: int = 0,
) -> _core.VirtualRig:
    """Build the virtual SS15 rig: DAC -> SA11 amplifier -> plant -> ADC, all in C++.

    The plant is ``input_blocks -> Preisach model -> output_blocks``
    (see :mod:`preisach.blocks`); with no blocks it is the classical model alone.

    Parameters
    ----------
    model : PreisachModel or str
        The Preisach model (input ``V_in`` in V, output in V), or a built-in name
        (``"ss15-1hz"``, ``"ss15-2hz"``, ``"ss15-4hz"``) or a saved model file.
    state : State or str, optional
        Starting state: a :class:`State`, ``"anhysteretic"`` (default),
        ``"negative_saturation"`` or ``"positive_saturation"``.
    sample_time : float
        The rig's sample period (s); trials must use it (the blocks are discretised for it).
    input_blocks, output_blocks : sequence
        Blocks (or ``{"kind": ..., **params}`` mappings) before and after the Preisach stage.
    moving_gain : float
        Output feedback of the Preisach stage (V/V), 0 for the classical model.
    adc_noise : float
        Measurement noise (V rms, Gaussian, seeded) added at the ADC input.
    adc_bits : int
        ADC resolution over the input channel's range (14 bits over +/-5 V = 0.61 mV).
    dac_bits : int
        DAC resolution over the output channel's range (0: ideal).
    amplifier : LinearCalibration
        The rig's *true* amplifier ``V_in = gain * V_dac + offset`` (Eq B.1b by default).  Give
        a different one than the output channel's calibration to simulate a miscalibration.
    amp_limit : float
        The amplifier's output swing (V).
    output, input : Channel, optional
        Default :func:`ss15_output_channel` and :func:`ss15_input_channel`.
    seed : int
        Seed of the ADC noise.

    Returns
    -------
    preisach._core.VirtualRig
        A device for :func:`run_trial`; ``rig.state``, ``rig.plant_output`` and
        ``rig.reset(state)`` inspect and reset it between trials.

    """
    if isinstance(model, str):
        model = (
            PreisachModel.builtin(model)
            if model.lower().startswith("ss15-")
            else PreisachModel.load(model)
        )
    if not isinstance(model, PreisachModel):
        raise TypeError(f"model: expected a PreisachModel or a name, got {type(model).__name__}")
    dt = float(sample_time)
    chain = [
        *_as_blocks(input_blocks, dt),
        _core.PreisachStage(dt, model.table, _start_state(model, state), float(moving_gain)),
        *_as_blocks(output_blocks, dt),
    ]
    return _core.VirtualRig(
        BlockChain(chain),
        ss15_output_channel() if output is None else output,
        ss15_input_channel() if input is None else input,
        sample_time=dt,
        dac_bits=int(dac_bits),
        amp_gain=amplifier.gain,
        amp_offset=amplifier.offset,
        amp_limit=float(amp_limit),
        adc_bits=int(adc_bits),
        adc_noise=float(adc_noise),
        seed=int(seed),
    )


def comedi_device(
    file: str,
    outputs: Sequence[Channel] | None = None,
    inputs: Sequence[Channel] | None = None,
    *,
    calibration_file: str = "",
) -> _core.ComediDevice:
    """Open a Comedi card (Linux) for trials.

    Parameters
    ----------
    file : str
        Device file, e.g. ``"/dev/comedi0"``.
    outputs, inputs : sequence of Channel, optional
        Default the SS15 wiring: :func:`ss15_output_channel`, :func:`ss15_input_channel`.
    calibration_file : str
        comedilib software-calibration file (from ``comedi_soft_calibrate``) for
        software-calibrated cards; default comedilib's default path.

    Raises
    ------
    preisach.errors.DeviceError
        If the file cannot be opened (the message names it), a channel or range does not
        exist, the calibration is missing, or this build has no Comedi support.

    """
    return _core.ComediDevice(
        file,
        list(outputs) if outputs is not None else [ss15_output_channel()],
        list(inputs) if inputs is not None else [ss15_input_channel()],
        calibration_file,
    )


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

    def work() -> None:
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
    worker.start()

    def finish() -> None:
        # Wait for the worker to ramp the output down and close the file, whatever happens.
        while not done.is_set():
            try:
                done.wait(0.05)
            except KeyboardInterrupt:  # a second Ctrl-C: finish the file first
                pass
        worker.join()

    try:
        while not done.wait(poll):
            if progress is not None:
                progress(runner.progress, runner.planned)
    except KeyboardInterrupt:
        interrupted = True
        runner.request_stop("interrupted by the user (KeyboardInterrupt)")
        finish()
    except BaseException as exc:
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


class DevicePlant:
    """A DAQ device as a plant of :mod:`preisach.experiments` (its ``Plant`` protocol).

    Every run is a trial of :func:`run_trial` on the device, recorded to a file, so the
    regulation experiments (``drive_to_state``, ``drift_test``, ``closed_loop_test``, the
    sweeps) run unchanged on the virtual rig or a real one.  The protocol's timing is kept:
    its ``y[k]`` is the output *after* ``u[k]`` was applied, which on a clocked loop is the
    reading of the next sample, so each run takes one extra sample (holding the last input)
    and returns the readings shifted by one; the PI controller's ``u_c[k]`` from ``y[k]``
    acts at sample ``k + 1`` exactly as :class:`~preisach.experiments.PIConfig` describes.

    Parameters
    ----------
    device : VirtualRig or ComediDevice
        The device.
    sample_time : float, optional
        Sample period (s); default the virtual rig's, required for other devices.
    input_range : (float, float)
        Admissible actuator input (V); ``u_max`` is the saturation ``u_hat`` of the
        initialisation inputs.
    model : PreisachModel, optional
        A model of the rig; ``drive_to_state`` uses it for the neutral locus of psi_n.
    record_dir : str or path-like, optional
        Keep every run's recording there (``run_0001_open.csv``, ...); default a temporary
        folder removed with the plant.
    realtime : bool
        Pace a simulated device (a real one always is).
    safety : SafetyLimits, optional
        Limits of every run.

    """

    def __init__(
        self,
        device: Device,
        *,
        sample_time: float | None = None,
        input_range: tuple[float, float] = (-100.0, 100.0),
        model: PreisachModel | None = None,
        record_dir: PathLike | None = None,
        realtime: bool = False,
        safety: SafetyLimits | None = None,
    ) -> None:
        if sample_time is None:
            if not isinstance(device, _core.VirtualRig):
                raise ValueError("sample_time: required for a device other than the virtual rig")
            sample_time = device.sample_time
        self.device = device
        self._ts = float(sample_time)
        self._range = (float(input_range[0]), float(input_range[1]))
        if model is not None:
            self.model = model
        self.realtime = bool(realtime)
        self.safety = safety
        self._tmp = (
            tempfile.TemporaryDirectory(prefix="preisach-plant-") if record_dir is None else None
        )
        self.record_dir = os.fspath(record_dir) if record_dir is not None else self._tmp.name  # type: ignore[union-attr]
        os.makedirs(self.record_dir, exist_ok=True)
        self._count = itertools.count(1)
        #: Results of the runs so far, in order.
        self.results: list[TrialResult] = []

    def __repr__(self) -> str:
        return f"DevicePlant({self.device.description!r}, sample_time={self._ts:g})"

    @property
    def sample_time(self) -> float:
        """Sampling period (s)."""
        return self._ts

    @property
    def input_range(self) -> tuple[float, float]:
        """``(u_min, u_max)`` (V)."""
        return self._range

    def reset(self, state: State | None = None) -> None:
        """Virtual rig: set the Preisach state (default its starting state).

        A real device cannot be put in a given state: ``None`` is accepted (every experiment
        starts by saturating the input), a state raises :class:`ValueError`.
        """
        if isinstance(self.device, _core.VirtualRig):
            self.device.reset(state)
        elif state is not None:
            raise ValueError("reset: a real device cannot be set to a given Preisach state")

    def snapshot(self) -> State | None:
        """Return the virtual rig's Preisach state; ``None`` for a real device."""
        return self.device.state if isinstance(self.device, _core.VirtualRig) else None

    def _run(self, controller: Any, n: int, kind: str) -> Recording:
        path = os.path.join(self.record_dir, f"run_{next(self._count):04d}_{kind}.csv")
        res = run_trial(
            self.device,
            controller,
            path,
            sample_time=self._ts,
            n_samples=n + 1,
            realtime=self.realtime,
            safety=self.safety,
            metadata={"experiment": f"plant_{kind}"},
        )
        self.results.append(res)
        if not res.complete:
            raise RuntimeError(f"{path}: the run ended early: {res.end_status}")
        return Recording.load(path)

    def run_open_loop(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply ``u`` (V), one sample per ``sample_time``; returns the outputs (V)."""
        uu = np.ascontiguousarray(u, dtype=float)
        if uu.ndim != 1 or uu.size == 0:
            raise ValueError(f"u: expected a non-empty 1-D array, got shape {uu.shape}")
        rec = self._run(WaveformController(np.append(uu, uu[-1])), uu.size, "open")
        return rec.y[1:]

    def run_closed_loop(
        self, u_open: ArrayLike, controller: Any
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop of a :class:`~preisach.experiments.PIConfig` over ``u_open`` (V).

        Returns the applied input (V), the output (V) and the controller output (controller
        units), sample for sample as :class:`~preisach.experiments.ModelPlant` does.
        """
        uu = np.ascontiguousarray(u_open, dtype=float)
        if uu.ndim != 1 or uu.size == 0:
            raise ValueError(f"u_open: expected a non-empty 1-D array, got shape {uu.shape}")
        if not math.isclose(controller.sample_time, self._ts, rel_tol=1e-9):
            raise ValueError(
                f"controller.sample_time = {controller.sample_time:g} s differs from "
                f"the plant's sample_time {self._ts:g} s"
            )
        g = float(controller.input_gain)
        ff = np.append(uu, uu[-1])
        pi = PIController(
            controller.kp * g,
            controller.ki * g,
            controller.setpoint,
            self._ts,
            ff,
            enable_at=int(controller.enable_at) + 1,
            average=int(controller.average),
        )
        rec = self._run(pi, uu.size, "closed")
        n = uu.size
        uc = (rec.columns["u_cmd"][1 : n + 1] - ff[1 : n + 1]) / g if g else np.zeros(n)
        return rec.u[:n], rec.y[1 : n + 1], uc
