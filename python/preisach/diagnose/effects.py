"""Physics blocks around a Preisach model: the candidate explanations of diagnosis.

A block is a single-input single-output discrete-time system sampled every ``dt`` seconds,
with a few named parameters (physical units, independent of ``dt``), an internal state,
:meth:`Block.reset`, :meth:`Block.step` and a vectorised :meth:`Block.run` that continues from
the current state.  Input-side blocks act on the input (V) before the Preisach operator,
output-side blocks on its output (V).  The interface mirrors the C++ blocks of
``cpp/include/preisach/blocks/`` (``kind``, ``params`` with units, ``reset(x0)`` returning
the steady output, ``step``, ``run``), so the two can be unified; the functional forms here
are deliberately generic (see each class) because diagnosis must not assume the exact laws
of any one rig.

Sampling convention (the same as the C++ blocks): ``step(x)`` advances one sample interval
with the input held at ``x`` and returns the output at the end of the interval; linear blocks
are discretised exactly under this zero-order hold.

Overlap with the virtual rig's C++ blocks (:mod:`preisach.daq.blocks`).  Several candidates model
the same physics as a rig block; they are kept as independent implementations here because the
proof of diagnosis (:mod:`preisach.studies.diagnosis_cases`) uses the rig's blocks as the truth,
and a candidate that called the truth's code would prove nothing about the code.  A unified block
library would map them as follows:

==========================  =============================================  ====================
diagnosis block             rig block                                      difference
==========================  =============================================  ====================
:class:`SecondOrderMode`    ``StructuralMode(frequency, damping)``         same discretisation;
                                                                           adds participation
:class:`FirstOrderInputLag` ``InputLag(time_constant)``                    same physics
:class:`PronyCreep`         ``Creep(rate, tau_min, tau_max)``              both sums of lags;
                                                                           here free weights at
                                                                           fixed time constants
                                                                           and a settled gain
:class:`FractionalDelay`    ``Delay(samples)``, ``MovingAverage(length)``  fractional delay
                                                                           here, whole samples
                                                                           there
:class:`LagrangeDelay`      ``Delay(samples)``                             flat-magnitude
                                                                           fractional delay
                                                                           here
:class:`SensorDrift`        ``OffsetDrift(rate, sigma, seed)``             deterministic rate
                                                                           here, plus a random
                                                                           walk there
:class:`OutputFeedback`     ``PreisachStage(moving_gain)``                 centred polynomial
                                                                           feedback here, linear
                                                                           there
:class:`SplineFeedback`     ``PreisachStage(moving_gain)``                 spline feedback here,
                                                                           linear there
==========================  =============================================  ====================

:class:`RateDependentPlay`, :class:`RateDependentWidth`, :class:`LevelDependentGain`,
:class:`FirstOrderOutputLag` and :class:`GainOffset` have no rig counterpart.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import linalg, signal

from .. import _core

if TYPE_CHECKING:
    from ..model import State

__all__ = [
    "EFFECT_TYPES",
    "EffectBlock",
    "PronyCreep",
    "FirstOrderInputLag",
    "FirstOrderOutputLag",
    "FractionalDelay",
    "LagrangeDelay",
    "GainOffset",
    "LevelDependentGain",
    "OutputFeedback",
    "RateDependentPlay",
    "RateDependentWidth",
    "ReversibleRelaxation",
    "SensorDrift",
    "SecondOrderMode",
    "TwoModes",
    "FeedbackBlock",
    "SplineFeedback",
    "effect_from_dict",
]

Array = NDArray[np.float64]


def _finite(kind: str, name: str, value: Any) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{kind}: parameter {name} must be finite, got {value!r}")
    return v


def _positive(kind: str, name: str, value: Any) -> float:
    v = _finite(kind, name, value)
    if v <= 0:
        raise ValueError(f"{kind}: parameter {name} must be > 0, got {value!r}")
    return v


def _nonneg(kind: str, name: str, value: Any) -> float:
    v = _finite(kind, name, value)
    if v < 0:
        raise ValueError(f"{kind}: parameter {name} must be >= 0, got {value!r}")
    return v


_CHECKS = {"finite": _finite, ">0": _positive, ">=0": _nonneg}


def _lag(x: Array, pole: float, previous: float) -> Array:
    """First-order lag ``y[k] = pole y[k-1] + (1 - pole) x[k]`` from ``y[-1] = previous``.

    The exact zero-order-hold discretisation of ``tau dy/dt = x - y`` with
    ``pole = exp(-dt / tau)``; units of ``x`` and ``previous`` alike (V, V/s, ...).
    """
    y, _ = signal.lfilter([1 - pole], [1.0, -pole], x, zi=[pole * previous])
    return np.asarray(y)


def _as_input(kind: str, x: ArrayLike) -> Array:
    a = np.ascontiguousarray(x, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{kind}: expected a 1-D input array, got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise ValueError(f"{kind}: input sample {int(bad[0])} is not finite")
    return a


class EffectBlock:
    """Base class: a SISO block with named parameters, a state, ``reset``, ``step``, ``run``.

    Subclasses set ``kind`` (short identifier), ``side`` (``"input"`` or ``"output"``),
    ``PARAMS`` (parameter names with units) and ``DOMAIN`` (``">0"`` or ``">=0"`` for the
    parameters that must be positive or non-negative; the others must be finite), implement
    :meth:`_run` and :meth:`reset`, and may derive discretised constants in :meth:`_derive`.

    Parameters
    ----------
    dt : float
        Sample time (s).
    **params : float
        The parameters named in ``PARAMS`` (physical units, see the subclass).

    """

    kind: ClassVar[str] = ""
    side: ClassVar[str] = "output"
    PARAMS: ClassVar[tuple[tuple[str, str], ...]] = ()
    DOMAIN: ClassVar[dict[str, str]] = {}
    #: values of the parameters that may be left out (added after files were written)
    OPTIONAL: ClassVar[dict[str, float]] = {}
    #: an output block that needs the Preisach input (and some its initial state and model)
    #: besides the Preisach output: it runs through :meth:`apply_chain`, not :meth:`run`
    needs_chain: ClassVar[bool] = False

    def __init__(self, dt: float, **params: Any) -> None:
        self.dt = _positive(self.kind or "block", "dt", dt)
        names = [p for p, _ in self.PARAMS]
        unknown = sorted(set(params) - set(names))
        if unknown:
            raise TypeError(f"{self.kind}: unknown parameter(s) {unknown}; expected {names}")
        params = {**self.OPTIONAL, **params}
        missing = [p for p in names if p not in params]
        if missing:
            raise TypeError(f"{self.kind}: missing parameter(s) {missing}")
        self._params: dict[str, Any] = {}
        self._set(params)
        self.reset(0.0)

    # -- parameters ---------------------------------------------------------------------
    def _set(self, params: dict[str, Any]) -> None:
        """Validate and store the parameters, then derive the discretised constants."""
        check = {k: _CHECKS[self.DOMAIN.get(k, "finite")] for k, _ in self.PARAMS}
        self._params = {k: check[k](self.kind, k, params[k]) for k in check}
        self._derive()

    def _derive(self) -> None:
        """Constants that follow from the parameters and ``dt`` (none by default)."""

    @property
    def params(self) -> dict[str, Any]:
        """Parameter values by name (physical units, see :attr:`units`)."""
        return dict(self._params)

    @property
    def units(self) -> dict[str, str]:
        """Unit of every parameter."""
        return dict(self.PARAMS)

    def with_dt(self, dt: float) -> EffectBlock:
        """Return the same physical block for another sample time (fresh state)."""
        return type(self)(dt, **self._params)

    # -- simulation ---------------------------------------------------------------------
    def reset(self, x0: float) -> float:  # pragma: no cover - abstract
        """Reset to the steady state for the constant input ``x0``; returns the output."""
        raise NotImplementedError

    def run(self, x: ArrayLike) -> Array:
        """Process the samples ``x`` from the current state (which is advanced)."""
        return self._run(_as_input(self.kind, x))

    def apply_chain(self, x: ArrayLike, u: ArrayLike, state: State, model: Any) -> Array:
        """Output (V) of a :attr:`needs_chain` block, from rest.

        ``x``: the Preisach output (V); ``u``: the Preisach input (V); ``state``: its
        initial state; ``model``: the :class:`~preisach.PreisachModel` producing ``x``.
        """
        raise TypeError(f"{self.kind}: a block of the output alone; use run()")

    def _run(self, x: Array) -> Array:  # pragma: no cover - abstract
        raise NotImplementedError

    def step(self, x: float) -> float:
        """Advance one sample with input ``x``; returns the output."""
        return float(self.run(np.array([x], dtype=float))[0])

    def _static(self, x0: float) -> float:
        """Output of a memoryless block for the input ``x0``."""
        return float(self._run(np.array([_finite(self.kind, "x0", x0)]))[0])

    # -- persistence --------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly description: kind, side, dt and parameters."""
        p = {
            k: (list(map(float, v)) if isinstance(v, (list, tuple, np.ndarray)) else float(v))
            for k, v in self._params.items()
        }
        return {
            "type": type(self).__name__,
            "kind": self.kind,
            "side": self.side,
            "dt": self.dt,
            "params": p,
        }

    def describe(self) -> str:
        """One line with the parameters and their units."""
        parts = []
        for k, unit in self.PARAMS:
            v = self._params[k]
            if isinstance(v, (list, tuple, np.ndarray)):
                parts.append(f"{k}=[{', '.join(f'{float(a):.4g}' for a in v)}] {unit}".rstrip())
            else:
                parts.append(f"{k}={float(v):.4g} {unit}".rstrip())
        return f"{self.kind}({', '.join(parts)})"

    def __repr__(self) -> str:
        return f"<{self.describe()} dt={self.dt:g} s, {self.side} side>"


