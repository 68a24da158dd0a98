"""Inputs that drive a plant to an initial state: psi_n, psi_a, psi_d (thesis §4.2).

All three start by saturating the input, so the state they reach does not depend on where the
plant was before:

* **psi_n** (Eq 4.1/4.2): a sinusoid about ``l`` whose amplitude decays linearly to zero,
  starting at the saturation ``u_hat`` (for ``l >= 0``; ``-u_hat`` for ``l < 0``).  Its
  reversal points pair up on the line ``alpha + beta = 2 l``, so the boundary approximates the
  neutral state psi_n^l (Eq 2.17) with a staircase whose steps shrink to zero at the end.  The
  thesis does not state ``t_1 - t_0``; here it is ``cycles / f`` (default 10 cycles).
* **psi_a** (Eq 4.3, ``theta_a = -pi/2``): one period of ``u_hat sin`` starting at ``-u_hat``,
  then half a period rising from ``-u_hat`` to the offset ``u_bar`` - a point on the ascending
  major branch.
* **psi_d** (Eq 4.4, ``theta_d = +pi/2``): one period starting at ``+u_hat``, then half a period
  falling from ``+u_hat`` to ``u_bar`` - the descending major branch.  (Eq 4.4 as printed
  repeats the offset and amplitude of Eq 4.3, which would jump from ``u_hat`` to ``u_bar`` and
  end at ``-u_hat``; we use the continuous fall ``(u_bar + u_hat)/2 + (u_hat - u_bar)/2
  sin(...)`` that the text describes.)

In the thesis ``u_hat = 7`` V at the DAQ connector, about 99 V of amplifier output; here the
waveforms are in model-input volts and ``u_hat`` defaults to the plant's saturation
(``input_range``).  Asymmetric ranges are handled by starting psi_n on the side whose mirror
image about ``l`` stays in range.

:func:`drive_to_state` finds the offset: ``l = N_inv(y_d)`` (Eq 2.19/2.20) for psi_n and a
search over ``u_bar`` for psi_a/psi_d, each refined on the plant until the output at ``t_1``
lands in the target window.  Which window depends on the plant, as in the thesis (§4.2):

* a simulated plant (:class:`~preisach.experiments.ModelPlant`, any plant that is not a DAQ
  device): ``thresholds="simulation"``, ``y_d +/- 0.03`` V;
* a DAQ device (:class:`preisach.daq.DevicePlant`, a real rig or the virtual one):
  ``thresholds="experiment"``, the landing windows of Table 4.1 for psi_a/psi_d (psi_n keeps
  ``y_d +/- 0.03`` V, reached through the measured locus).

The thesis's experiments also accept an initial state only if the output then stays within
``y_d +/- 0.1`` V from ``t_1`` to ``t_1 + 2`` s (:data:`HOLD_BAND`, :data:`HOLD_DURATION`);
:func:`drive_to_state` records that check (``hold_check``) and can warn or raise.  On the rig the
beam's creep carries the output from the Table 4.1 window towards ``y_d``; a plant without such
dynamics (the classical model, the virtual rig without blocks) stays where it landed, so
psi_a/psi_d reached with the Table 4.1 windows fail the check there - use
``thresholds="simulation"`` for such plants.

Every waveform is an :class:`~preisach.waveforms.InputSignal` (the package's one sampled-input
type) and carries its time base (:attr:`Waveform.time`, relative to ``t_1``) so it can be
played on a DAQ device as it is.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError, PreisachError, PreisachWarning
from ..model import State
from ..neutral import NeutralLocus, neutral_locus
from ..waveforms import InputSignal
from .plant import Plant

__all__ = [
    "HOLD_BAND",
    "HOLD_DURATION",
    "KINDS",
    "SIMULATION_TOLERANCE",
    "TABLE_4_1",
    "HoldWindowError",
    "HoldWindowWarning",
    "Initialisation",
    "Waveform",
    "branch_input",
    "default_thresholds",
    "drive_to_state",
    "landing_window",
    "measure_locus",
    "neutral_input",
]

#: The three initial states: neutral, ascending branch, descending branch.
KINDS: tuple[str, ...] = ("n", "a", "d")
_NAMES = {"n": "psi_n", "a": "psi_a", "d": "psi_d"}

#: Output tolerance (V) around ``y_d`` for the initial states in simulation (§4.2).
SIMULATION_TOLERANCE: float = 0.03

#: Table 4.1: landing windows ``(dy_l, dy_h)`` (V) of the output at the end of the first half
#: period, relative to ``y_d = 1``, used in the thesis's experiments for psi_a and psi_d (the
#: beam's creep carries the output on towards ``y_d`` afterwards).
TABLE_4_1: dict[float, dict[str, tuple[float, float]]] = {
    1.0: {"a": (-0.22, -0.14), "d": (0.14, 0.22)},
    2.0: {"a": (-0.28, -0.22), "d": (0.22, 0.28)},
    4.0: {"a": (-0.44, -0.38), "d": (0.38, 0.44)},
}

#: Half-width (V) of the band ``y_d +/- HOLD_BAND`` the output must stay in from ``t_1`` to
#: ``t_1 + HOLD_DURATION`` in the thesis's experiments (§4.2, also Fig 4.14).
HOLD_BAND: float = 0.1

#: Length (s) of the hold after ``t_1`` over which :data:`HOLD_BAND` is checked (§4.2).
HOLD_DURATION: float = 2.0

_HOLD_CHECKS = ("record", "warn", "raise", "off")


class HoldWindowWarning(PreisachWarning):
    """The output left ``y_d +/- HOLD_BAND`` during the hold after ``t_1`` (thesis §4.2)."""


class HoldWindowError(PreisachError, ValueError):
    """An initial state failed the thesis's acceptance check (``hold_check="raise"``)."""


