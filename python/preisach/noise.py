r"""Band-limited uniform input noise for open-loop drift tests (thesis §4.1-4.2).

The thesis injects a zero-mean, uniformly distributed random input noise :math:`\eta(t)` on top
of the regulated input, :math:`u(t) = \bar u_d + \eta(t)` (Problem 1, chapter 4).  It was
produced with Simulink's *Uniform Random Number* block, whose sample time had to be set to
0.015 s, followed by a low-pass filter with a 15 Hz cut-off chosen well below the 37.62 Hz
natural frequency of the bimorph; the amplitude was 0.5 V.  The thesis does not state the
filter's type or order, nor exactly how the amplitude was normalised, so this module fixes
those choices explicitly:

Generation pipeline (all at the simulation sample time ``sample_time``, default 1 ms)
    1. Draw i.i.d. values uniform on ``[-1, 1]`` (zero mean), one every ``hold_time``
       seconds (default 0.015 s), and hold each one (zero-order hold) until the next draw.
       Draw ``k`` is held on the samples whose time ``t = i * sample_time`` satisfies
       ``k * hold_time <= t < (k + 1) * hold_time``, so ``hold_time`` need not be a multiple
       of ``sample_time``.
    2. Low-pass filter the held sequence with a digital Butterworth filter of order ``order``
       (default 4) whose -3 dB frequency is ``cutoff`` (default 15 Hz), designed at the
       sampling rate ``1 / sample_time`` with :func:`scipy.signal.butter` as second-order
       sections and applied **causally** with :func:`scipy.signal.sosfilt` from a zero initial
       state, as an online Simulink filter would.  The filter therefore has a start-up
       transient (the output rises from 0 during roughly the first ``1 / cutoff`` seconds) and
       unit DC gain, so the output stays zero-mean.
    3. Scale the filtered sequence so that its largest absolute value equals ``amplitude``
       (V), i.e. :math:`\|\eta\|_\infty = \xi` exactly as in Problem 1 of chapter 4.

Amplitude convention.  The alternative reading of "amplitude 0.5 V" is the bound of the raw
uniform draws (the block's ``Minimum``/``Maximum`` = -0.5/0.5).  With that convention the
filtered peak is *not* the amplitude: a 4th-order Butterworth overshoots on the held steps, so
over tens of seconds the filtered peak is typically 1.1-1.2 times the raw bound, while its
standard deviation is about 0.38 times the raw bound.  We use the peak convention because it
is the quantity the regulation problem is stated in.  With the defaults the scaled sequence
has a standard deviation of roughly 0.33-0.37 times ``amplitude``.

Spectrum.  A Butterworth filter is -3 dB *at* the cut-off, so some power lies just above it:
with the defaults about 92 % of the power (Welch estimate) lies below 15 Hz and more than
99.9 % below 30 Hz, i.e. the main power component is below the cut-off as in thesis Fig. 4.4.
Raise ``order`` for a sharper split (order 8 gives about 96 % below 15 Hz).

Reproducibility.  ``seed`` may be ``None`` (fresh OS entropy), a non-negative ``int`` (same
int -> bit-identical sequence) or a :class:`numpy.random.Generator` (consumed and advanced).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Union

import numpy as np
from numpy.typing import NDArray
from scipy import signal

__all__ = ["NoiseSpec", "SeedLike", "uniform_filtered_noise"]

SeedLike = Union[int, np.random.Generator, None]
"""Accepted seeds: ``None``, a non-negative ``int`` or a :class:`numpy.random.Generator`."""

# Relative tolerance used when mapping sample instants to hold intervals, so that e.g.
# 15 * 1e-3 s is recognised as the start of the second 0.015 s hold interval.
_HOLD_EPS = 1e-9


def _check_positive_float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    number = float(value)
    if not math.isfinite(number) or number <= 0.0:
        raise ValueError(f"{name} must be a finite positive number, got {number!r}")
    return number


def _validate(
    amplitude: Any, sample_time: Any, hold_time: Any, cutoff: Any, order: Any
) -> tuple[float, float, float, float, int]:
    """Check the generator parameters and return them as floats / int."""
    if isinstance(amplitude, bool) or not isinstance(amplitude, numbers.Real):
        raise TypeError(f"amplitude must be a real number, got {type(amplitude).__name__}")
    amplitude = float(amplitude)
    if not math.isfinite(amplitude) or amplitude < 0.0:
        raise ValueError(f"amplitude must be finite and >= 0 (V), got {amplitude!r}")
    sample_time = _check_positive_float("sample_time", sample_time)
    hold_time = _check_positive_float("hold_time", hold_time)
    cutoff = _check_positive_float("cutoff", cutoff)
    if isinstance(order, bool) or not isinstance(order, numbers.Integral):
        raise TypeError(f"order must be an int, got {type(order).__name__}")
    order = int(order)
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    if hold_time < sample_time * (1.0 - _HOLD_EPS):
        raise ValueError(
            f"hold_time ({hold_time} s) must be >= sample_time ({sample_time} s): the noise "
            "cannot be drawn faster than it is sampled"
        )
    hold_nyquist = 0.5 / hold_time
    if cutoff >= hold_nyquist:
        raise ValueError(
            f"cutoff ({cutoff} Hz) must be below the Nyquist frequency of the hold rate, "
            f"0.5 / hold_time = {hold_nyquist:g} Hz"
        )
    # cutoff < 0.5/hold_time <= 0.5/sample_time, so the digital design is always valid.
    return amplitude, sample_time, hold_time, cutoff, order


def _make_rng(seed: SeedLike) -> np.random.Generator:
    if seed is None or isinstance(seed, np.random.Generator):
        return np.random.default_rng(seed)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise TypeError(
            f"seed must be None, a non-negative int or a numpy.random.Generator, "
            f"got {type(seed).__name__}"
        )
    if int(seed) < 0:
        raise ValueError(f"seed must be a non-negative int, got {int(seed)}")
    return np.random.default_rng(int(seed))


def _sample_count(duration: Any, sample_time: float) -> int:
    duration = _check_positive_float("duration", duration)
    n = int(round(duration / sample_time))
    if n < 1:
        raise ValueError(
            f"duration ({duration} s) is shorter than half a sample_time ({sample_time} s); "
            "no samples would be generated"
        )
    return n


def uniform_filtered_noise(
    duration: float,
    amplitude: float = 0.5,
    *,
    sample_time: float = 1e-3,
    hold_time: float = 0.015,
    cutoff: float = 15.0,
    order: int = 4,
    seed: SeedLike = None,
) -> NDArray[np.float64]:
    """Generate zero-mean, held, low-pass-filtered uniform noise (thesis §4.1).

    See the module docstring for the exact pipeline and conventions.

    Parameters
    ----------
    duration : float
        Length of the sequence (s).  The number of samples is
        ``round(duration / sample_time)``; sample ``i`` is at time ``i * sample_time``.
    amplitude : float, default 0.5
        Peak absolute value of the returned sequence (V): ``max(abs(x)) == amplitude``.
        ``0`` returns zeros.
    sample_time : float, default 1e-3
        Simulation sample time (s) at which the noise is returned and filtered.
    hold_time : float, default 0.015
        Interval (s) between successive uniform draws (zero-order hold); must be
        ``>= sample_time``.
    cutoff : float, default 15.0
        -3 dB frequency (Hz) of the Butterworth low-pass filter; must be below the
        Nyquist frequency of the hold rate, ``0.5 / hold_time`` (33.3 Hz by default).
    order : int, default 4
        Order of the Butterworth filter.
    seed : None, int or numpy.random.Generator, optional
        Randomness source.  The same ``int`` always gives the same sequence; a ``Generator``
        is advanced.

    Returns
    -------
    numpy.ndarray
        1-D float64 array of noise samples (V).

    Raises
    ------
    ValueError
        If a time, frequency or order is non-positive or non-finite, ``amplitude`` is
        negative, ``hold_time < sample_time``, ``cutoff >= 0.5 / hold_time``, or ``seed`` is
        a negative int.
    TypeError
        If an argument has the wrong type.

    Examples
    --------
    >>> eta = uniform_filtered_noise(10.0, 0.5, seed=1)
    >>> eta.shape, float(abs(eta).max())
    ((10000,), 0.5)

    """
    amplitude, sample_time, hold_time, cutoff, order = _validate(
        amplitude, sample_time, hold_time, cutoff, order
    )
    n = _sample_count(duration, sample_time)
    rng = _make_rng(seed)

    # Zero-order hold: sample i belongs to hold interval floor(i * sample_time / hold_time).
    hold_index = np.floor(np.arange(n) * (sample_time / hold_time) + _HOLD_EPS).astype(np.int64)
    draws = rng.uniform(-1.0, 1.0, size=int(hold_index[-1]) + 1)
    held = draws[hold_index]

    sos = signal.butter(order, cutoff, btype="lowpass", output="sos", fs=1.0 / sample_time)
    filtered = np.asarray(signal.sosfilt(sos, held), dtype=np.float64)

    i_peak = int(np.argmax(np.abs(filtered)))
    peak = abs(float(filtered[i_peak]))
    if amplitude == 0.0 or peak == 0.0:
        return np.zeros(n, dtype=np.float64)
    out = filtered * (amplitude / peak)
    # Make ``max(abs(out)) == amplitude`` hold exactly, not just to rounding.
    np.clip(out, -amplitude, amplitude, out=out)
    out[i_peak] = math.copysign(amplitude, filtered[i_peak])
    return out


@dataclass(frozen=True)
class NoiseSpec:
    """Parameters of :func:`uniform_filtered_noise`, validated once and reusable.

    Parameters
    ----------
    amplitude : float, default 0.5
        Peak absolute value of the noise (V).
    sample_time : float, default 1e-3
        Sample time of the generated sequence (s).
    hold_time : float, default 0.015
        Interval between uniform draws (s).
    cutoff : float, default 15.0
        -3 dB frequency of the Butterworth low-pass filter (Hz).
    order : int, default 4
        Butterworth filter order.

    Examples
    --------
    >>> spec = NoiseSpec(amplitude=0.5)
    >>> x = spec.generate(2.0, seed=3)
    >>> len(x)
    2000

    """

    amplitude: float = 0.5
    sample_time: float = 1e-3
    hold_time: float = 0.015
    cutoff: float = 15.0
    order: int = 4

    def __post_init__(self) -> None:
        amplitude, sample_time, hold_time, cutoff, order = _validate(
            self.amplitude, self.sample_time, self.hold_time, self.cutoff, self.order
        )
        object.__setattr__(self, "amplitude", amplitude)
        object.__setattr__(self, "sample_time", sample_time)
        object.__setattr__(self, "hold_time", hold_time)
        object.__setattr__(self, "cutoff", cutoff)
        object.__setattr__(self, "order", order)

    def generate(self, duration: float, seed: SeedLike = None) -> NDArray[np.float64]:
        """Generate ``duration`` seconds of noise (V) with these parameters.

        Parameters
        ----------
        duration : float
            Length of the sequence (s).
        seed : None, int or numpy.random.Generator, optional
            Randomness source, as in :func:`uniform_filtered_noise`.

        Returns
        -------
        numpy.ndarray
            1-D float64 array of ``round(duration / sample_time)`` samples (V).

        """
        return uniform_filtered_noise(
            duration,
            self.amplitude,
            sample_time=self.sample_time,
            hold_time=self.hold_time,
            cutoff=self.cutoff,
            order=self.order,
            seed=seed,
        )

    def to_dict(self) -> dict[str, Any]:
        """Return the parameters as a plain, JSON-serialisable ``dict``."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> NoiseSpec:
        """Build a spec from a mapping produced by :meth:`to_dict`.

        Raises
        ------
        ValueError
            If ``data`` has keys that are not fields of :class:`NoiseSpec`.

        """
        unknown = set(data) - {"amplitude", "sample_time", "hold_time", "cutoff", "order"}
        if unknown:
            raise ValueError(f"unknown NoiseSpec field(s): {sorted(unknown)}")
        return cls(**dict(data))
