"""Timing and noise of the regulation experiments (thesis §4.2 and §5.1).

Times are in seconds **after t_1**, the instant the initial state is reached (the end of the
initialisation waveform).  A trial's test segment is sampled at ``t_1 + k T_s``, ``k = 0, 1,
...``; averaging windows ``(a, b)`` select the samples with ``a <= t < b``.

Open-loop drift test (§4.2 steps 4-6): hold the offset for 2 s, then add 8 s of noise scaled by
``K_n``; the differential drift is ``ybar(8, 10) - ybar(0, 2)``.

Closed-loop test (§5.1 steps 2-5): hold the offset, PI controller on at 1 s, noise from 2 s to
10 s, end at 12 s; the control effort is ``n_c = ||u_cn - ubar_c||_2`` (Eq 5.3) with ``u_cn``
the controller output during the noise, ``(2, 10)``, and ``ubar_c`` its mean over
``(1.5, 2)`` - the controller's steady offset just before the noise, so that only the effort
spent against the noise counts.  ``n_c`` is the 2-norm of the *sample* vector (Matlab's
``norm``), so it grows with the sampling rate; ``n_c * sqrt(T_s)`` (``nc_l2``, the L2 norm of
the signal in V*s^0.5) compares runs at different ``T_s``.

Noise: :class:`preisach.noise.NoiseSpec` (zero-mean uniform draws every 0.015 s, 4th-order
Butterworth at 15 Hz, peak 0.5 V), generated at the plant's sample time from an integer seed,
multiplied by ``K_n`` and by ``input_gain`` (DAQ volts to model-input volts, see
:mod:`preisach.experiments.plant`).  The same seed gives the same noise for every initial
state and frequency at one sample time, so comparisons between states are paired.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..noise import NoiseSpec
from .plant import SS15_INPUT_GAIN, PIConfig

__all__ = [
    "THESIS_GAINS",
    "ClosedLoopProtocol",
    "DriftProtocol",
    "ExperimentResult",
    "control_effort",
    "differential_drift",
    "trial_noise",
    "window_mean",
]

#: Noise gains of the thesis, ``K_n = 0.8 i`` for ``i = 1 .. 7``.
THESIS_GAINS: tuple[float, ...] = tuple(round(0.8 * i, 10) for i in range(1, 8))


def _index(t: float, ts: float) -> int:
    return int(round(t / ts))


def _window(name: str, w: tuple[float, float]) -> tuple[float, float]:
    a, b = float(w[0]), float(w[1])
    if not (math.isfinite(a) and math.isfinite(b) and 0.0 <= a < b):
        raise ValueError(f"{name}: expected a time window (a, b) with 0 <= a < b (s), got {w!r}")
    return (a, b)


def window_mean(y: NDArray[np.float64], sample_time: float, window: tuple[float, float]) -> float:
    """Mean of ``y`` over the samples with ``a <= t < b`` (``t = k * sample_time``, s)."""
    a, b = _window("window", window)
    i0, i1 = _index(a, sample_time), _index(b, sample_time)
    if i1 > len(y) or i1 <= i0:
        raise ValueError(
            f"window {window!r} s needs samples {i0}..{i1 - 1}, but the signal has "
            f"{len(y)} samples at {sample_time:g} s"
        )
    return float(np.mean(y[i0:i1]))


def differential_drift(
    y: NDArray[np.float64],
    sample_time: float,
    before: tuple[float, float] = (0.0, 2.0),
    after: tuple[float, float] = (8.0, 10.0),
) -> tuple[float, float, float]:
    """Differential output drift ``ybar(after) - ybar(before)`` (V) of §4.3.

    Parameters
    ----------
    y : ndarray
        Output (V) sampled from ``t_1``.
    sample_time : float
        Sampling period (s).
    before, after : (float, float)
        Averaging windows (s after ``t_1``); thesis: ``(0, 2)`` and ``(8, 10)``.

    Returns
    -------
    (drift, ybar_before, ybar_after) : tuple of float

    """
    yb = window_mean(y, sample_time, before)
    ya = window_mean(y, sample_time, after)
    return ya - yb, yb, ya


def control_effort(
    uc: NDArray[np.float64],
    sample_time: float,
    effort: tuple[float, float] = (2.0, 10.0),
    baseline: tuple[float, float] = (1.5, 2.0),
) -> tuple[float, float]:
    """Control effort ``n_c = ||u_cn - ubar_c||_2`` of Eq 5.3.

    Parameters
    ----------
    uc : ndarray
        Controller output (controller units, e.g. DAQ volts) sampled from ``t_1``.
    sample_time : float
        Sampling period (s).
    effort : (float, float)
        Window of ``u_cn`` (s after ``t_1``); thesis ``(2, 10)``, the noise.
    baseline : (float, float)
        Window whose mean is ``ubar_c`` (s after ``t_1``); thesis ``(1.5, 2)``.

    Returns
    -------
    (n_c, ubar_c) : tuple of float
        The 2-norm of the sample vector (controller units) and the baseline.

    """
    a, b = _window("effort", effort)
    ubar = window_mean(uc, sample_time, baseline)
    i0, i1 = _index(a, sample_time), _index(b, sample_time)
    if i1 > len(uc):
        raise ValueError(f"effort window {effort!r} s needs {i1} samples, got {len(uc)}")
    # pairwise summation, not BLAS: the same bits whatever the thread count (a study run on
    # Dask workers equals the serial run), and no BLAS threads spinning against the C++ loops
    d = uc[i0:i1] - ubar
    return float(np.sqrt(np.sum(d * d))), ubar


def _add_noise(
    rows: NDArray[np.float64],
    protocol: DriftProtocol | ClosedLoopProtocol,
    gains: list[float],
    seeds: list[int],
    sample_time: float,
    window: tuple[int, int],
    duration: float,
) -> None:
    """Add each (gain, seed)'s noise to its row of input samples (V), on ``window``.

    ``duration`` s of the seed's :func:`trial_noise`, scaled by ``input_gain * gain``, from
    sample ``window[0]`` on, cut at ``window[1]``.
    """
    start, stop = window
    for r, (g, s) in enumerate(zip(gains, seeds)):
        eta = trial_noise(protocol.noise, sample_time, duration, s)
        m = min(len(eta), stop - start)
        rows[r, start : start + m] += protocol.input_gain * g * eta[:m]


@lru_cache(maxsize=256)
def _cached_noise(spec: NoiseSpec, duration: float, seed: int) -> NDArray[np.float64]:
    x = spec.generate(duration, seed=seed)
    x.setflags(write=False)
    return x


def trial_noise(
    spec: NoiseSpec, sample_time: float, duration: float, seed: int
) -> NDArray[np.float64]:
    """Unit-gain noise of one trial (the spec's volts, peak ``spec.amplitude``), cached.

    Generated at ``sample_time`` (the spec's own sample time is replaced) from the integer
    ``seed``; read-only.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative int, got {seed!r}")
    return _cached_noise(replace(spec, sample_time=float(sample_time)), float(duration), int(seed))


def _check_common(obj: Any) -> None:
    if not (math.isfinite(obj.input_gain) and obj.input_gain > 0):
        raise ValueError(f"input_gain: must be positive (V per V), got {obj.input_gain!r}")
    if not isinstance(obj.noise, NoiseSpec):
        raise TypeError(f"noise: expected a NoiseSpec, got {type(obj.noise).__name__}")


@dataclass
class ExperimentResult:
    """What every regulation experiment's result has (base of the drift and closed-loop results).

    Attributes
    ----------
    kind : str
        Initial state, ``"n"``, ``"a"`` or ``"d"``.
    frequency : float
        Initialisation frequency (Hz).
    gain : float
        Noise gain ``K_n``.
    seed : int
        Noise seed.
    sample_time : float
        Sampling period (s).
    offset : float
        Input held from ``t_1`` (V).

    """

    kind: str
    frequency: float
    gain: float
    seed: int
    sample_time: float
    offset: float

    #: Fields holding traces (arrays from ``t_1``), left out of :meth:`to_dict`.
    TRACES = ("input", "output", "control")

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times after ``t_1`` (s)."""
        output = getattr(self, "output", None)
        if output is None:
            raise ValueError("this result kept no trace (time, input, output)")
        return np.asarray(np.arange(len(output)) * self.sample_time, dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """Return the scalar results (no trace, no sample time) as a dict."""
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in self.TRACES and f.name != "sample_time"
        }


@dataclass(frozen=True)
class DriftProtocol:
    """Timing of the open-loop drift test (§4.2 steps 4-6).

    Attributes
    ----------
    hold : float
        Offset held alone after ``t_1`` (s); thesis 2.
    noise_duration : float
        Noise injected after the hold (s); thesis 8.
    before, after : (float, float)
        Windows of the differential drift (s after ``t_1``); thesis ``(0, 2)``, ``(8, 10)``.
    noise : NoiseSpec
        Unit-gain noise (peak 0.5 V at the DAQ connector in the thesis).
    input_gain : float
        Model-input volts per noise volt (default the SS15 amplifier, 14.12).

    """

    hold: float = 2.0
    noise_duration: float = 8.0
    before: tuple[float, float] = (0.0, 2.0)
    after: tuple[float, float] = (8.0, 10.0)
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    input_gain: float = SS15_INPUT_GAIN

    def __post_init__(self) -> None:
        if not (self.hold >= 0 and self.noise_duration > 0):
            raise ValueError(
                f"hold >= 0 and noise_duration > 0 (s) needed, got {self.hold!r}, "
                f"{self.noise_duration!r}"
            )
        end = self.hold + self.noise_duration
        for name in ("before", "after"):
            a, b = _window(name, getattr(self, name))
            if b > end + 1e-12:
                raise ValueError(f"{name} = {(a, b)!r} s ends after the test ({end:g} s)")
            object.__setattr__(self, name, (a, b))
        _check_common(self)

    @property
    def duration(self) -> float:
        """Length of the test segment after ``t_1`` (s)."""
        return self.hold + self.noise_duration

    def open_inputs(
        self, offset: float, gains: list[float], seeds: list[int], sample_time: float
    ) -> NDArray[np.float64]:
        """Input rows (V) of the test segment for every (gain, seed) pair, in that order."""
        ts = sample_time
        n = _index(self.duration, ts)
        rows = np.full((len(gains), n), float(offset))
        _add_noise(rows, self, gains, seeds, ts, (_index(self.hold, ts), n), self.noise_duration)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        d = asdict(self)
        d["noise"] = self.noise.to_dict()
        return d


@dataclass(frozen=True)
class ClosedLoopProtocol:
    """Timing, controller and noise of the closed-loop test (§5.1).

    Attributes
    ----------
    kp, ki : float
        PI gains of Eq 5.2 (DAQ volts per output volt, and per volt-second); thesis 1.5, 30.
    average_window : float
        Error averaging at the controller input (s): 0 for the thesis's simulations, 0.025 for
        its experiments.
    controller_on : float
        Controller enabled (s after ``t_1``); thesis 1.
    noise_start, noise_end : float
        Noise injected (s after ``t_1``); thesis 2 and 10.
    end : float
        End of the trial (s after ``t_1``); thesis 12.
    effort, baseline : (float, float)
        Windows of ``u_cn`` and ``ubar_c`` in Eq 5.3; thesis ``(2, 10)`` and ``(1.5, 2)``.
    noise : NoiseSpec
        Unit-gain noise.
    input_gain : float
        Model-input volts per DAQ volt (noise and controller output).

    """

    kp: float = 1.5
    ki: float = 30.0
    average_window: float = 0.0
    controller_on: float = 1.0
    noise_start: float = 2.0
    noise_end: float = 10.0
    end: float = 12.0
    effort: tuple[float, float] = (2.0, 10.0)
    baseline: tuple[float, float] = (1.5, 2.0)
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    input_gain: float = SS15_INPUT_GAIN

    def __post_init__(self) -> None:
        if not (
            0 <= self.controller_on <= self.end
            and 0 <= self.noise_start < self.noise_end <= self.end
        ):
            raise ValueError(
                "closed-loop timing: need 0 <= controller_on <= end and "
                "0 <= noise_start < noise_end <= end (s)"
            )
        if not (math.isfinite(self.average_window) and self.average_window >= 0):
            raise ValueError(f"average_window: must be >= 0 (s), got {self.average_window!r}")
        for name in ("effort", "baseline"):
            a, b = _window(name, getattr(self, name))
            if b > self.end + 1e-12:
                raise ValueError(f"{name} = {(a, b)!r} s ends after the trial ({self.end:g} s)")
            object.__setattr__(self, name, (a, b))
        _check_common(self)

    @property
    def duration(self) -> float:
        """Length of the test segment after ``t_1`` (s)."""
        return self.end

    def pi_config(self, setpoint: float, sample_time: float) -> PIConfig:
        """Return the :class:`PIConfig` of this protocol at a sample time."""
        return PIConfig(
            setpoint=setpoint,
            kp=self.kp,
            ki=self.ki,
            sample_time=sample_time,
            average=max(1, _index(self.average_window, sample_time)),
            enable_at=_index(self.controller_on, sample_time),
            input_gain=self.input_gain,
        )

    def open_inputs(
        self, offset: float, gains: list[float], seeds: list[int], sample_time: float
    ) -> NDArray[np.float64]:
        """Open-loop part of the input (V) for every (gain, seed) pair: offset plus noise."""
        ts = sample_time
        rows = np.full((len(gains), _index(self.end, ts)), float(offset))
        window = (_index(self.noise_start, ts), _index(self.noise_end, ts))
        _add_noise(rows, self, gains, seeds, ts, window, self.noise_end - self.noise_start)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        d = asdict(self)
        d["noise"] = self.noise.to_dict()
        return d