def _is_device(plant: object) -> bool:
    """Whether ``plant`` is a DAQ device: it says so with ``is_device = True``."""
    return getattr(plant, "is_device", False) is True


def default_thresholds(plant: Plant) -> str:
    """Landing thresholds :func:`drive_to_state` uses on ``plant`` by default.

    Parameters
    ----------
    plant : Plant
        The plant.

    Returns
    -------
    str
        ``"experiment"`` (Table 4.1) for a DAQ device plant, one with ``is_device = True``
        (:class:`preisach.daq.DevicePlant`: a real or virtual rig, whether or not it carries a
        model for the neutral locus); ``"simulation"`` (``y_d +/- 0.03`` V) for every other
        plant.

    """
    return "experiment" if _is_device(plant) else "simulation"


def _check_kind(kind: str) -> str:
    k = str(kind).lower().removeprefix("psi_")
    if k not in KINDS:
        raise ValueError(f"kind: expected one of 'n', 'a', 'd' (psi_n, psi_a, psi_d), got {kind!r}")
    return k


def _positive(name: str, v: float) -> float:
    v = float(v)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: must be a positive finite number, got {v!r}")
    return v


def landing_window(
    kind: str,
    y_d: float,
    frequency: float | None = None,
    *,
    thresholds: str = "simulation",
    tolerance: float = SIMULATION_TOLERANCE,
) -> tuple[float, float]:
    """Window (V) the output must land in at ``t_1`` for an initial state.

    Parameters
    ----------
    kind : {"n", "a", "d"}
        Initial state.
    y_d : float
        Desired output (V).
    frequency : float, optional
        Initialisation frequency (Hz); needed for ``thresholds="experiment"``.
    thresholds : {"simulation", "experiment"}
        ``"simulation"``: ``y_d +/- tolerance``.  ``"experiment"``: Table 4.1's
        ``[y_d + dy_l, y_d + dy_h]`` for psi_a and psi_d at 1, 2 or 4 Hz (psi_n keeps
        ``y_d +/- tolerance``: the thesis reaches it through the measured locus).
        :func:`drive_to_state` picks one from the plant (:func:`default_thresholds`).
    tolerance : float
        Half-width (V) of the simulation window.

    """
    k = _check_kind(kind)
    if thresholds not in ("simulation", "experiment"):
        raise ValueError(f"thresholds: expected 'simulation' or 'experiment', got {thresholds!r}")
    tol = _positive("tolerance", tolerance)
    if thresholds == "experiment" and k != "n":
        if frequency is None or float(frequency) not in TABLE_4_1:
            raise ValueError(
                f"thresholds='experiment': Table 4.1 has windows for 1, 2 and 4 Hz only, "
                f"got frequency={frequency!r}"
            )
        lo, hi = TABLE_4_1[float(frequency)][k]
        return (y_d + lo, y_d + hi)
    return (y_d - tol, y_d + tol)