def _steady_zi(b: Array, a: Array) -> Array:
    """Direct-form-II-transposed state of ``lfilter(b, a)`` at rest with a unit input.

    With ``a[0] = 1`` and DC gain ``g = sum(b) / sum(a)``, the state recursion at rest gives
    ``z_k = sum_{j > k} (b_j - a_j g)``; cheaper than :func:`scipy.signal.lfilter_zi`.
    """
    n = max(len(a), len(b))
    bb = np.zeros(n)
    aa = np.zeros(n)
    bb[: len(b)] = b
    aa[: len(a)] = a
    g = bb.sum() / aa.sum()
    d = bb - aa * g
    return np.cumsum(d[::-1])[::-1][1:]


class _LinearFilter(EffectBlock):
    """A unit-DC-gain linear filter y = x + m (H x - x) held as ``(b, a)`` + ``zi``."""

    _b: Array
    _a: Array

    def _design(self) -> tuple[Array, Array, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    def _derive(self) -> None:
        self._b, self._a, self._mix = self._design()
        self._zi = np.zeros(max(len(self._a), len(self._b)) - 1)

    def reset(self, x0: float) -> float:
        """Steady state for the constant input ``x0`` (unit DC gain: returns ``x0``)."""
        x0 = _finite(self.kind, "x0", x0)
        self._zi = _steady_zi(self._b, self._a) * x0 if self._zi.size else self._zi
        return x0

    def _run(self, x: Array) -> Array:
        if not self._zi.size:
            h = signal.lfilter(self._b, self._a, x)
        else:
            h, self._zi = signal.lfilter(self._b, self._a, x, zi=self._zi)
        return np.asarray(x + self._mix * (h - x), dtype=float)


def _expm2(A: Array) -> Array:
    """``exp(A)`` of a real 2x2 matrix, stable for equal eigenvalues.

    ``exp(A) = e^s (cosh(q) I + sinh(q) / q (A - s I))`` with ``s = tr(A) / 2`` and
    ``q^2 = s^2 - det(A)`` (``q`` complex for complex eigenvalues; ``sinh(q)/q`` by its series
    near ``q = 0``).
    """
    s = 0.5 * (A[0, 0] + A[1, 1])
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    q2 = s * s - det
    q = np.sqrt(complex(q2))
    if abs(q) < 1e-4:
        ch = 1 + q2 / 2 + q2 * q2 / 24
        sh = 1 + q2 / 6 + q2 * q2 / 120
    else:
        ch = np.cosh(q)
        sh = np.sinh(q) / q
    return np.asarray(
        (math.exp(s) * (complex(ch) * np.eye(2) + complex(sh) * (A - s * np.eye(2)))).real,
        dtype=float,
    )


def _mode_zoh(wn: float, zeta: float, dt: float) -> tuple[Array, Array, Array]:
    """Exact zero-order-hold discretisation of the mode ``G = wn^2 / D``, ``V = 2 zeta wn s / D``.

    ``D = s^2 + 2 zeta wn s + wn^2``.  With the state ``[p, dp/dt]``: ``Phi = exp(A dt)`` and
    ``Gamma = A^-1 (Phi - I) B``; the common denominator ``a`` is the characteristic
    polynomial of ``Phi`` and each numerator follows from its step response at the ends of
    the first two sample intervals (``G``: the first state; ``V``: the second, scaled by
    ``2 zeta / wn``), so ``1 - G - V`` is the acceleration response ``s^2 / D``.  Convention
    of the blocks (``cpp/include/preisach/blocks/linear.hpp``): ``y[k]`` is the output at the
    end of the interval over which ``x[k]`` is held.  Returns ``(b_G, b_V, a)``.
    """
    A = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]])
    B = np.array([0.0, wn * wn])
    Phi = _expm2(A * dt)
    Gamma = np.linalg.solve(A, (Phi - np.eye(2)) @ B)
    a1, a2 = -float(np.trace(Phi)), float(np.linalg.det(Phi))
    x1 = Gamma
    x2 = Phi @ x1 + Gamma
    a = np.array([1.0, a1, a2])
    # from the step responses s0, s1 at the ends of the first two intervals
    b = np.array([x1[0], x2[0] - x1[0] + a1 * x1[0]])
    b *= a.sum() / b.sum()  # exact unit DC gain after rounding
    c = 2.0 * zeta / wn
    v = c * np.array([x1[1], x2[1] - x1[1] + a1 * x1[1]])  # zero DC gain
    return b, v, a


