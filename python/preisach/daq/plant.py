"""A DAQ device as a plant of the regulation experiments (:mod:`preisach.experiments`)."""

from __future__ import annotations

import itertools
import math
import os
import tempfile
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..model import PreisachModel, State
from ..recording import Recording
from .channel import SafetyLimits
from .controller import PIController, WaveformController
from .device import Device
from .runner import PathLike, TrialResult, run_trial

__all__ = ["DevicePlant"]


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

    Attributes
    ----------
    is_device : bool
        ``True``: the plant is a DAQ device (a real or virtual rig), so the experiments use the
        thesis's experimental landing windows on it (Table 4.1).

    """

    #: Marks a DAQ device for the experiments (they do not import this layer's classes).
    is_device: bool = True

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
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        if record_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="preisach-plant-")
            self.record_dir = self._tmp.name
        else:
            self.record_dir = os.fspath(record_dir)
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
