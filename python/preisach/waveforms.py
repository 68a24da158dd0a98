"""Test inputs of the thesis's chapter 3: FOD sweep (Fig 3.17), wiping-out (3.6), CML (3.13).

Every generator returns an :class:`InputSignal` (time in seconds, input in volts) that unpacks
like a tuple, ``t, u = fod_sweep()``, and can be simulated or played on a device as it is.

The thesis describes these inputs in words and figures only; the figures are not in its text,
so the choices below are ours and are all parameters:

* **Legs.**  Each input is a sequence of target values joined by *legs*.  A leg lasts half a
  period ``T / 2 = 1 / (2 f)`` whatever its amplitude (the thesis plots every test against
  ``T``), and is a half cosine (``shape="cosine"``, zero slope at both ends, like a sinusoid
  between its extrema) or a straight ramp (``shape="triangle"``).  Leg ends fall on samples, so
  every turning value is attained exactly.
* **Start.**  The tests start at negative saturation ``u_min`` (after the thesis's
  initialisation the input "goes to negative saturation" first).  ``start=x`` prepends a leg
  from ``x`` to ``u_min``; :func:`decaying_sine` and :func:`concatenate` rebuild the full thesis
  sequence (initialisation for 12 s, then the test from ``t = 12`` s).
* **FOD sweep** (Fig 3.17, section 3.3.1): for every level ``alpha_i`` above ``u_min`` (the 21
  levels ``-100 + 10 i`` V by default), a rise from ``u_min`` to ``alpha_i`` and a fall back to
  ``u_min``, one period per curve; the thesis's example curve is ``alpha_1 = 100`` V, so the
  curves run from the highest ``alpha`` down (``order="descending"``).
* **Wiping-out test** (Fig 3.6, section 3.2.1): from ``u_min`` a rise to the first peak (the 1st
  ascending branch), then segment A - falls to the trough and rises to the lower peaks (the
  2nd and 3rd ascending branches), a last fall to the trough - then the rise to the first peak
  again (the 4th ascending branch, whose peak starts segment B), and segment B repeating A.
  The defaults ``peaks = (100, 72, 44)`` V and ``trough = -40`` V reproduce the reversal
  levels the thesis reads off Fig 3.10 (98.85, 70.69, 42.48 V measured: 100 V and 80 % and
  60 % of the 140 V span above the -40 V trough, scaled by the amplifier's 98.85/100) and the
  -40 V start of the compared branches.
* **Congruent minor loop (CML) test** (Fig 3.13, section 3.2.2): two minor loops between the same
  input extrema ``loop = (low, high)`` with different histories.  From ``u_min`` the input
  rises to ``high``, falls to ``low`` and rises back through ``high`` (loop A) on to ``peak``,
  the peak that "shifts the second minor loop upwards"; then it falls to ``low``, rises to
  ``high`` and falls to ``low`` (loop B).  The thesis does not give the loop levels; the
  defaults ``loop = (0, 50)`` V, ``peak = 100`` V give a clearly shifted pair.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "InputSignal",
    "cml_input",
    "concatenate",
    "decaying_sine",
    "fod_sweep",
    "legs",
    "wiping_out_input",
]

_SHAPES = ("cosine", "triangle")


@dataclass
class InputSignal:
    """A sampled test input.

    Unpacks like a tuple: ``t, u = signal``.

    Attributes
    ----------
    t : ndarray
        Sample times (s), ``t[k] = k * sample_time``.
    u : ndarray
        Input (V).
    sample_time : float
        Sampling period (s).
    name : str
        Which test (``"fod_sweep"``, ``"wiping_out"``, ``"cml"``, ...).
    params : dict
        The generator's parameters (JSON-friendly).
    turns : ndarray of int
        Sample indices of the leg ends (turning points and the end of the signal).
    marks : dict of str to ndarray of int
        Named sample indices, e.g. ``"alpha"`` (the turning points of the FOD curves) or
        ``"segment_a"``/``"segment_b"`` (first and last sample of a test segment).

    """

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    sample_time: float
    name: str
    params: dict[str, Any] = field(default_factory=dict)
    turns: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    marks: dict[str, NDArray[np.int64]] = field(default_factory=dict)

    def __iter__(self) -> Iterator[NDArray[np.float64]]:
        yield self.t
        yield self.u

    def __len__(self) -> int:
        return int(self.u.size)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` (s)."""
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly description (parameters and sizes, not samples)."""
        return {
            "name": self.name,
            "params": dict(self.params),
            "samples": len(self),
            "sample_time": self.sample_time,
            "duration": self.duration,
        }


# ------------------------------------------------------------------------------------------
# building blocks
# ------------------------------------------------------------------------------------------
def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: must be a positive finite number, got {value!r}")
    return v


def _finite(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return v


def legs(
    points: ArrayLike,
    durations: ArrayLike | float,
    *,
    sample_time: float = 1e-3,
    shape: str = "cosine",
    name: str = "legs",
) -> InputSignal:
    """Join target values by legs: the generator behind every test input of this module.

    Parameters
    ----------
    points : array_like, shape (k + 1,)
        Input values (V) at the leg ends; ``points[0]`` is the first sample.
    durations : float or array_like, shape (k,)
        Duration of each leg (s), or one duration for all.  Each leg end is put on the nearest
        sample (at least one sample per leg).
    sample_time : float
        Sampling period (s).
    shape : {"cosine", "triangle"}
        Half cosine (zero slope at the ends) or straight ramp.
    name : str
        Stored in the result.

    Returns
    -------
    InputSignal
        ``turns`` holds the sample index of every leg end.

    """
    ts = _positive("sample_time", sample_time)
    if shape not in _SHAPES:
        raise ValueError(f"shape: expected one of {_SHAPES}, got {shape!r}")
    p = np.asarray(points, dtype=float)
    if p.ndim != 1 or p.size < 2:
        raise ValueError("points: need a 1-D sequence of at least 2 input values (V)")
    if not np.all(np.isfinite(p)):
        raise ValueError("points: every input value must be finite")
    d = np.broadcast_to(np.asarray(durations, dtype=float), (p.size - 1,)).copy()
    if not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ValueError("durations: every leg duration must be positive and finite (s)")
    ends = np.round(np.cumsum(d) / ts).astype(np.int64)
    ends = np.maximum(ends, np.arange(1, p.size, dtype=np.int64))
    ends = np.maximum.accumulate(ends)
    for k in range(1, ends.size):  # at least one sample per leg
        if ends[k] <= ends[k - 1]:
            ends[k] = ends[k - 1] + 1
    n = int(ends[-1]) + 1
    u = np.empty(n)
    u[0] = p[0]
    start = 0
    for k in range(p.size - 1):
        stop = int(ends[k])
        tau = (np.arange(start + 1, stop + 1) - start) / (stop - start)
        if shape == "cosine":
            tau = 0.5 * (1.0 - np.cos(np.pi * tau))
        u[start + 1 : stop + 1] = p[k] + (p[k + 1] - p[k]) * tau
        u[stop] = p[k + 1]  # exact turning value
        start = stop
    turns = np.concatenate(([0], ends)).astype(np.int64)
    return InputSignal(
        (np.arange(n) * ts).astype(np.float64),
        u,
        ts,
        name,
        {"points": p.tolist(), "shape": shape, "sample_time": ts},
        turns,
    )


def _with_start(points: list[float], start: float | None, u_min: float) -> list[float]:
    if start is None or float(start) == u_min:
        return points
    return [_finite("start", start), *points]


def _test_signal(
    points: list[float],
    frequency: float,
    sample_time: float,
    shape: str,
    name: str,
    params: dict[str, Any],
) -> InputSignal:
    f = _positive("frequency", frequency)
    sig = legs(points, 0.5 / f, sample_time=sample_time, shape=shape, name=name)
    sig.params = {**params, "frequency": f, "shape": shape, "sample_time": sig.sample_time}
    return sig


# ------------------------------------------------------------------------------------------
# the thesis's test inputs
# ------------------------------------------------------------------------------------------
def fod_sweep(
    levels: ArrayLike | int = 21,
    *,
    u_min: float = -100.0,
    u_max: float = 100.0,
    frequency: float = 1.0,
    sample_time: float = 1e-3,
    shape: str = "cosine",
    order: str = "descending",
    start: float | None = None,
) -> InputSignal:
    """Identification input of Fig 3.17: one first-order descending (FOD) curve per level.

    For every level ``alpha`` above ``u_min``: rise from ``u_min`` to ``alpha`` in ``T / 2``,
    fall back to ``u_min`` in ``T / 2`` (``T = 1 / frequency``).  The falling input passes every
    level ``beta <= alpha``, so the FOD finder reads ``y(alpha, beta)`` on the whole grid.

    Parameters
    ----------
    levels : int or array_like
        Number of equally spaced levels on ``[u_min, u_max]`` (default 21: the thesis's
        ``-100 + 10 i`` V) or the levels themselves (V, increasing; the first is taken as
        ``u_min``).
    u_min, u_max : float
        Input range (V) when ``levels`` is a number.
    frequency : float
        ``f`` (Hz): one FOD curve per period.
    sample_time : float
        Sampling period (s); the thesis samples at 1 kHz.
    shape : {"cosine", "triangle"}
        Leg shape (see the module docstring).
    order : {"descending", "ascending"}
        Curves from the highest ``alpha`` down (the thesis's ``alpha_1 = 100`` V first) or up.
    start : float, optional
        Input (V) at ``t = 0`` when not ``u_min``: a first leg goes from it to ``u_min``.

    Returns
    -------
    InputSignal
        ``marks["alpha"]`` holds the sample index of each curve's turning point.

    """
    if np.ndim(levels) == 0:
        k = int(np.asarray(levels))
        if k < 2:
            raise ValueError(f"levels: need at least 2 levels, got {k}")
        lo, hi = _finite("u_min", u_min), _finite("u_max", u_max)
        if not hi > lo:
            raise ValueError(f"u_max ({hi}) must exceed u_min ({lo})")
        lv = np.linspace(lo, hi, k)
    else:
        lv = np.asarray(levels, dtype=float)
        if lv.ndim != 1 or lv.size < 2 or not np.all(np.isfinite(lv)) or np.any(np.diff(lv) <= 0):
            raise ValueError(
                "levels: need a finite, strictly increasing 1-D array of >= 2 levels (V)"
            )
    if order not in ("descending", "ascending"):
        raise ValueError(f"order: expected 'descending' or 'ascending', got {order!r}")
    low = float(lv[0])
    alphas = lv[1:][::-1] if order == "descending" else lv[1:]
    pts: list[float] = [low]
    for a in alphas:
        pts += [float(a), low]
    pts = _with_start(pts, start, low)
    sig = _test_signal(
        pts,
        frequency,
        sample_time,
        shape,
        "fod_sweep",
        {"levels": lv.tolist(), "order": order, "start": start},
    )
    first = 1 if len(pts) == 2 * alphas.size + 1 else 2
    sig.marks["alpha"] = sig.turns[first::2][: alphas.size].copy()
    return sig


def wiping_out_input(
    frequency: float = 1.0,
    *,
    peaks: Sequence[float] = (100.0, 72.0, 44.0),
    trough: float = -40.0,
    u_min: float = -100.0,
    sample_time: float = 1e-3,
    shape: str = "cosine",
    start: float | None = None,
) -> InputSignal:
    """Wiping-out test input of Fig 3.6 (section 3.2.1).

    ``u_min -> peaks[0]`` (1st ascending branch), segment A: for each further peak
    ``-> trough -> peak`` (2nd, 3rd, ... ascending branch), ``-> trough``; then ``-> peaks[0]``
    (the ascending branch between the segments, whose peak wipes out A's memory) and segment
    B, a copy of A.  Every leg lasts ``T / 2``.

    Parameters
    ----------
    frequency : float
        ``f`` (Hz); the thesis uses 1, 2 and 4 Hz.
    peaks : sequence of float
        Decreasing peak inputs (V); ``peaks[0]`` starts both segments.
    trough : float
        Input (V) every fall of the segments goes to; below ``min(peaks)``, above ``u_min``.
    u_min : float
        Negative saturation (V), where the test starts.
    sample_time, shape, start
        As for :func:`fod_sweep`.

    Returns
    -------
    InputSignal
        ``marks["segment_a"]`` and ``marks["segment_b"]``: first and last sample of each
        segment (the first sample is the peak that starts it).

    """
    pk = [_finite("peaks", p) for p in peaks]
    lo, tr = _finite("u_min", u_min), _finite("trough", trough)
    if len(pk) < 2:
        raise ValueError("peaks: need at least two peaks (the first starts each segment)")
    if any(b >= a for a, b in zip(pk, pk[1:])):
        raise ValueError(f"peaks: must be strictly decreasing, got {list(pk)}")
    if not lo < tr < pk[-1]:
        raise ValueError(
            f"trough ({tr} V) must lie between u_min ({lo} V) and the lowest peak ({pk[-1]} V)"
        )
    seg: list[float] = []
    for p in pk[1:]:
        seg += [tr, p]
    seg.append(tr)
    pts = [lo, pk[0], *seg, pk[0], *seg]
    n_before = len(_with_start([lo], start, lo)) - 1
    pts = _with_start(pts, start, lo)
    sig = _test_signal(
        pts,
        frequency,
        sample_time,
        shape,
        "wiping_out",
        {"peaks": pk, "trough": tr, "u_min": lo, "start": start},
    )
    i_a = n_before + 1
    i_b = i_a + len(seg) + 1
    sig.marks["segment_a"] = np.array([sig.turns[i_a], sig.turns[i_a + len(seg)]], dtype=np.int64)
    sig.marks["segment_b"] = np.array([sig.turns[i_b], sig.turns[i_b + len(seg)]], dtype=np.int64)
    return sig


def cml_input(
    frequency: float = 1.0,
    *,
    loop: tuple[float, float] = (0.0, 50.0),
    peak: float = 100.0,
    u_min: float = -100.0,
    sample_time: float = 1e-3,
    shape: str = "cosine",
    start: float | None = None,
) -> InputSignal:
    """Congruent minor loop (CML) test input of Fig 3.13 (section 3.2.2).

    ``u_min -> high -> low -> peak`` (loop A: the fall from ``high`` to ``low`` and the rise
    back through ``high``), then ``-> low -> high -> low`` (loop B, shifted upwards by the
    larger peak before it).  Every leg lasts ``T / 2``.

    Parameters
    ----------
    frequency : float
        ``f`` (Hz).
    loop : (float, float)
        ``(low, high)`` input extrema (V) of both minor loops.
    peak : float
        The peak (V) between the loops, above ``high``.
    u_min : float
        Negative saturation (V), where the test starts.
    sample_time, shape, start
        As for :func:`fod_sweep`.

    Returns
    -------
    InputSignal
        ``marks["loop_a"]``: samples at ``high``, ``low`` (loop A closes when the rise after
        ``low`` passes ``high`` again); ``marks["loop_b"]``: samples at ``low``, ``high``, ``low``.

    """
    lo = _finite("u_min", u_min)
    low, high = (_finite("loop", v) for v in loop)
    pk = _finite("peak", peak)
    if not lo < low < high < pk:
        raise ValueError(
            f"need u_min < low < high < peak, got u_min = {lo}, loop = ({low}, "
            f"{high}), peak = {pk} (V)"
        )
    pts = [lo, high, low, pk, low, high, low]
    k0 = len(_with_start([lo], start, lo)) - 1
    pts = _with_start(pts, start, lo)
    sig = _test_signal(
        pts,
        frequency,
        sample_time,
        shape,
        "cml",
        {"loop": [low, high], "peak": pk, "u_min": lo, "start": start},
    )
    sig.marks["loop_a"] = sig.turns[k0 + 1 : k0 + 3].copy()
    sig.marks["loop_b"] = sig.turns[k0 + 4 : k0 + 7].copy()
    return sig


def decaying_sine(
    duration: float = 12.0,
    frequency: float = 1.0,
    amplitude: float = 100.0,
    *,
    offset: float = 0.0,
    sample_time: float = 1e-3,
) -> InputSignal:
    """Generate the thesis's initialisation: a sinusoid whose amplitude decays linearly to zero.

    ``u(t) = offset + amplitude (1 - t / duration) sin(2 pi f t)`` for ``0 <= t <= duration``,
    ending at ``offset``.  It approximates the anhysteretic state (``offset = 0``) before each
    test (section 3.2); the tests of Figs 3.6 and 3.13 start at ``t = 12`` s.

    Parameters
    ----------
    duration : float
        Length (s).
    frequency : float
        Frequency of the sinusoid (Hz).
    amplitude : float
        Initial amplitude (V).
    offset : float
        Centre and final value (V).
    sample_time : float
        Sampling period (s).

    """
    dur = _positive("duration", duration)
    f = _positive("frequency", frequency)
    ts = _positive("sample_time", sample_time)
    amp, off = _finite("amplitude", amplitude), _finite("offset", offset)
    n = int(round(dur / ts)) + 1
    t = (np.arange(n) * ts).astype(np.float64)
    u = off + amp * np.clip(1.0 - t / dur, 0.0, 1.0) * np.sin(2 * np.pi * f * t)
    u[-1] = off
    return InputSignal(
        t,
        u,
        ts,
        "decaying_sine",
        {"duration": dur, "frequency": f, "amplitude": amp, "offset": off, "sample_time": ts},
        np.array([0, n - 1], dtype=np.int64),
    )


def concatenate(*signals: InputSignal) -> InputSignal:
    """Play signals one after the other (same sample time); times continue.

    When a signal starts at the value the previous one ended on, the duplicate sample is
    dropped.  Turning points and marks are shifted to the joined sample indices; marks of
    the later signals win on equal names.
    """
    if not signals:
        raise ValueError("concatenate: need at least one signal")
    ts = signals[0].sample_time
    for s in signals[1:]:
        if not math.isclose(s.sample_time, ts, rel_tol=1e-9):
            raise ValueError(f"concatenate: sample times differ ({ts} s and {s.sample_time} s)")
    parts: list[NDArray[np.float64]] = []
    turns: list[NDArray[np.int64]] = []
    marks: dict[str, NDArray[np.int64]] = {}
    n = 0
    for s in signals:
        u = s.u
        shift = n
        if parts and u.size and u[0] == parts[-1][-1]:
            u = u[1:]
            shift = n - 1
        parts.append(u)
        turns.append(s.turns + shift)
        for k, v in s.marks.items():
            marks[k] = v + shift
        n += u.size
    uu = np.concatenate(parts)
    tt = np.unique(np.concatenate(turns))
    return InputSignal(
        (np.arange(uu.size) * ts).astype(np.float64),
        uu,
        ts,
        "+".join(s.name for s in signals),
        {"parts": [s.to_dict() for s in signals]},
        tt.astype(np.int64),
        marks,
    )