def _mode_foh(wn: float, zeta: float, dt: float) -> tuple[Array, Array, Array]:
    """:func:`_mode_zoh` under a first-order hold: the input linear between its samples.

    ``s_k = Phi s_{k-1} + Gamma_1 x[k] + (Gamma - Gamma_1) x[k-1]``, ``Gamma_1`` the response
    to a unit ramp over one interval (divided by ``dt``); three numerator taps.
    """
    A = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]])
    F = np.zeros((4, 4))
    F[:2, :2] = A
    F[:2, 2] = [0.0, wn * wn]
    F[2, 3] = 1.0
    E = linalg.expm(F * dt)
    Phi, Gamma, Gamma1 = E[:2, :2], E[:2, 2], E[:2, 3] / dt
    tr = float(np.trace(Phi))
    a = np.array([1.0, -tr, float(np.linalg.det(Phi))])
    P, rest = Phi - tr * np.eye(2), Gamma - Gamma1

    def num(c: Array) -> Array:
        return np.array([c @ Gamma1, c @ (P @ Gamma1) + c @ rest, c @ (P @ rest)])

    b = num(np.array([1.0, 0.0]))
    b *= a.sum() / b.sum()
    v = num(np.array([0.0, 2.0 * zeta / wn]))
    return b, v, a


def _mode_held(f_n: float, zeta: float, dt: float, hold: float) -> tuple[Array, Array, Array]:
    """:func:`_mode_zoh` at ``f_n`` (Hz) under the hold ``hold`` (see :class:`SecondOrderMode`).

    From 0 to 1 the mix ``(1 - hold) ZOH + hold FOH`` of the two discretisations
    (:func:`_mode_foh`), from 1 to 2 the mix ``(2 - hold) FOH + (hold - 1) z^-1 ZOH``;
    returns ``(b_G, b_V, a)`` as :func:`_mode_zoh` does.
    """
    b, v, a = _mode_zoh(2 * math.pi * f_n, zeta, dt)
    if not hold:
        return b, v, a
    bf, vf, _ = _mode_foh(2 * math.pi * f_n, zeta, dt)
    if hold <= 1.0:  # zero order (0) to first order (1)
        return (1.0 - hold) * np.r_[b, 0.0] + hold * bf, (1.0 - hold) * np.r_[v, 0.0] + hold * vf, a
    w = min(hold, 2.0) - 1.0  # first order (1) to the zero-order response a sample later (2)
    return (1.0 - w) * bf + w * np.r_[0.0, b], (1.0 - w) * vf + w * np.r_[0.0, v], a


class SecondOrderMode(_LinearFilter):
    """A lightly damped structural mode after the hysteresis (output side).

    ``y = x + m (G x - x) - r A x`` with ``G(s) = wn^2 / D(s)``, ``A(s) = s^2 / D(s)``,
    ``D(s) = s^2 + 2 zeta wn s + wn^2``, ``wn = 2 pi f_n``, discretised exactly under a
    zero-order hold, a first-order hold or a mix of the two (``hold``).  ``m``
    (participation) is the fraction of the measured output that passes through the mode
    (1: the sensor sees only the beam's response); ``r`` (reaction) the part moved by the
    mode's response to the actuator's acceleration (a mount or frame that recoils:
    ``r > 0`` lowers the output while it accelerates).  The two are the
    numerator of any second-order response with unit DC gain.  Unit DC gain: quasi-static
    signals pass unchanged; steps ring at ``f_n``.

    Parameters
    ----------
    f_n : float
        Natural frequency (Hz).
    zeta : float
        Damping ratio (1).
    participation : float
        ``m`` (1).
    reaction : float, optional
        ``r`` (1); 0 when left out.
    hold : float, optional
        How the block's input moves between its samples and when its output is read: 0
        (default) held over the interval that ends at its sample (zero-order hold, as the
        rig's ``StructuralMode``), 1 linear between its samples (first-order hold: input and
        output sampled at the same instants, the input continuous), 2 held over the
        interval that starts at its sample (the output read as the input is updated, before
        the mode has moved: the zero-order response one sample later, while the part
        that does not pass through the mode follows at once); between, the mix of the two
        neighbouring responses.  Each step delays the ring by about half a sample of
        phase (``pi f_n dt``: 48 degrees at 264 Hz sampled at 1 kHz), enough to hide a
        fast mode from a fit under another.

    """

    kind = "structural_mode"
    side = "output"
    PARAMS = (
        ("f_n", "Hz"),
        ("zeta", ""),
        ("participation", ""),
        ("reaction", ""),
        ("hold", ""),
    )
    DOMAIN = {"f_n": ">0", "zeta": ">0"}
    OPTIONAL = {"reaction": 0.0, "hold": 0.0}

    def _design(self) -> tuple[Array, Array, float]:
        p = self._params
        m, r = p["participation"], p["reaction"]
        b, v, a = _mode_held(p["f_n"], p["zeta"], self.dt, p["hold"])
        if r == 0.0:
            return b, a, m
        # y = x + (m + r) (G x - x) + r V x  (A = 1 - G - V), one filter with mix 1
        num = (1.0 - m - r) * a
        num[: b.size] += (m + r) * b + r * v
        return num, a, 1.0