@dataclass
class Waveform(InputSignal):
    """An initialisation input (psi_n, psi_a or psi_d), sampled for a plant.

    A :class:`~preisach.waveforms.InputSignal` (the package's one sampled-input type: ``t`` in
    s from 0, ``u`` in V, ``sample_time``, ``name`` ``"psi_n"``/``"psi_a"``/``"psi_d"``) with
    the initialisation's parameters.  Samples are at ``t_0 + k * sample_time`` for
    ``k = 0 .. len(u) - 1``; ``t_1`` (when the state is reached and the offset starts to be
    held) is the sample after the last one.

    Attributes
    ----------
    kind : str
        ``"n"``, ``"a"`` or ``"d"``.
    offset : float
        The value held from ``t_1`` on (V): ``l`` for psi_n, ``u_bar`` for psi_a/psi_d.
    frequency : float
        Frequency of the sinusoid (Hz).
    u_hat : float
        Saturation amplitude used (V).

    """

    kind: str = "n"
    offset: float = 0.0
    frequency: float = float("nan")
    u_hat: float = float("nan")

    @classmethod
    def sampled(
        cls,
        kind: str,
        u: NDArray[np.float64],
        sample_time: float,
        offset: float,
        frequency: float,
        u_hat: float,
    ) -> Waveform:
        """Build the waveform of ``kind`` from input samples ``u`` (V) every ``sample_time`` s."""
        u = np.asarray(u, dtype=np.float64)
        return cls(
            t=np.arange(u.size, dtype=np.float64) * float(sample_time),
            u=u,
            sample_time=float(sample_time),
            name=f"psi_{kind}",
            params={"offset": offset, "frequency": frequency, "u_hat": u_hat},
            kind=kind,
            offset=offset,
            frequency=frequency,
            u_hat=u_hat,
        )

    @property
    def input(self) -> NDArray[np.float64]:
        """Input samples (V), the same array as ``u``."""
        return self.u

    @property
    def duration(self) -> float:
        """``t_1 - t_0`` (s): the samples' span plus the one sample to ``t_1``."""
        return len(self.u) * self.sample_time

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times (s) relative to ``t_1`` (all negative; the first is ``t_0 - t_1``)."""
        n = len(self.u)
        return np.asarray((np.arange(n) - n) * self.sample_time, dtype=np.float64)

    def with_hold(self) -> NDArray[np.float64]:
        """Return the input followed by one sample of the offset (the input up to ``t_1``)."""
        return np.append(self.u, self.offset)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly description (parameters, not samples)."""
        return {
            "kind": self.kind,
            "offset": self.offset,
            "frequency": self.frequency,
            "sample_time": self.sample_time,
            "u_hat": self.u_hat,
            "duration": self.duration,
            "samples": len(self.u),
        }


def _samples(duration: float, ts: float) -> NDArray[np.float64]:
    n = int(round(duration / ts))
    if n < 2:
        raise ValueError(f"sample_time {ts:g} s is too long for a {duration:g} s waveform")
    return np.asarray(np.arange(n) * ts, dtype=np.float64)


