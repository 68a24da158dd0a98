"""Where the output comes from: the plant interface of the regulation experiments.

The experiments of chapters 4-5 only need a *plant*: something that can be put in a start
state, driven open loop with an input sequence, and run in a clocked PI loop.  They are
written against the :class:`Plant` protocol, so the same experiment definitions run on

* :class:`ModelPlant` - a :class:`~preisach.PreisachModel` simulated in C++ (this module), and
* a DAQ-backed plant (the hardware layer), which implements the same four methods.

Units.  A plant's input is the **model input** (for the SS15: the amplifier voltage ``V_in``,
volts) and its output the measured output (volts).  The thesis states its noise amplitude
(0.5 V) and PI gains (``K_p = 1.5``, ``K_i = 30``) at the DAQ connector: its Simulink signals
are in DAQ volts (Eq 4.3 uses ``u_hat = 7`` V for the +/-100 V range), which the SA11 amplifier
multiplies by 14.12 in magnitude (Eq B.2).  The experiments therefore scale noise and
controller output by ``input_gain`` (default :data:`SS15_INPUT_GAIN`) before they reach the
plant; set ``input_gain=1`` to state them directly in model-input volts.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..daq.calibration import SS15_INPUT_GAIN
from ..model import BUILTIN_MODELS, PreisachModel, Slopes, State

__all__ = [
    "SS15_INPUT_GAIN",
    "ModelPlant",
    "PIConfig",
    "Plant",
    "SimulatedPlant",
    "ss15_plants",
    "thesis_sample_time",
]


def thesis_sample_time(frequency: float) -> float:
    """Loop sample time (s) of §5.1: 1 ms for 1 and 2 Hz initialisation, 0.5 ms for 4 Hz."""
    if not (math.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency: must be a positive number of Hz, got {frequency!r}")
    return 5e-4 if frequency >= 4.0 else 1e-3


@dataclass(frozen=True)
class PIConfig:
    """One closed-loop run: the discrete PI controller of Eq 5.2 and how it meets the plant.

    The loop, sample by sample ``k`` (the clocked loop of a DAQ trial runner):

    * ``u(k) = u_open(k) + input_gain * u_c(k-1)`` is applied (``u_c(-1) = 0``: one sample of
      computation delay);
    * ``y(k)`` is read and ``e(k) = setpoint - y(k)``;
    * for ``k < enable_at`` the controller is off (``u_c(k) = 0``; the error still enters the
      averaging window), else ``u_c(k) = kp * ebar(k) + ki * sample_time * sum(ebar)`` where
      ``ebar`` is the mean of the last ``average`` errors.

    Attributes
    ----------
    setpoint : float
        Desired output ``y_d`` (V).
    kp : float
        Proportional gain (controller units per output volt).
    ki : float
        Integral gain (controller units per output volt-second).
    sample_time : float
        ``T_s`` (s); must equal the plant's sample time.
    average : int
        Errors averaged at the controller's input (1: none; the thesis's experiments use
        25 ms, i.e. 25 samples at 1 ms).
    enable_at : int
        First sample (index into the run) at which the controller acts.
    input_gain : float
        Model-input volts per controller unit.

    """

    setpoint: float
    kp: float = 1.5
    ki: float = 30.0
    sample_time: float = 1e-3
    average: int = 1
    enable_at: int = 0
    input_gain: float = 1.0

    def __post_init__(self) -> None:
        for name in ("setpoint", "kp", "ki", "input_gain"):
            v = getattr(self, name)
            if not math.isfinite(float(v)):
                raise ValueError(f"PIConfig.{name}: must be finite, got {v!r}")
        if not (math.isfinite(self.sample_time) and self.sample_time > 0):
            raise ValueError(
                f"PIConfig.sample_time: must be positive (s), got {self.sample_time!r}"
            )
        if int(self.average) < 1:
            raise ValueError(f"PIConfig.average: must be >= 1 sample, got {self.average!r}")
        if int(self.enable_at) < 0:
            raise ValueError(f"PIConfig.enable_at: must be >= 0, got {self.enable_at!r}")

    def controller(self) -> _core.PIController:
        """Return a fresh step-by-step controller with these gains (for a loop in Python)."""
        return _core.PIController(self.kp, self.ki, self.sample_time, int(self.average))

    def core_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`preisach._core.closed_loop`."""
        return {
            "setpoint": float(self.setpoint),
            "kp": float(self.kp),
            "ki": float(self.ki),
            "sample_time": float(self.sample_time),
            "average": int(self.average),
            "enable_at": int(self.enable_at),
            "input_gain": float(self.input_gain),
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        return asdict(self)


@runtime_checkable
class Plant(Protocol):
    """What the regulation experiments need from the thing whose output they regulate.

    A plant keeps its state between calls (as a rig does): ``run_open_loop`` and
    ``run_closed_loop`` continue from wherever the previous call left it.
    """

    @property
    def sample_time(self) -> float:
        """Sampling period of every run (s)."""
        ...

    @property
    def input_range(self) -> tuple[float, float]:
        """``(u_min, u_max)``: the admissible input (V); ``u_max`` is the saturation ``u_hat``."""
        ...

    def reset(self, state: State | None = None) -> None:
        """Put the plant in a start state (a model: ``state``, default anhysteretic).

        A rig may not be able to set an arbitrary ``state``; it may raise ``ValueError`` for
        one and must accept ``None``.  Every experiment begins with a waveform that saturates
        the input, so the start state does not matter to the results.
        """
        ...

    def run_open_loop(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply the input samples ``u`` (V), one per ``sample_time``; return the outputs (V)."""
        ...

    def run_closed_loop(
        self, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop of ``controller`` over the open-loop input ``u_open`` (V).

        Returns
        -------
        u : ndarray
            Applied input (V).
        y : ndarray
            Output (V).
        uc : ndarray
            Controller output (controller units).

        """
        ...

    def snapshot(self) -> State | None:
        """Return the current state if the plant can be :meth:`reset` to it exactly, else None."""
        ...


class SimulatedPlant:
    """What the plants simulated in C++ share (:class:`ModelPlant`, :class:`RatePlant`).

    A subclass names its model class (``_model_type``), makes its step-by-step simulator
    (:meth:`_new_simulator`) and runs its PI loop (:meth:`_closed_loop`); the checks, the
    open-loop runs and the controller checks live here, once.

    Parameters
    ----------
    model
        The model (input V, output V), an instance of the subclass's ``_model_type``.
    sample_time : float, default 1e-3
        Sampling period (s).
    threads : int, default 0
        Worker threads of the batched runs; 0 uses every core.
    out_of_range : {"clamp", "raise"}, optional
        Policy for inputs outside the model range; default the model's.

    """

    _model_type: ClassVar[type[Any]] = object
    model: Any
    _sim: Any

    def __init__(
        self,
        model: Any,
        sample_time: float = 1e-3,
        *,
        threads: int = 0,
        out_of_range: str | None = None,
    ) -> None:
        if not isinstance(model, self._model_type):
            raise TypeError(
                f"model: expected a {self._model_type.__name__}, got {type(model).__name__}"
            )
        if not (math.isfinite(sample_time) and sample_time > 0):
            raise ValueError(f"sample_time: must be positive (s), got {sample_time!r}")
        if threads < 0:
            raise ValueError(f"threads: must be >= 0, got {threads}")
        self.model = model
        self._ts = float(sample_time)
        self.threads = int(threads)
        self.out_of_range = model.out_of_range if out_of_range is None else out_of_range
        if self.out_of_range not in ("clamp", "raise"):
            raise ValueError(
                f"out_of_range: expected 'clamp' or 'raise', got {self.out_of_range!r}"
            )
        self._sim = self._new_simulator()

    def _new_simulator(self) -> Any:
        raise NotImplementedError

    def _closed_loop(
        self, u_open: NDArray[np.float64], controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.model!r}, sample_time={self._ts:g})"

    @property
    def sample_time(self) -> float:
        """Sampling period (s)."""
        return self._ts

    @property
    def input_range(self) -> tuple[float, float]:
        """``(u_min, u_max)`` of the model (V)."""
        return (float(self.model.u_min), float(self.model.u_max))

    @property
    def output(self) -> float:
        """Current output (V)."""
        return float(self._sim.output)

    def slopes(self) -> Slopes:
        """One-sided dy/du (V/V) at the current state (Appendix A)."""
        return Slopes(*self._sim.slopes())

    def run_open_loop(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply ``u`` (V) from the current state; return the outputs (V)."""
        uu = np.ascontiguousarray(u, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u: expected a 1-D array of input samples, got shape {uu.shape}")
        return np.asarray(self._sim.run(uu, self.out_of_range))

    def _check(self, controller: PIConfig) -> None:
        if not isinstance(controller, PIConfig):
            raise TypeError(f"controller: expected a PIConfig, got {type(controller).__name__}")
        if not math.isclose(controller.sample_time, self._ts, rel_tol=1e-9):
            raise ValueError(
                f"controller.sample_time = {controller.sample_time:g} s differs from the "
                f"plant's sample_time {self._ts:g} s"
            )

    def run_closed_loop(
        self, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop (in C++, GIL released) from the current state; see :class:`PIConfig`."""
        self._check(controller)
        uu = np.ascontiguousarray(u_open, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u_open: expected a 1-D array, got shape {uu.shape}")
        return self._closed_loop(uu, controller)

    def _rows(self, u_open: ArrayLike, controller: PIConfig) -> NDArray[np.float64]:
        """Check a batch of loop runs: the controller and a 2-D ``u_open`` (runs, samples)."""
        self._check(controller)
        uu = np.ascontiguousarray(u_open, dtype=float)
        if uu.ndim != 2:
            raise ValueError(f"u_open: expected a 2-D array (runs, samples), got shape {uu.shape}")
        return uu


class ModelPlant(SimulatedPlant):
    """A Preisach model as a plant: every run is simulated in C++.

    Besides the :class:`Plant` protocol it offers batched runs from one snapshot on all cores
    (:meth:`run_open_loop_batch`, :meth:`run_closed_loop_batch`), which the sweeps use.

    Parameters
    ----------
    model : PreisachModel
        The model (input V, output V).
    sample_time : float, default 1e-3
        Sampling period (s).
    threads : int, default 0
        Worker threads of the batched runs; 0 uses every core.
    out_of_range : {"clamp", "raise"}, optional
        Policy for inputs outside the model range; default the model's.

    """

    _model_type = PreisachModel
    model: PreisachModel
    _sim: _core.Simulator

    def _new_simulator(self) -> _core.Simulator:
        return self.model.simulator(self.model.anhysteretic_state())

    def __getstate__(self) -> dict[str, Any]:
        # The C++ simulator does not pickle; its exact state does (studies ship plants to
        # worker processes and Dask workers).
        d = self.__dict__.copy()
        d["_sim"] = self._sim.state
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        state = d.pop("_sim")
        self.__dict__.update(d)
        self._sim = self.model.simulator(state)

    def reset(self, state: State | None = None) -> None:
        """Set the model's state (default: the anhysteretic state)."""
        self._sim.reset(self.model.anhysteretic_state() if state is None else state)

    def snapshot(self) -> State:
        """Return the current state (exact)."""
        return self._sim.state

    def _closed_loop(
        self, u_open: NDArray[np.float64], controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        return _core.closed_loop(
            self._sim, u_open, out_of_range=self.out_of_range, **controller.core_kwargs()
        )

    def run_open_loop_batch(self, state: State, u: ArrayLike) -> NDArray[np.float64]:
        """Every row of ``u`` (V) from ``state`` on all cores; returns the outputs (V)."""
        y, _ = self.model.simulate_batch(
            u, state, threads=self.threads, out_of_range=self.out_of_range
        )
        return y

    def run_closed_loop_batch(
        self, state: State, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop for every row of ``u_open`` (V) from ``state``, on all cores."""
        u, y, uc, _ = _core.closed_loop_batch(
            self.model.table,
            [state],
            self._rows(u_open, controller),
            out_of_range=self.out_of_range,
            threads=self.threads,
            **controller.core_kwargs(),
        )
        return u, y, uc


def ss15_plants(sample_time: float | None = None, *, levels: int = 201) -> dict[float, ModelPlant]:
    """Make the three built-in SS15 models plants, keyed by identification frequency (Hz).

    Parameters
    ----------
    sample_time : float, optional
        Sampling period (s) of all three; default :func:`thesis_sample_time` (1 ms for 1 and
        2 Hz, 0.5 ms for 4 Hz).
    levels : int
        Table levels of the built-in models.

    """
    out: dict[float, ModelPlant] = {}
    for name, f in BUILTIN_MODELS.items():
        ts = thesis_sample_time(f) if sample_time is None else sample_time
        out[float(f)] = ModelPlant(PreisachModel.builtin(name, levels), ts)
    return out