class TwoModes(_LinearFilter):
    """Two structural modes after the hysteresis, superposed (output side).

    ``y = x + m_1 (G_1 x - x) + m_2 (G_2 x - x)`` with ``G_k(s) = wn_k^2 / (s^2 + 2 zeta_k
    wn_k s + wn_k^2)``: the modal sum of a structure read by a sensor away from the drive
    (participations of either sign: a sensor not collocated with the actuator sees the
    second mode in antiphase), each mode discretised as :class:`SecondOrderMode` with one
    hold for both.  Unit DC gain.

    Parameters
    ----------
    f_n, zeta, participation : float
        First mode: natural frequency (Hz), damping ratio (1), participation ``m_1`` (1).
    f_n2, zeta2, participation2 : float
        Second mode, the same.
    hold : float, optional
        As :class:`SecondOrderMode` (0 to 2; 0, a zero-order hold, by default).

    """

    kind = "two_modes"
    side = "output"
    PARAMS = (
        ("f_n", "Hz"),
        ("zeta", ""),
        ("participation", ""),
        ("f_n2", "Hz"),
        ("zeta2", ""),
        ("participation2", ""),
        ("hold", ""),
    )
    DOMAIN = {"f_n": ">0", "zeta": ">0", "f_n2": ">0", "zeta2": ">0"}
    OPTIONAL = {"hold": 0.0}

    def _design(self) -> tuple[Array, Array, float]:
        p = self._params
        b1, _, a1 = _mode_held(p["f_n"], p["zeta"], self.dt, p["hold"])
        b2, _, a2 = _mode_held(p["f_n2"], p["zeta2"], self.dt, p["hold"])
        n = max(b1.size, a1.size)  # both modes' taps padded alike: H = 1 + sum m_k (G_k - 1)
        b1, a1, b2, a2 = (np.r_[c, np.zeros(n - c.size)] for c in (b1, a1, b2, a2))
        num = np.convolve(a1, a2)
        num += p["participation"] * np.convolve(b1 - a1, a2)
        num += p["participation2"] * np.convolve(b2 - a2, a1)
        return num, np.convolve(a1, a2), 1.0


class PronyCreep(EffectBlock):
    """Creep: part of every output change arrives slowly (output side).

    ``y = x_0 + g (x - x_0) + sum_i c_i (L_i x - x)`` with first-order lags ``L_i`` of time
    constants ``tau_i`` (exact under a zero-order hold), ``x_0`` the input the block was
    settled at (:meth:`reset`).  After a step of size D the output first moves by
    ``(g - sum c_i) D`` and then creeps by ``c_i D`` with time constant ``tau_i``; the settled
    gain of a move is ``g``.  The gain acts on the moves since the block was settled, not on
    the absolute output: a recording starts settled wherever it starts, so a creep with
    ``g != 1`` adds no offset to a recording that starts away from zero output.  A sum of
    lags one decade apart is the standard Prony-series representation of the logarithmic
    creep of piezo actuators, so this form fits creep laws of any shape on the time scales
    covered, not one particular law.

    Parameters
    ----------
    taus : sequence of float
        Time constants (s).
    weights : sequence of float
        ``c_i`` (fractions of the move, 1 = 100 %), one per time constant.
    gain : float
        Settled gain ``g`` (1).

    """

    kind = "creep"
    side = "output"
    PARAMS = (("taus", "s"), ("weights", ""), ("gain", ""))

    def _set(self, params: dict[str, Any]) -> None:
        taus = [float(t) for t in np.atleast_1d(params["taus"])]
        w = [float(c) for c in np.atleast_1d(params["weights"])]
        if len(taus) != len(w) or not taus:
            raise ValueError(
                f"creep: need one weight per time constant, got {len(w)} weights "
                f"for {len(taus)} time constants"
            )
        for t in taus:
            _positive(self.kind, "taus", t)
        for c in w:
            _finite(self.kind, "weights", c)
        self._params = {
            "taus": taus,
            "weights": w,
            "gain": _finite(self.kind, "gain", params["gain"]),
        }
        # parallel first-order sections (a common denominator loses precision for slow poles)
        self._lags = [math.exp(-self.dt / t) for t in taus]
        self._z = np.zeros(len(taus))
        self._x0 = 0.0

    def reset(self, x0: float) -> float:
        """Every lag settled at ``x0`` (the reference of the settled gain); returns ``x0``."""
        x0 = _finite(self.kind, "x0", x0)
        self._z = np.full(len(self._lags), x0)
        self._x0 = x0
        return x0

    def _run(self, x: Array) -> Array:
        p = self._params
        y = self._x0 + p["gain"] * (x - self._x0)
        for k, (e, c) in enumerate(zip(self._lags, p["weights"])):
            lag = _lag(x, e, self._z[k])
            if x.size:
                self._z[k] = lag[-1]
            if c != 0.0:
                y = y + c * (lag - x)
        return np.asarray(y, dtype=float)