def neutral_input(
    l: float,  # noqa: E741 (the thesis's symbol)
    frequency: float,
    *,
    u_range: tuple[float, float],  # noqa: E741
    cycles: float = 10.0,
    sample_time: float = 1e-3,
    u_hat: float | None = None,
) -> Waveform:
    """Build the decaying sinusoid of Eq 4.1/4.2 that drives any state to psi_n^l.

    ``u(t) = (t_1 - t)/(t_1 - t_0) * A * sin(2 pi f (t - t_0) + pi/2) + l`` on ``[t_0, t_1)``,
    with ``A = u_hat - l`` (starting at ``+u_hat``) when ``l`` is at or above the middle of the
    range and ``A = -u_hat' - l`` (starting at the lower saturation) otherwise - Eq 4.1's
    ``sgn(l) u_hat - l``, and Eq 4.2 for ``l = 0``.

    Parameters
    ----------
    l : float
        Offset of the neutral state (V), inside ``u_range``.
    frequency : float
        ``f`` (Hz).
    u_range : (float, float)
        Input range ``(u_min, u_max)`` (V) of the plant.
    cycles : float, default 10
        Number of periods, ``f (t_1 - t_0)``; more cycles give finer steps of the staircase.
    sample_time : float, default 1e-3
        Sampling period (s).
    u_hat : float, optional
        Start amplitude (V, positive): the waveform starts at ``+u_hat`` or ``-u_hat``.
        Default: the saturation ``u_max`` (or ``-u_min`` when starting low).

    Returns
    -------
    Waveform

    """
    f = _positive("frequency", frequency)
    ts = _positive("sample_time", sample_time)
    cyc = _positive("cycles", cycles)
    lo, hi = float(u_range[0]), float(u_range[1])
    l = float(l)  # noqa: E741
    if not (lo <= l <= hi):
        raise ValueError(f"l = {l:g} V is outside the input range [{lo:g}, {hi:g}] V")
    start_high = l >= 0.5 * (lo + hi)
    if u_hat is None:
        top = hi if start_high else lo
    else:
        top = _positive("u_hat", u_hat) * (1.0 if start_high else -1.0)
    amp = top - l
    duration = cyc / f
    t = _samples(duration, ts)
    u = (duration - t) / duration * amp * np.sin(2 * np.pi * f * t + np.pi / 2) + l
    return Waveform.sampled("n", u, ts, l, f, abs(top))


def branch_input(
    kind: str,
    u_bar: float,
    frequency: float,
    *,
    u_range: tuple[float, float],
    sample_time: float = 1e-3,
    u_hat: float | None = None,
) -> Waveform:
    """One and a half periods of a sinusoid ending at ``u_bar`` on a major branch (Eq 4.3/4.4).

    ``kind="a"``: ``u_hat sin(2 pi f (t - t_0) - pi/2)`` for one period (from ``-u_hat`` up to
    ``+u_hat`` and back), then ``(u_bar + u_hat)/2 sin(...) + (u_bar - u_hat)/2`` rising to
    ``u_bar`` at ``t_1 = t_0 + 1.5/f``.  ``kind="d"``: the mirror image, starting at ``+u_hat``
    and falling to ``u_bar`` (see the module note on Eq 4.4).

    Parameters
    ----------
    kind : {"a", "d"}
        Ascending (psi_a) or descending (psi_d) branch.
    u_bar : float
        Final input (V), the offset held afterwards.
    frequency : float
        ``f`` (Hz).
    u_range : (float, float)
        Input range (V) of the plant; the default ``u_hat`` is its saturation.
    sample_time : float
        Sampling period (s).
    u_hat : float, optional
        Amplitude (V); default: the saturation of ``u_range`` (``u_max`` for the upper, ``-u_min``
        for the lower excursion).

    """
    k = _check_kind(kind)
    if k == "n":
        raise ValueError("branch_input: kind must be 'a' or 'd'; use neutral_input for psi_n")
    f = _positive("frequency", frequency)
    ts = _positive("sample_time", sample_time)
    lo, hi = float(u_range[0]), float(u_range[1])
    if u_hat is not None:
        a = _positive("u_hat", u_hat)
        lo, hi = -a, a
    ub = float(u_bar)
    if not (lo <= ub <= hi):
        raise ValueError(f"u_bar = {ub:g} V is outside [{lo:g}, {hi:g}] V")
    t = _samples(1.5 / f, ts)
    mid, half = 0.5 * (hi + lo), 0.5 * (hi - lo)
    if k == "a":
        ph = 2 * np.pi * f * t - np.pi / 2
        u = mid + half * np.sin(ph)
        second = t >= 1.0 / f
        u[second] = 0.5 * (ub - lo) * np.sin(ph[second]) + 0.5 * (ub + lo)
    else:
        ph = 2 * np.pi * f * t + np.pi / 2
        u = mid + half * np.sin(ph)
        second = t >= 1.0 / f
        u[second] = 0.5 * (hi - ub) * np.sin(ph[second]) + 0.5 * (hi + ub)
    return Waveform.sampled(k, u, ts, ub, f, max(abs(lo), abs(hi)))