class _TapDelay(EffectBlock):
    """A delay read through FIR taps: ``y[n] = sum_k h_k x[n - M - k]`` (output side).

    Subclasses give ``M`` and the taps ``h`` (summing to 1) for the delay in samples
    (:meth:`_taps`).
    """

    kind = "delay"
    side = "output"
    PARAMS = (("tau", "s"),)
    DOMAIN = {"tau": ">=0"}

    def _taps(self, d: float) -> tuple[int, Array]:
        raise NotImplementedError  # pragma: no cover

    def _derive(self) -> None:
        self._m, self._h = self._taps(self._params["tau"] / self.dt)
        self._buf = np.zeros(self._m + self._h.size - 1)

    def reset(self, x0: float) -> float:
        """Buffer filled with ``x0``; returns ``x0`` (the taps sum to 1)."""
        x0 = _finite(self.kind, "x0", x0)
        self._buf = np.full(self._buf.size, x0)
        return x0

    def _run(self, x: Array) -> Array:
        full = np.concatenate([self._buf, x])
        last = self._h.size - 1
        y = np.zeros(x.size)
        for k, h in enumerate(self._h):  # full[last - k + t] is x[t - M - k]
            y += h * full[last - k : last - k + x.size]
        self._buf = full[full.size - self._buf.size :]
        return y


class FractionalDelay(_TapDelay):
    """Transport delay or measurement lag of the output (output side).

    ``y(t) = x(t - tau)``, linearly interpolated between samples, so ``tau`` need not be a
    multiple of the sample time.  At frequencies well below ``1 / (2 pi tau)`` a first-order
    measurement lag, a moving-average filter or an anti-alias filter act like a delay equal
    to their group delay, so this one parameter stands for all of them.

    Parameters
    ----------
    tau : float
        Delay (s), >= 0.

    """

    #: how the reading between samples is made (``preisach.compensate`` inverts accordingly)
    interpolation = "linear"

    def _taps(self, d: float) -> tuple[int, Array]:
        n = int(math.floor(d))
        return n, np.array([1.0 - (d - n), d - n])


class LagrangeDelay(_TapDelay):
    """Fractional delay with a flat magnitude: third-order Lagrange interpolation (output side).

    ``y[n] = sum_k h_k x[n - M - k]`` for ``k = 0..3``, with ``h_k = prod_{j != k} (D - j) /
    (k - j)``, ``D = tau / dt - M`` and ``M = max(0, floor(tau / dt) - 1)``: the textbook FIR
    fractional-delay filter (Laakso, Valimaki, Karjalainen and Laine, IEEE Signal Processing
    Magazine 13(1), 1996), centred on the delay (``1 <= D < 2``) once ``tau >= dt`` and causal
    below.  A whole number of samples is an exact shift.  Unlike :class:`FractionalDelay`,
    whose linear interpolation averages neighbouring samples (at half a sample it is a
    two-sample moving average, a low-pass), this one is within 1 % of an exact delay
    (magnitude and phase) up to a tenth of the sample rate, where linear interpolation is off
    by up to 5 %: the reading of a band-limited output a fraction of a sample late, e.g. an
    input and an output channel sampled one after the other by a multiplexed ADC, or a
    digital fractional-delay filter.

    Parameters
    ----------
    tau : float
        Delay (s), >= 0.

    """

    interpolation = "lagrange"

    def _taps(self, d: float) -> tuple[int, Array]:
        m = max(0, int(math.floor(d)) - 1)
        ks = range(4)
        h = [math.prod((d - m - j) / (k - j) for j in ks if j != k) for k in ks]
        return m, np.array(h, dtype=float)


class FirstOrderOutputLag(_LinearFilter):
    """A first-order measurement filter between the actuator output and the reading (output side).

    ``tau dy/dt = x - y`` for the input interpolated linearly between its samples (exact under
    a first-order hold: the actuator's output is a continuous signal, not a staircase), so at
    low frequency the reading lags by exactly ``tau``, whatever ``tau / dt``; a sensor or
    amplifier with a first-order bandwidth.  Unlike a pure delay its group delay falls with
    frequency (to half at ``1 / (2 pi tau)``).  Diagnosis names it under ``delay`` (the
    measurement chain) in the form ``first_order_lag``.

    Parameters
    ----------
    tau : float
        Time constant (s), >= 0 (0 passes the input unchanged).

    """

    kind = "delay"
    side = "output"
    PARAMS = (("tau", "s"),)
    DOMAIN = {"tau": ">=0"}

    def _design(self) -> tuple[Array, Array, float]:
        t = self._params["tau"]
        if t <= 0:
            return np.array([1.0]), np.array([1.0]), 1.0
        pole = math.exp(-self.dt / t)
        r = t / self.dt * (1.0 - pole)  # first-order-hold discretisation: b0 + b1 = 1 - pole
        return np.array([1.0 - r, r - pole]), np.array([1.0, -pole]), 1.0


class FirstOrderInputLag(EffectBlock):
    """Rate-dependent hysteresis from a lag before the hysteresis (input side).

    The relays see the input through a first-order lag, ``tau dz/dt = u - z`` (exact under
    a zero-order hold): e.g. an amplifier driving the piezo's capacitance through its output
    impedance.  To first order the relays see ``u - tau du/dt``, so loops widen in proportion
    to the rate - like a delay after the hysteresis; unlike a delay, the lag lowers the
    extrema the relays see at sharp reversals (by about ``0.7 tau |du/dt|``), which changes the
    branches that follow.

    Parameters
    ----------
    tau : float
        Time constant (s), >= 0 (0 passes the input unchanged).

    """

    kind = "rate_dependence"
    side = "input"
    PARAMS = (("tau", "s"),)
    DOMAIN = {"tau": ">=0"}

    def _derive(self) -> None:
        t = self._params["tau"]
        self._e = math.exp(-self.dt / t) if t > 0 else 0.0
        self._z = 0.0

    def reset(self, x0: float) -> float:
        """Settled at ``x0``; returns ``x0``."""
        self._z = _finite(self.kind, "x0", x0)
        return self._z

    def _run(self, x: Array) -> Array:
        if x.size == 0 or self._e == 0.0:
            if x.size:
                self._z = float(x[-1])
            return x.copy()
        y = _lag(x, self._e, self._z)
        self._z = float(y[-1])
        return y


class RateDependentPlay(EffectBlock):
    """Rate-dependent hysteresis: loops widen with the input rate (input side).

    The Preisach operator sees the input through a play (backlash) operator of half-width
    ``w(t) = w_ref (|v(t)| / v_ref) ** p``, where ``v`` is the input rate ``du/dt`` smoothed by
    a first-order lag of time constant ``tau_v``.  Driving relays through a play of width
    ``w`` moves their thresholds apart to ``alpha + w`` and ``beta - w``: the
    threshold-dilation form of rate-dependent Prandtl-Ishlinskii and Preisach models.
    ``p = 1`` is close to a first-order lag on the input (amplifier driving a capacitive
    load), ``p < 1`` a loop width growing sublinearly (e.g. logarithmically) with the rate,
    ``p = 0`` a rate-independent extra width.

    Parameters
    ----------
    w_ref : float
        Half-width (V) at the reference rate, >= 0.
    exponent : float
        ``p`` (1), >= 0.
    v_ref : float
        Reference rate (V/s), > 0.
    tau_v : float
        Time constant (s) of the rate smoothing, > 0.

    """

    kind = "rate_dependence"
    side = "input"
    PARAMS = (("w_ref", "V"), ("exponent", ""), ("v_ref", "V/s"), ("tau_v", "s"))
    DOMAIN = {"w_ref": ">=0", "exponent": ">=0", "v_ref": ">0", "tau_v": ">0"}

    def _derive(self) -> None:
        self._e = math.exp(-self.dt / self._params["tau_v"])
        self._last = 0.0
        self._v = 0.0
        self._z = 0.0

    def reset(self, x0: float) -> float:
        """At rest at ``x0`` (rate 0, play output ``x0``); returns ``x0``."""
        x0 = _finite(self.kind, "x0", x0)
        self._last, self._v, self._z = x0, 0.0, x0
        return x0

    def width(self, x: Array) -> tuple[Array, Array]:
        """Half-width (V) and smoothed rate (V/s) for the input ``x`` (state not advanced)."""
        v = np.diff(np.concatenate([[self._last], x])) / self.dt
        vf = _lag(v, self._e, self._v)
        p = self._params
        return p["w_ref"] * (np.abs(vf) / p["v_ref"]) ** p["exponent"], vf

    def _run(self, x: Array) -> Array:
        if x.size == 0:
            return x.copy()
        w, vf = self.width(x)
        z, last = _core.play_operator(x, w, self._z)
        self._last, self._v, self._z = float(x[-1]), float(vf[-1]), float(last)
        return np.asarray(z)


class SensorDrift(EffectBlock):
    """Sensor offset drifting with time, unrelated to the input (output side).

    ``y = x + offset + rate * t`` with ``t`` the time since :meth:`reset`.  Diagnosis fits
    the drift of each recording as a smooth function of time (a spline); what carries over
    to new runs, and is stored here, is its deterministic part: the mean rate.

    Parameters
    ----------
    offset : float
        Offset at reset (V).
    rate : float
        Drift rate (V/s).

    """

    kind = "sensor_drift"
    side = "output"
    PARAMS = (("offset", "V"), ("rate", "V/s"))

    def _derive(self) -> None:
        self._k = 0

    def reset(self, x0: float) -> float:
        """Time back to 0; returns ``x0 + offset``."""
        self._k = 0
        return float(_finite(self.kind, "x0", x0) + self._params["offset"])

    def _run(self, x: Array) -> Array:
        t = (self._k + 1 + np.arange(x.size)) * self.dt
        self._k += x.size
        return np.asarray(x + self._params["offset"] + self._params["rate"] * t, dtype=float)


class LevelDependentGain(EffectBlock):
    """A nonlinear sensor: a static curve between the actuator output and the reading (output side).

    ``y = x + Y (c2 q^2 + c3 q^3)``, ``q = (x - x_c) / Y``: a static map after the Preisach
    operator (e.g. a strain-gauge bridge's nonlinearity) whose slope ``1 + 2 c2 q + 3 c3 q^2``
    scales small loops according to where on the output axis they sit.  ``x_c`` and ``Y`` are
    the centre and half-span of the model's output range (fixed, not fitted).  A classical
    model identified from FOD curves already absorbs any static map on those curves, so
    diagnosis fits it together with the Preisach weights when the identification recording is
    given.

    Parameters
    ----------
    c2, c3 : float
        Quadratic and cubic coefficients (1).
    x_c : float
        Centre of the output range (V).
    span : float
        ``Y`` (V), > 0.

    """

    kind = "sensor_nonlinearity"
    side = "output"
    PARAMS = (("c2", ""), ("c3", ""), ("x_c", "V"), ("span", "V"))
    DOMAIN = {"span": ">0"}

    def reset(self, x0: float) -> float:
        """Return the output for ``x0`` (a static map has no state to reset)."""
        return self._static(x0)

    def _run(self, x: Array) -> Array:
        p = self._params
        q = (x - p["x_c"]) / p["span"]
        return np.asarray(x + p["span"] * (p["c2"] * q * q + p["c3"] * q**3), dtype=float)

    def slope(self, x: ArrayLike) -> Array:
        """``dy/dx`` (1): the factor by which a small minor loop at level ``x`` is scaled."""
        p = self._params
        q = (np.asarray(x, dtype=float) - p["x_c"]) / p["span"]
        return np.asarray(1 + 2 * p["c2"] * q + 3 * p["c3"] * q * q, dtype=float)

    def inverse(self, y: ArrayLike) -> Array:
        """``x`` with ``self(x) = y`` (Newton iteration; the map must be monotone on the range)."""
        y = np.asarray(y, dtype=float)
        x = y.copy()
        for _ in range(30):
            f = self._run(x) - y
            x = x - f / self.slope(x)
            if np.max(np.abs(f), initial=0.0) < 1e-13 * max(1.0, self._params["span"]):
                break
        return x


class FeedbackBlock(EffectBlock):
    """Base class of the output-feedback blocks (a moving Preisach model; ``side = "feedback"``).

    Such a block is not a filter on a signal: it changes how the Preisach operator is run, so
    :class:`~preisach.diagnose.AugmentedModel` and diagnosis call :meth:`simulate`;
    :meth:`run` is the feedback map from the previous output (V) to the input shift (V).
    """

    side = "feedback"

    def reset(self, x0: float) -> float:
        """Return the input shift (V) for the previous output ``x0`` (V); a static map."""
        return self._static(x0)

    def simulate(
        self, table: Any, u: ArrayLike, state: Any
    ) -> tuple[Array, Array, Any]:  # pragma: no cover - abstract
        """Run the Preisach ``table`` with this feedback; returns ``(y, u_eff, final_state)``."""
        raise NotImplementedError