@dataclass
class Initialisation:
    """An initial state reached on a plant, and how.

    Attributes
    ----------
    kind : str
        ``"n"``, ``"a"`` or ``"d"``.
    waveform : Waveform
        The input that reaches it (play it from any state).
    y_d : float
        Desired output (V).
    window : (float, float)
        Window (V) the output had to land in at ``t_1``.
    y_end : float
        Output at ``t_1`` (V).
    iterations : int
        Plant runs the offset search used.
    state : State or None
        Snapshot of the plant at the end of the final run: at ``t_1``, or after the hold when
        the hold was checked - the same state for a rate-independent model, whose state a
        constant input does not change (``None`` for plants that cannot restore one).
    l_inverse : float or None
        For psi_n: ``N_inv(y_d)`` from the locus, before any correction on the plant (V).
    thresholds : str or None
        How ``window`` was chosen: ``"simulation"``, ``"experiment"`` (Table 4.1) or
        ``"window"`` (given explicitly).
    hold_band : (float, float) or None
        Acceptance band ``y_d +/- HOLD_BAND`` (V) of the hold check; ``None`` if not checked.
    hold_range : (float, float) or None
        Lowest and highest output (V) from ``t_1`` to ``t_1 + HOLD_DURATION`` in the final run;
        ``None`` if not checked.

    """

    kind: str
    waveform: Waveform
    y_d: float
    window: tuple[float, float]
    y_end: float
    iterations: int
    state: State | None = field(default=None, repr=False)
    l_inverse: float | None = None
    thresholds: str | None = None
    hold_band: tuple[float, float] | None = None
    hold_range: tuple[float, float] | None = None

    @property
    def hold_ok(self) -> bool | None:
        """Whether the output stayed in ``hold_band`` during the hold (§4.2); None: unchecked."""
        if self.hold_band is None or self.hold_range is None:
            return None
        return bool(
            self.hold_band[0] <= self.hold_range[0] and self.hold_range[1] <= self.hold_band[1]
        )

    @property
    def offset(self) -> float:
        """Input held from ``t_1`` on (V)."""
        return self.waveform.offset

    @property
    def frequency(self) -> float:
        """Initialisation frequency (Hz)."""
        return self.waveform.frequency

    @property
    def name(self) -> str:
        """``"psi_n"``, ``"psi_a"`` or ``"psi_d"``."""
        return _NAMES[self.kind]

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly summary."""
        return {
            "kind": self.kind,
            "name": self.name,
            "y_d": self.y_d,
            "window": list(self.window),
            "y_end": self.y_end,
            "offset": self.offset,
            "iterations": self.iterations,
            "l_inverse": self.l_inverse,
            "thresholds": self.thresholds,
            "hold_band": None if self.hold_band is None else list(self.hold_band),
            "hold_range": None if self.hold_range is None else list(self.hold_range),
            "hold_ok": self.hold_ok,
            "waveform": self.waveform.to_dict(),
        }


def paired_trials(
    plant: Plant, init: Initialisation, gains: Sequence[float], seeds: Sequence[int]
) -> tuple[list[float], list[int], float]:
    """Check a batch of trials from ``init``: one seed per gain, ``init`` made on this clock.

    Returns the gains, the seeds and the plant's sample time (s).
    """
    gain_list = [float(g) for g in gains]
    seed_list = [int(s) for s in seeds]
    if len(gain_list) != len(seed_list):
        raise ValueError(
            f"gains and seeds: need the same length, got {len(gain_list)} and {len(seed_list)}"
        )
    ts = float(plant.sample_time)
    if not np.isclose(init.waveform.sample_time, ts, rtol=1e-9):
        raise ValueError(
            f"init was made at {init.waveform.sample_time:g} s, the plant samples at {ts:g} s"
        )
    return gain_list, seed_list, ts


def _measure(plant: Plant, wave: Waveform, settle: int) -> float:
    plant.reset(None)
    y = np.asarray(plant.run_open_loop(wave.with_hold()), dtype=float)
    return float(np.mean(y[-settle:]))


def _search(
    measure: Callable[[float], float],
    lo: float,
    hi: float,
    window: tuple[float, float],
    x0: float,
    max_iter: int,
    what: str,
) -> tuple[float, float, int]:
    """Find x in [lo, hi] with measure(x) in window; measure is non-decreasing in x.

    Illinois (modified regula falsi) on measure(x) - target, started from x0; stops as soon
    as the measurement lands in the window.  Returns (x, measure(x), evaluations).
    """
    target = 0.5 * (window[0] + window[1])
    evals = 0

    def ev(x: float) -> float:
        nonlocal evals
        evals += 1
        return measure(x)

    def inside(y: float) -> bool:
        return window[0] <= y <= window[1]

    x = min(max(x0, lo), hi)
    y = ev(x)
    if inside(y):
        return x, y, evals
    if y < target:
        a, fa = x, y - target
        b = hi
        fb = ev(b) - target
        if inside(fb + target):
            return b, fb + target, evals
        if fb < 0:
            raise ValueError(
                f"{what}: the output cannot reach {window[0]:g}..{window[1]:g} V "
                f"(at most {fb + target:.4g} V at the upper end {hi:g} V)"
            )
    else:
        b, fb = x, y - target
        a = lo
        fa = ev(a) - target
        if inside(fa + target):
            return a, fa + target, evals
        if fa > 0:
            raise ValueError(
                f"{what}: the output cannot reach {window[0]:g}..{window[1]:g} V "
                f"(at least {fa + target:.4g} V at the lower end {lo:g} V)"
            )
    side = 0
    for _ in range(max_iter):
        x = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not (min(a, b) < x < max(a, b)):
            x = 0.5 * (a + b)
        y = ev(x)
        if inside(y):
            return x, y, evals
        fx = y - target
        if fx < 0:
            a, fa = x, fx
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb = x, fx
            if side == 1:
                fa *= 0.5
            side = 1
        if abs(b - a) < 1e-12 * max(1.0, abs(a), abs(b)):
            break
    raise ConvergenceError(
        f"{what}: no offset in [{lo:g}, {hi:g}] V put the output in "
        f"[{window[0]:g}, {window[1]:g}] V after {evals} runs (last {y:.6g} V at "
        f"{x:.6g} V); the output may jump over the window - widen it"
    )


def drive_to_state(
    plant: Plant,
    kind: str,
    y_d: float,
    frequency: float,
    *,
    locus: NeutralLocus | None = None,
    thresholds: str | None = None,
    tolerance: float = SIMULATION_TOLERANCE,
    window: tuple[float, float] | None = None,
    cycles: float = 10.0,
    u_hat: float | None = None,
    settle: int = 1,
    max_iter: int = 60,
    hold_check: str = "record",
    hold_band: float = HOLD_BAND,
    hold: float = HOLD_DURATION,
) -> Initialisation:
    """Find and run the input that puts ``plant`` in psi_n, psi_a or psi_d with output ``y_d``.

    psi_n: ``l = locus.inverse(y_d)`` (Eq 2.19/2.20); if the plant's output at ``t_1`` after the
    decaying sinusoid (which only approximates psi_n^l) misses the window, ``l`` is corrected
    by a search on the plant.  psi_a/psi_d: ``u_bar`` is searched on the plant (the output at
    ``t_1`` grows with ``u_bar`` on both branches) until the output lands in the window.  The
    final run plays the waveform found and, unless ``hold_check="off"``, holds the offset for
    ``hold`` seconds to check the thesis's experimental acceptance condition (§4.2): the output
    stays within ``y_d +/- hold_band`` from ``t_1`` to ``t_1 + hold``.  The plant is left in the
    state at the end of that run.

    Parameters
    ----------
    plant : Plant
        Model-backed or DAQ-backed plant.
    kind : {"n", "a", "d"}
        Initial state.
    y_d : float
        Desired output (V).
    frequency : float
        Initialisation frequency ``f`` (Hz).
    locus : NeutralLocus, optional
        For psi_n.  Default: the exact locus of ``plant.model`` when the plant has one; a rig
        needs a measured locus (:func:`measure_locus`).
    thresholds : {"simulation", "experiment"}, optional
        Landing windows, see :func:`landing_window`.  Default :func:`default_thresholds`:
        ``"experiment"`` (Table 4.1, as in the thesis's experiments) on a DAQ device plant,
        ``"simulation"`` (``y_d +/- tolerance``) on a model plant.  Table 4.1 has windows for
        1, 2 and 4 Hz only.
    tolerance : float
        Half-width (V) of the simulation window (thesis: 0.03 V).
    window : (float, float), optional
        Explicit landing window (V); overrides ``thresholds``.
    cycles : float
        Periods of the psi_n sinusoid (see :func:`neutral_input`).
    u_hat : float, optional
        Saturation amplitude (V); default the plant's input range.
    settle : int
        Output samples averaged at ``t_1`` (1: the output at ``t_1`` itself; more for a noisy rig).
    max_iter : int
        Iterations of the offset search.
    hold_check : {"record", "warn", "raise", "off"}
        The acceptance check over the hold: ``"record"`` (default) measures it into
        :attr:`Initialisation.hold_range` / :attr:`Initialisation.hold_ok`; ``"warn"`` also
        emits :class:`HoldWindowWarning` and ``"raise"`` raises :class:`HoldWindowError` when
        the output leaves the band; ``"off"`` skips the hold (the final run ends at ``t_1``).
    hold_band : float
        Half-width (V) of the acceptance band around ``y_d``; thesis 0.1 V.
    hold : float
        Length (s) of the checked hold after ``t_1``; thesis 2 s.

    Returns
    -------
    Initialisation

    Raises
    ------
    ValueError
        If ``y_d`` cannot be reached, or Table 4.1 has no window for ``frequency``.
    ConvergenceError
        If the search does not land in the window within ``max_iter`` runs.
    HoldWindowError
        With ``hold_check="raise"``, if the output leaves ``y_d +/- hold_band`` during the hold.

    """
    k = _check_kind(kind)
    y_d = float(y_d)
    if not math.isfinite(y_d):
        raise ValueError(f"y_d: desired output is not finite ({y_d!r})")
    f = _positive("frequency", frequency)
    if settle < 1:
        raise ValueError(f"settle: need at least 1 sample, got {settle}")
    if hold_check not in _HOLD_CHECKS:
        raise ValueError(f"hold_check: expected one of {_HOLD_CHECKS}, got {hold_check!r}")
    band = _positive("hold_band", hold_band)
    hold_s = _positive("hold", hold)
    if window is not None:
        win = tuple(float(v) for v in window)
        how = "window"
    else:
        how = default_thresholds(plant) if thresholds is None else thresholds
        try:
            win = landing_window(k, y_d, f, thresholds=how, tolerance=tolerance)
        except ValueError as exc:
            if thresholds is None:
                raise ValueError(
                    f"{exc} (thresholds='experiment' is the default on a DAQ device plant); "
                    "pass thresholds='simulation' or an explicit window=(low, high) V"
                ) from None
            raise
    if len(win) != 2 or not win[0] <= win[1]:
        raise ValueError(f"window: expected (low, high) with low <= high, got {window!r}")
    lo, hi = (float(v) for v in plant.input_range)
    ts = float(plant.sample_time)
    l_inv: float | None = None
    if k == "n":
        if locus is None:
            model = getattr(plant, "model", None)
            if model is None:
                raise ValueError(
                    "locus: this plant has no model; measure the neutral locus first "
                    "(measure_locus) and pass it"
                )
            locus = neutral_locus(model)
        l_inv = locus.inverse(y_d)

        def make(x: float) -> Waveform:
            return neutral_input(x, f, u_range=(lo, hi), cycles=cycles, sample_time=ts, u_hat=u_hat)

        x0 = l_inv
        what = f"psi_n at y_d = {y_d:g} V"
    else:

        def make(x: float) -> Waveform:
            return branch_input(k, x, f, u_range=(lo, hi), sample_time=ts, u_hat=u_hat)

        x0 = 0.5 * (lo + hi)
        what = f"{_NAMES[k]} at y_d = {y_d:g} V"
        if u_hat is not None:
            lo, hi = -float(u_hat), float(u_hat)
    x, y, evals = _search(
        lambda v: _measure(plant, make(v), settle), lo, hi, (win[0], win[1]), x0, max_iter, what
    )
    wave = make(x)
    accept: tuple[float, float] | None = None
    held: tuple[float, float] | None = None
    if hold_check == "off":
        y_end = _measure(plant, wave, settle)
    else:
        n = len(wave.input)
        n_hold = max(1, int(round(hold_s / ts)))
        plant.reset(None)
        yy = np.asarray(
            plant.run_open_loop(np.concatenate([wave.input, np.full(n_hold, wave.offset)])),
            dtype=float,
        )
        y_end = float(np.mean(yy[n + 1 - settle : n + 1]))  # as _measure: the output at t_1
        accept = (y_d - band, y_d + band)
        held = (float(np.min(yy[n:])), float(np.max(yy[n:])))
    init = Initialisation(
        k,
        wave,
        y_d,
        (win[0], win[1]),
        y_end,
        evals + 1,
        plant.snapshot(),
        l_inv,
        how,
        accept,
        held,
    )
    if init.hold_ok is False and hold_check in ("warn", "raise"):
        assert held is not None and accept is not None
        msg = (
            f"{what}: the output left y_d +/- {band:g} V = [{accept[0]:g}, {accept[1]:g}] V "
            f"during the {hold_s:g} s hold after t_1 (it spanned {held[0]:.4g} .. {held[1]:.4g} V; "
            f"landed at {y_end:.4g} V in the {how} window [{win[0]:g}, {win[1]:g}] V); the "
            "thesis's experiments accept an initial state only inside that band (§4.2)"
        )
        if hold_check == "raise":
            raise HoldWindowError(msg)
        warnings.warn(msg, HoldWindowWarning, stacklevel=2)
    return init


def measure_locus(
    plant: Plant,
    offsets: np.ndarray,
    frequency: float,
    *,
    cycles: float = 10.0,
    settle: int = 1,
    u_hat: float | None = None,
) -> NeutralLocus:
    """Measure ``N(l)`` on a plant: drive it with :func:`neutral_input` for every offset.

    This is how the thesis finds ``l`` in the experiments (§4.2): the locus from rig data,
    inverted by interpolation.

    Parameters
    ----------
    plant : Plant
        The plant.
    offsets : array_like
        Increasing offsets ``l`` (V).
    frequency : float
        Frequency of the decaying sinusoid (Hz).
    cycles : float
        Periods of the decaying sinusoid (see :func:`neutral_input`).
    u_hat : float, optional
        Start amplitude (V); default the plant's saturation.
    settle : int
        Output samples averaged at ``t_1``.

    Returns
    -------
    NeutralLocus
        ``source="measured"`` (inverted by linear interpolation).

    """
    ls = np.asarray(offsets, dtype=float)
    lo, hi = (float(v) for v in plant.input_range)
    ys = [
        _measure(
            plant,
            neutral_input(
                x,
                frequency,
                u_range=(lo, hi),
                cycles=cycles,
                sample_time=plant.sample_time,
                u_hat=u_hat,
            ),
            settle,
        )
        for x in ls
    ]
    return NeutralLocus(ls, np.asarray(ys), source="measured")