class SplineFeedback(FeedbackBlock):
    """Non-congruent minor loops: the output feeds back on the relays' input through a spline.

    The relays see ``u_eff = u + f(y_prev)`` with ``f`` a uniform cubic B-spline on
    ``[y_lo, y_hi]`` (``len(coefficients) - 3`` equal intervals; ``f`` is constant outside,
    at its end values): a moving Preisach model (Della Torre, ``H_eff = H + alpha M``) whose
    feedback may be any smooth function of the output - linear (the classical moving model),
    saturating, stronger at one end - rather than one functional form.  Minor loops between
    the same two inputs then differ with the output level they sit at.  The closed loop runs
    in C++ (``preisach._core.simulate_feedback_spline``).

    Parameters
    ----------
    coefficients : sequence of float
        B-spline coefficients (V of input shift), at least 4.  Coefficient ``i`` sits at the
        output ``y_lo + (i - 1) h``, ``h = (y_hi - y_lo) / (len - 3)``; coefficients on a
        straight line give a linear feedback.
    y_lo, y_hi : float
        The output range (V) the spline spans, ``y_hi > y_lo``.

    """

    kind = "non_congruence"
    PARAMS = (("coefficients", "V"), ("y_lo", "V"), ("y_hi", "V"))

    def _set(self, params: dict[str, Any]) -> None:
        c = [_finite(self.kind, "coefficients", v) for v in np.atleast_1d(params["coefficients"])]
        if len(c) < 4:
            raise ValueError(f"{self.kind}: need at least 4 coefficients, got {len(c)}")
        lo = _finite(self.kind, "y_lo", params["y_lo"])
        hi = _finite(self.kind, "y_hi", params["y_hi"])
        if not hi > lo:
            raise ValueError(f"{self.kind}: y_hi ({hi!r}) must lie above y_lo ({lo!r})")
        self._params = {"coefficients": c, "y_lo": lo, "y_hi": hi}
        self._c = np.asarray(c, dtype=float)

    @staticmethod
    def greville(y_lo: float, y_hi: float, n: int) -> Array:
        """Output levels (V) at which the ``n`` coefficients sit (straight lines are exact)."""
        h = (y_hi - y_lo) / (n - 3)
        return np.asarray(y_lo + (np.arange(n) - 1.0) * h)

    def _run(self, x: Array) -> Array:
        p = self._params
        return np.asarray(_core.feedback_spline(x, p["y_lo"], p["y_hi"], self._c))

    def simulate(self, table: Any, u: ArrayLike, state: Any) -> tuple[Array, Array, Any]:
        """Run the Preisach ``table`` with this feedback; returns ``(y, u_eff, final_state)``."""
        p = self._params
        y, ue, fin = _core.simulate_feedback_spline(
            table, np.ascontiguousarray(u, dtype=float), state, p["y_lo"], p["y_hi"], self._c
        )
        return np.asarray(y), np.asarray(ue), fin


class OutputFeedback(FeedbackBlock):
    """Non-congruent minor loops: the output feeds back on the relays' input (Preisach stage).

    The relays see ``u_eff = u + a d + b d^2 / span + c d^3 / span^2``, ``d = y_prev - y_c``
    (the previous output relative to the centre of the output range): a moving Preisach model
    (Della Torre, ``H_eff = H + alpha M``) with a quadratic term (feedback differing between
    the top and the bottom of the range) and a cubic one (feedback saturating or growing
    toward both ends).  Minor loops between the same two inputs
    then differ with the output level they sit at.  This block is not a filter on a signal: it
    changes how the Preisach operator is run, so :class:`~preisach.diagnose.AugmentedModel`
    runs the operator with it (``preisach._core.simulate_moving``); :meth:`run` is the feedback
    map from the previous output to the input shift (V).

    Parameters
    ----------
    a : float
        Linear feedback gain (V of input per V of output).
    b : float
        Quadratic feedback gain (V/V).
    c : float
        Cubic feedback gain (V/V).
    y_c : float
        Centre of the output range (V).
    span : float
        Half-span of the output range (V), > 0.

    """

    kind = "non_congruence"
    side = "feedback"
    PARAMS = (("a", "V/V"), ("b", "V/V"), ("c", "V/V"), ("y_c", "V"), ("span", "V"))
    DOMAIN = {"span": ">0"}

    def reset(self, x0: float) -> float:
        """Return the input shift (V) for the previous output ``x0`` (V); a static map."""
        return self._static(x0)

    def _run(self, x: Array) -> Array:
        p = self._params
        d = x - p["y_c"]
        q = d / p["span"]
        return np.asarray(d * (p["a"] + q * (p["b"] + p["c"] * q)), dtype=float)

    def simulate(self, table: Any, u: ArrayLike, state: Any) -> tuple[Array, Array, Any]:
        """Run the Preisach ``table`` with this feedback; returns ``(y, u_eff, final_state)``."""
        p = self._params
        y, ue, fin = _core.simulate_moving(
            table,
            np.ascontiguousarray(u, dtype=float),
            state,
            p["a"],
            p["b"],
            p["y_c"],
            p["span"],
            p["c"],
        )
        return np.asarray(y), np.asarray(ue), fin


class RateDependentWidth(EffectBlock):
    """Rate-dependent hysteresis: the loop width grows with the input rate (output side).

    ``y = x + c (rho / rho_ref) ** p (x - A(u))``: the hysteretic deviation of the Preisach
    output ``x`` from the model's anhysteretic curve ``A(u)`` (the output of the neutral state
    at the current input) is scaled up by a power of the smoothed input rate ``rho``
    (``|du/dt|`` through a first-order lag ``tau_v``): at higher rates the ascending and
    descending branches lie further apart, as the thesis observed between its 1, 2 and 4 Hz
    identifications.  The block needs the input and the anhysteretic curve besides ``x``
    (:attr:`needs_chain`): diagnosis calls :meth:`apply`,
    :class:`~preisach.diagnose.AugmentedModel` :meth:`apply_chain`; :meth:`run` is not
    available.

    Parameters
    ----------
    c : float
        Relative widening at the reference rate (1).
    exponent : float
        ``p`` (1), >= 0.
    rho_ref : float
        Reference rate (V/s), > 0.
    tau_v : float
        Time constant (s) of the rate smoothing, > 0.

    """

    kind = "rate_dependence"
    side = "output"
    needs_chain = True
    PARAMS = (("c", ""), ("exponent", ""), ("rho_ref", "V/s"), ("tau_v", "s"))
    DOMAIN = {"exponent": ">=0", "rho_ref": ">0", "tau_v": ">0"}

    def reset(self, x0: float) -> float:
        """At rest (rate 0): returns ``x0``."""
        return _finite(self.kind, "x0", x0)

    def _run(self, x: Array) -> Array:
        raise TypeError(
            "rate_dependence (loop width): needs the input and the anhysteretic curve; use apply()"
        )

    def rate_factor(self, u: ArrayLike) -> Array:
        """``(rho / rho_ref) ** p`` for the input samples ``u`` (V), from rest."""
        uu = np.asarray(u, dtype=float)
        v = np.abs(np.diff(uu, prepend=uu[:1])) / self.dt
        rho = _lag(v, math.exp(-self.dt / self._params["tau_v"]), 0.0)
        return np.asarray(
            (np.maximum(rho, 0.0) / self._params["rho_ref"]) ** self._params["exponent"],
            dtype=float,
        )

    def apply(self, x: ArrayLike, u: ArrayLike, anhysteretic: ArrayLike) -> Array:
        """Output (V) for the Preisach output ``x``, the input ``u`` and ``A(u)`` (all V)."""
        xx = np.asarray(x, dtype=float)
        return np.asarray(
            xx
            + self._params["c"]
            * self.rate_factor(u)
            * (xx - np.asarray(anhysteretic, dtype=float)),
            dtype=float,
        )

    def apply_chain(self, x: ArrayLike, u: ArrayLike, state: State, model: Any) -> Array:
        """:meth:`apply` with ``model``'s anhysteretic curve (its neutral locus) at ``u``."""
        grid = np.linspace(model.u_min, model.u_max, 401)
        anh = np.interp(
            np.asarray(u, dtype=float), grid, np.asarray(_core.neutral_locus(model.table, grid))
        )
        return self.apply(x, u, anh)


class ReversibleRelaxation(EffectBlock):
    """Rate-dependent hysteresis from a reversible part that relaxes (output side).

    ``y = x - k (u - z)``, ``tau dz/dt = u - z`` (exact under a zero-order hold, settled at
    the first input): a share ``k`` (V of output per V of input) of the linear, reversible
    response follows the input through a first-order relaxation of time constant ``tau`` -
    the Debye relaxation of the dielectric polarisation behind the intrinsic piezoelectric
    effect.  At an input rate ``du/dt`` the output falls behind by about
    ``k tau du/dt``: the loops widen in proportion to the rate, elliptically, whatever the
    hysteretic state (a delay of the output instead lags by ``tau dy/dt``, in proportion to
    the loop's slope), and a held input settles within a few ``tau``.  The block needs the
    input besides ``x`` (:attr:`needs_chain`): diagnosis calls :meth:`apply`,
    :class:`~preisach.diagnose.AugmentedModel` :meth:`apply_chain`; :meth:`run` is not
    available.

    Parameters
    ----------
    k : float
        Relaxing share of the reversible response (V/V), >= 0.
    tau : float
        Relaxation time constant (s), > 0.

    """

    kind = "rate_dependence"
    side = "output"
    needs_chain = True
    PARAMS = (("k", "V/V"), ("tau", "s"))
    DOMAIN = {"k": ">=0", "tau": ">0"}

    def reset(self, x0: float) -> float:
        """At rest (settled): returns ``x0``."""
        return _finite(self.kind, "x0", x0)

    def _run(self, x: Array) -> Array:
        raise TypeError("rate_dependence (relaxation): needs the input; use apply()")

    def apply(self, x: ArrayLike, u: ArrayLike) -> Array:
        """Output (V) for the Preisach output ``x`` (V) and the input ``u`` (V), from rest."""
        uu = np.asarray(u, dtype=float)
        xx = np.asarray(x, dtype=float)
        if uu.size == 0:
            return xx.copy()
        z = _lag(uu, math.exp(-self.dt / self._params["tau"]), float(uu[0]))
        return np.asarray(xx - self._params["k"] * (uu - z), dtype=float)

    def apply_chain(self, x: ArrayLike, u: ArrayLike, state: State, model: Any) -> Array:
        """:meth:`apply` (the state and model are not needed)."""
        return self.apply(x, u)


class GainOffset(EffectBlock):
    """Calibration error: the output scale and zero differ from the model's (output side).

    ``y = gain * x + offset``.

    Parameters
    ----------
    gain : float
        Scale (1).
    offset : float
        Zero shift (V).

    """

    kind = "gain_offset"
    side = "output"
    PARAMS = (("gain", ""), ("offset", "V"))

    def reset(self, x0: float) -> float:
        """Return ``gain * x0 + offset`` (a static map has no state to reset)."""
        return float(self._params["gain"] * _finite(self.kind, "x0", x0) + self._params["offset"])

    def _run(self, x: Array) -> Array:
        return np.asarray(self._params["gain"] * x + self._params["offset"], dtype=float)


#: EffectBlock classes by class name (several may share a ``kind``: two forms of rate dependence).
EFFECT_TYPES: dict[str, type[EffectBlock]] = {
    c.__name__: c
    for c in (
        SecondOrderMode,
        TwoModes,
        PronyCreep,
        FractionalDelay,
        LagrangeDelay,
        FirstOrderInputLag,
        FirstOrderOutputLag,
        RateDependentPlay,
        RateDependentWidth,
        ReversibleRelaxation,
        SensorDrift,
        LevelDependentGain,
        OutputFeedback,
        SplineFeedback,
        GainOffset,
    )
}


def effect_from_dict(data: dict[str, Any]) -> EffectBlock:
    """Inverse of :meth:`Block.to_dict`."""
    try:
        cls = EFFECT_TYPES[data["type"]]
    except KeyError as exc:
        raise ValueError(
            f"block: unknown type {data.get('type')!r}; known: {sorted(EFFECT_TYPES)}"
        ) from exc
    return cls(float(data["dt"]), **data["params"])
