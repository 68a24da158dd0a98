"""Concealed-effect test cases: a classical Preisach device plus ONE small effect, or none.

A case is what a user would bring to diagnosis: an FOD identification sweep and several other
experiments (wiping-out, CML, multi-frequency sine, step-and-hold, filtered noise) of the
same device, measured with white noise and an ADC's quantisation.  The device is a classical
Preisach model (by default the thesis's SS15 1 Hz model) augmented by one effect whose size
is set so that its RMS contribution on the diagnosis experiments is ``effect_size`` times
the noise standard deviation - invisible on a loop plot.  The sweep carries the effect too, so
a model identified from it has absorbed part of it, as in the laboratory.

The generators use functional forms that differ from diagnosis's candidates on purpose
(the candidate fitted for each kind is given in brackets):

* ``rate_dependence`` - the Everett function scaled by the rate: the output blends the
  model with a *fast* model of the same range whose hysteretic (off-diagonal) relay mass is
  larger and reversible mass smaller, with weight ``s (1 - exp(-rho / rho_0))`` of the
  input rate ``rho = |du/dt|`` low-passed with a time constant ``rho_tau`` drawn
  log-uniformly in 5-100 ms per case [an input lag, a play operator with power-law
  rate-dependent width on the input, or a rate-scaled loop width];
* ``structural_resonance`` - a second-order mode driven by the linearly interpolated
  (first-order hold) Preisach output, solved exactly in continuous time, participation ``s``
  [the same physics discretised exactly under a zero-order hold];
* ``creep`` - the logarithmic creep law: every output move ``dy`` adds
  ``s dy log10(1 + t / t_0)`` afterwards (a convolution; never settles) [a settled gain and
  first-order lags at 0.02, 0.2, 2 and 20 s with free weights];
* ``delay`` - a first-order measurement low-pass of time constant ``s`` acting on the
  continuous (linearly interpolated) output, so its delay at low frequencies is ``s`` [a pure,
  fractional delay];
* ``sensor_drift`` - a slow random offset per recording: a ramp plus three sinusoids of
  random periods (8-60 s) and phases, amplitude ``s`` [a per-recording cubic spline in time];
* ``non_congruence`` - a moving Preisach model with saturating feedback
  ``u_eff[k] = u[k] + s Y tanh((y[k-1] - y_c) / Y)``, with the centre ``y_c`` drawn per case
  anywhere in the middle half of the output range and the saturation scale ``Y`` between 0.2
  and 0.5 of the output span [output feedback with linear, quadratic and cubic terms about
  the *mid* output, so the truth's centre and shape are not the candidate's].

The randomised shape parameters (``rho_tau``, ``y_c``, ``Y``) are drawn independently of the
candidates' fixed constants (the loop-width candidate smooths the rate over
``max(20 ms, 4 dt)``, the feedback candidate expands about the mid output), so a match of the
two is a coincidence of one case, not a property of the proof.

``kind="none"`` makes the null case: the same experiments without any effect.

``generator="rig"`` takes the truth from the virtual SS15 rig instead (:mod:`preisach.daq`,
its C++ blocks :mod:`preisach.daq.blocks`), measured through its DAQ.  Its blocks are largely the
candidates' own forms (an input lag, a second-order mode, a Prony series, a delay, a moving
Preisach stage with linear feedback), so the rig generator is the *same-form check*: it shows
that diagnosis finds and measures an effect whose form it has; the ``own`` generator is the
different-form proof.

* ``rate_dependence`` - ``InputLag``: the amplifier's RC lag before the relays.  This is the
  rig's only rate-dependent mechanism; it widens loops in proportion to the input rate (to
  first order the relays see ``u - tau du/dt``) but is *the same physics* as the candidate's
  ``input_lag`` form, so this is a same-form test (the ``own`` generator's rate-scaled Everett
  function is the different-form one);
* ``structural_resonance`` - ``StructuralMode`` with full participation, damping 0.02-0.08;
  the frequency (80-250 Hz) sets the size, which on these experiments cannot fall below about
  3.5-5 x 1 mV (the ringing after each 40 ms step): smaller targets get a 250 Hz mode;
* ``creep`` - ``Creep``: equal-weight first-order lags one decade apart between ``tau_min``
  (10-100 ms) and ``tau_max`` (10-100 s), a Prony series like the candidate's;
* ``delay`` - a pure ``Delay``, a ``MovingAverage`` or both in series (random form), with the
  rig run at 20 kHz (input interpolated between the 1 kHz samples, as the amplifier smooths the
  DAC's steps; the reading taken at the end of each sample), so that the lag is any multiple
  of 50 us up to 5 ms rather than of the control clock's 1 ms;
* ``sensor_drift`` - ``OffsetDrift``: a rate plus a seeded random walk per recording;
* ``non_congruence`` - the moving Preisach stage ``u_eff = u + k y[k-1]`` with a positive
  gain (the mean-field sign; loop gain at most 0.5 at the steepest point of the major loop).
  A negative gain is absorbed almost entirely by a re-identified classical model (below 2.5 x
  the noise even at -20 V/V on these experiments), so it cannot make a concealed case of the
  requested size.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Union

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from .._io import write_json
from ..model import PreisachModel, State
from ..noise import uniform_filtered_noise
from ..recording import Recording
from ..waveforms import cml_input, fod_sweep, legs, wiping_out_input

if TYPE_CHECKING:  # pragma: no cover
    from ..diagnose import DiagnosisReport

__all__ = ["EFFECT_KINDS", "Case", "case_inputs", "make_case", "physical_checks", "run_case"]

Array = NDArray[np.float64]
PathLike = Union[str, "os.PathLike[str]"]

#: Effect kinds the generator can conceal (``"none"`` is the null case).
EFFECT_KINDS: tuple[str, ...] = (
    "rate_dependence",
    "structural_resonance",
    "creep",
    "delay",
    "sensor_drift",
    "non_congruence",
)


# ----------------------------------------------------------------------------------------
# experiments
# ----------------------------------------------------------------------------------------
def case_inputs(
    scale: float = 1.0,
    *,
    rng: np.random.Generator,
    u_min: float = -100.0,
    u_max: float = 100.0,
    dt: float = 1e-3,
) -> tuple[tuple[str, Array], list[tuple[str, Array]]]:
    """Identification sweep and diagnosis experiments (name, input in V) for one case.

    ``scale = 1`` gives a 20 s FOD sweep (21 levels at 1 Hz) and five experiments of 3-12 s;
    smaller scales shorten everything (``scale = 0.35`` is a quick test case).
    """
    span = u_max - u_min
    n_lev = 21 if scale >= 0.75 else 11
    f_id = 1.0 if scale >= 0.75 else max(1.0, 0.8 / scale)
    sweep = fod_sweep(np.linspace(u_min, u_max, n_lev), frequency=f_id, sample_time=dt).u
    exps: list[tuple[str, Array]] = []
    # triangle legs: sharp reversals tell a lag before the hysteresis (which lowers the extrema
    # the relays see) from a delay after it
    exps.append(
        ("wiping_out", wiping_out_input(2.0, u_min=u_min, sample_time=dt, shape="triangle").u)
    )
    exps.append(
        (
            "cml",
            cml_input(
                2.0,
                u_min=u_min,
                sample_time=dt,
                loop=(u_min + 0.5 * span, u_min + 0.75 * span),
                peak=u_max,
            ).u,
        )
    )
    # minor-loop ladder: the same small loop at five input offsets, reached once from below
    # and once from above (so at two output levels each): congruency under test
    pts = [u_min]
    for direction in (1, -1):
        offs = np.linspace(u_min + 0.2 * span, u_max - 0.2 * span, 5)[::direction]
        for o in offs:
            pts.append(float(o))
            for _ in range(2 if scale >= 0.75 else 1):
                pts += [float(o + 0.08 * span * direction), float(o)]
        pts.append(u_max if direction > 0 else u_min)
    exps.append(("minor_loops", legs(pts, 0.125, sample_time=dt).u))
    # multi-frequency sine, entered from u_min by one cosine leg
    T = 10.0 * scale
    t = np.arange(int(round(T / dt))) * dt
    fr = np.array([0.7, 2.3, 5.1]) * rng.uniform(0.9, 1.1, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    amp = np.array([0.25, 0.12, 0.05]) * span
    ms = (amp[:, None] * np.sin(2 * np.pi * fr[:, None] * t + ph[:, None])).sum(axis=0)
    ms = np.clip(ms, u_min, u_max)
    lead = legs([u_min, ms[0]], 0.3, sample_time=dt).u
    exps.append(("multisine", np.concatenate([lead, ms[1:]])))
    # step and hold: holds of 0.4-1.2 s between fast steps (40 ms cosine ramps, which still
    # excite a structural mode but keep its ringing within the sensor's range and the slope
    # within the rig's 10 kV/s slew limit)
    pts, durs = [u_min], []
    total = 0.0
    while total < T:
        pts.append(float(rng.uniform(u_min + 0.05 * span, u_max - 0.05 * span)))
        hold = float(rng.uniform(0.4, 1.2))
        durs.append(0.04)
        pts.append(pts[-1])
        durs.append(hold)
        total += hold + 0.04
    exps.append(("step_hold", legs(pts, durs, sample_time=dt).u))
    # filtered noise on a slow offset ramp
    noise = uniform_filtered_noise(T, 0.2 * span, sample_time=dt, seed=int(rng.integers(2**31)))
    off = u_min + span * (0.25 + 0.5 * np.linspace(0, 1, noise.size))
    un = np.clip(off + noise, u_min, u_max)
    lead = legs([u_min, un[0]], 0.3, sample_time=dt).u
    exps.append(("noise", np.concatenate([lead, un[1:]])))
    return ("fod_sweep", sweep), exps


# ----------------------------------------------------------------------------------------
# truths (the device's physics)
# ----------------------------------------------------------------------------------------
def _fast_model(model: PreisachModel) -> PreisachModel:
    """Return a model of the same range and outputs: more hysteretic mass, half the reversible."""
    w = model.cell_weights()
    diag = np.diag(np.diag(w))
    off = np.tril(w, -1)
    kappa = 0.5 * diag.sum() / max(off.sum(), 1e-300)
    return PreisachModel.from_weights(
        model.levels, off * (1 + kappa) + 0.5 * diag, y_min=model.y_min
    )


def _lowpass(x: Array, tau: float, dt: float) -> Array:
    e = math.exp(-dt / tau)
    y, _ = signal.lfilter([1 - e], [1, -e], x, zi=[e * x[0]])
    return np.asarray(y, dtype=np.float64)


def _mode_foh(x: Array, fn: float, zeta: float, dt: float) -> Array:
    """Exact continuous response of the mode to the linearly interpolated input (FOH)."""
    wn = 2 * math.pi * fn
    sys = signal.lti([wn * wn], [1.0, 2 * zeta * wn, wn * wn])
    t = np.arange(x.size) * dt
    # start at rest at x[0]: simulate the deviation from x[0]
    _, y, _ = signal.lsim(sys, x - x[0], t, interp=True)
    return np.asarray(y, dtype=np.float64) + float(x[0])


def _lag_foh(x: Array, tau: float, dt: float) -> Array:
    """First-order lag of the linearly interpolated signal, exact (its delay is ``tau``)."""
    e = math.exp(-dt / tau)
    # exact recursion for a piecewise-linear input: z_k = e z_{k-1} + b0 x_k + b1 x_{k-1}
    q = tau / dt * (1 - e)
    b0, b1 = 1 - q, q - e
    y, _ = signal.lfilter([b0, b1], [1.0, -e], x, zi=[(1 - b0) * x[0]])
    return np.asarray(y, dtype=np.float64)


def _log_creep(y: Array, t0: float, dt: float) -> Array:
    dy = np.diff(y, prepend=y[0])
    kern = np.log10(1 + np.arange(y.size) * dt / t0)
    return np.asarray(signal.fftconvolve(dy, kern)[: y.size], dtype=np.float64)


def _moving(
    model: PreisachModel, u: Array, state: State, a: float, yc: float, span: float
) -> Array:
    """Simulate a moving model with feedback ``u_eff = u + a span tanh((y_prev - yc) / span)``.

    ``a`` is the feedback's slope at ``yc`` (V/V), ``yc`` its centre and ``span`` its
    saturation scale (V).
    """
    sim = model.simulator(state)
    y = np.empty_like(u)
    prev = model.readout(state)
    lo, hi = model.u_min, model.u_max
    step = sim.step
    for k in range(u.size):
        ue = min(max(u[k] + a * span * math.tanh((prev - yc) / span), lo), hi)
        prev = step(ue)
        y[k] = prev
    return y


@dataclass
class _Truth:
    kind: str
    model: PreisachModel
    params: dict[str, float]
    dt: float
    rng_seed: int
    fast: PreisachModel | None = None

    def simulate(self, u: Array, strength: float, index: int) -> Array:
        m, p, dt = self.model, self.params, self.dt
        s0 = m.negative_saturation()
        if self.kind == "non_congruence" and strength != 0:
            return _moving(m, u, s0, strength, p["y_c"], p["Y"])
        y = m.simulate(u, s0, sample_time=dt).output
        if self.kind == "none" or strength == 0:
            return y
        if self.kind == "rate_dependence":
            assert self.fast is not None
            yf = self.fast.simulate(u, s0, sample_time=dt).output
            rho = _lowpass(np.abs(np.gradient(u, dt)), p["rho_tau"], dt)
            w = strength * (1 - np.exp(-rho / p["rho_0"]))
            return y + w * (yf - y)
        if self.kind == "structural_resonance":
            return y + strength * (_mode_foh(y, p["f_n"], p["zeta"], dt) - y)
        if self.kind == "creep":
            return y + strength * _log_creep(y, p["t0"], dt)
        if self.kind == "delay":
            return _lag_foh(y, strength, dt)
        if self.kind == "sensor_drift":
            rng = np.random.default_rng(self.rng_seed + 7919 * index)
            t = np.arange(u.size) * dt
            d = rng.uniform(-1, 1) * t / max(float(t[-1]), dt)
            for _ in range(3):
                per = rng.uniform(8.0, 60.0)
                d = d + rng.uniform(0.3, 1.0) * np.sin(
                    2 * np.pi * t / per + rng.uniform(0, 2 * np.pi)
                )
            return y + strength * d
        raise ValueError(f"kind: unknown effect {self.kind!r}")  # pragma: no cover


def _truth_params(kind: str, rng: np.random.Generator, model: PreisachModel) -> dict[str, float]:
    """Random shape parameters of an ``own`` truth (units: V/s, s, Hz, V)."""
    if kind == "rate_dependence":
        return {
            "rho_0": float(rng.uniform(150.0, 600.0)),
            "rho_tau": float(10 ** rng.uniform(math.log10(5e-3), math.log10(0.1))),
        }
    if kind == "structural_resonance":
        return {"f_n": float(rng.uniform(25.0, 60.0)), "zeta": float(rng.uniform(0.01, 0.05))}
    if kind == "creep":
        return {"t0": float(rng.uniform(0.01, 0.1))}
    if kind == "sensor_drift":
        return {}
    if kind == "non_congruence":
        lo, span = model.y_min, model.y_max - model.y_min
        return {
            "sign": float(rng.choice([-1.0, 1.0])),
            "y_c": float(lo + span * rng.uniform(0.25, 0.75)),
            "Y": float(span * rng.uniform(0.2, 0.5)),
        }
    if kind in ("delay", "none"):
        return {}
    raise ValueError(f"kind: expected one of {EFFECT_KINDS + ('none',)}, got {kind!r}")


# ----------------------------------------------------------------------------------------
# cases
# ----------------------------------------------------------------------------------------
@dataclass
class Case:
    """A concealed-effect case: identification sweep, diagnosis recordings and the truth."""

    kind: str
    identification: Recording
    recordings: list[Recording]
    truth: dict[str, Any] = field(default_factory=dict)
    #: The simulated device as ``(truth, strength)`` (set by :func:`make_case`, not saved by
    #: :meth:`save`): :func:`physical_checks` measures the true effect with it on test inputs.
    device: tuple[_Truth | _RigTruth, float] | None = field(default=None, repr=False, compare=False)

    def identify(self, levels: int | None = None) -> PreisachModel:
        """Identify a model from the sweep (Mayergoyz: :func:`preisach.identify.identify_fod`).

        Parameters
        ----------
        levels : int, optional
            Number of equally spaced FOD levels (V grid); default inferred from the sweep.

        """
        from ..identify import identify_fod

        return identify_fod(self.identification, levels, name="identified from FOD sweep").model

    def save(self, folder: PathLike) -> None:
        """Write ``identification.npz``, one ``<name>.npz`` per experiment and ``truth.json``."""
        d = Path(folder)
        d.mkdir(parents=True, exist_ok=True)
        self.identification.save(d / "identification.npz")
        names: list[str] = []
        for r in self.recordings:
            nm = str(r.metadata.get("experiment", f"rec{len(names)}"))
            r.save(d / f"{nm}.npz")
            names.append(nm)
        write_json(
            d / "truth.json", {"kind": self.kind, "recordings": names, **self.truth}, indent=2
        )

    @classmethod
    def load(cls, folder: PathLike) -> Case:
        """Read a case folder written by :meth:`save`."""
        d = Path(folder)
        info = json.loads((d / "truth.json").read_text())
        recs = [Recording.load(d / f"{n}.npz") for n in info.pop("recordings")]
        kind = info.pop("kind")
        return cls(kind, Recording.load(d / "identification.npz"), recs, info)


def _quantise(
    y: Array, rng: np.random.Generator, sigma: float, bits: int, rng_v: tuple[float, float]
) -> Array:
    lsb = (rng_v[1] - rng_v[0]) / 2**bits
    yn = y + rng.normal(0.0, sigma, y.size)
    return np.asarray(np.clip(np.round(yn / lsb) * lsb, rng_v[0], rng_v[1] - lsb), dtype=np.float64)


def make_case(
    kind: str,
    *,
    effect_size: float = 3.0,
    seed: int = 0,
    sigma: float = 1e-3,
    adc_bits: int = 14,
    adc_range: tuple[float, float] = (-10.0, 10.0),
    scale: float = 1.0,
    model: PreisachModel | None = None,
    dt: float = 1e-3,
    generator: str = "own",
    min_duration: float = 0.0,
) -> Case:
    """Build one case.

    Parameters
    ----------
    kind : str
        One of :data:`EFFECT_KINDS` or ``"none"``.
    effect_size : float
        Size of the effect in units of the noise standard deviation ``sigma``: the RMS (on the
        diagnosis experiments) of the part of the effect that no classical Preisach model can
        absorb - the excess residual of the best least-squares Preisach fit (41 levels,
        fitted to the sweep and all experiments, clean data) over the same fit without the
        effect.  The raw RMS of the effect (``truth["effect_rms"]``) is larger: the rest is
        absorbed by any identification.  Ignored for ``"none"``.
    seed : int
        Seeds the effect's parameters, the experiments and the noise.
    sigma : float
        White measurement noise standard deviation (V).
    adc_bits, adc_range : int, (float, float)
        Quantisation of the measured output: ``adc_bits`` over ``adc_range`` (V).
    scale : float
        Duration scale of the experiments (1: 20 s sweep, experiments up to 12 s).
    model : PreisachModel, optional
        The device's classical part; default the built-in ``ss15-1hz``.
    dt : float
        Sample time (s).
    min_duration : float
        Repeat every experiment's input until it lasts at least this long (s).
    generator : {"own", "rig"}
        ``"own"``: this module's truths (forms unlike the candidates, see the module
        docstring).  ``"rig"``: the virtual SS15 rig of :mod:`preisach.daq` with its physics
        blocks (see the module docstring), measured through the rig's ADC (noise ``sigma``,
        ``adc_bits`` over its input channel; ``adc_range`` is then unused).  The size actually
        reached is stored in ``truth["effect_size"]``: a delay case's lag is a whole number of
        50 us steps, and a rig mode cannot be made smaller than about 3.5 x 1 mV.

    Returns
    -------
    Case
        ``truth`` holds the kind, the generator's parameters, the strength, the effect's
        raw RMS and its unexplainable RMS (V) on the diagnosis experiments.

    """
    if kind != "none" and kind not in EFFECT_KINDS:
        raise ValueError(f"kind: expected one of {EFFECT_KINDS + ('none',)}, got {kind!r}")
    if not (effect_size > 0 or kind == "none"):
        raise ValueError(f"effect_size: must be > 0, got {effect_size!r}")
    if generator not in ("own", "rig"):
        raise ValueError(f"generator: expected 'own' or 'rig', got {generator!r}")
    rng = np.random.default_rng(seed)
    dev = model if model is not None else PreisachModel.builtin("ss15-1hz", levels=101)
    truth: _Truth | _RigTruth
    params: dict[str, Any]
    if generator == "rig":
        truth = _RigTruth(kind, dev, _rig_params(kind, rng), dt, int(rng.integers(2**31)))
        params = truth.params
    else:
        params = _truth_params(kind, rng, dev)
        truth = _Truth(
            kind,
            dev,
            params,
            dt,
            int(rng.integers(2**31)),
            _fast_model(dev) if kind == "rate_dependence" else None,
        )
    (sw_name, sw_u), exps = case_inputs(scale, rng=rng, u_min=dev.u_min, u_max=dev.u_max, dt=dt)
    if min_duration > 0:
        exps = [(n, np.tile(u, int(math.ceil(min_duration / (u.size * dt))))) for n, u in exps]
    all_u = [sw_u] + [u for _, u in exps]
    clean = [truth.simulate(u, 0.0, i) for i, u in enumerate(all_u)]
    fit = _ClassicalFit(dev, all_u)
    base_mse = fit.residual_mse(clean)

    def effect_rms(s: float) -> float:
        d = np.concatenate(
            [truth.simulate(u, s, i) - c for i, (u, c) in enumerate(zip(all_u, clean)) if i > 0]
        )
        return float(np.sqrt(np.mean(d * d)))

    def unexplained_rms(s: float) -> float:
        ys = [truth.simulate(u, s, i) for i, u in enumerate(all_u)]
        return float(np.sqrt(max(fit.residual_mse(ys) - base_mse, 0.0)))

    strength = 0.0
    rms = unexpl = 0.0
    if kind != "none":
        target = effect_size * sigma
        sign = params.get("sign", 1.0)
        if isinstance(truth, _RigTruth) and kind == "structural_resonance":
            # full participation: the frequency sets the size (a lower mode rings more)
            lo, hi = _RIG_MODE_BAND
            inv = _solve_strength(lambda s: unexplained_rms(min(1.0 / s, hi)), target, 1.0 / hi)
            strength = float(np.clip(1.0 / inv, lo, hi))
        elif isinstance(truth, _RigTruth) and kind == "delay":
            n_max = int(round(_RIG_MAX_LAG / dt * _RIG_OVERSAMPLE))
            strength = float(_closest_integer(unexplained_rms, target, n_max))
        else:
            start = _RIG_START[kind] if isinstance(truth, _RigTruth) else _START[kind]
            strength = _solve_strength(lambda s: unexplained_rms(sign * s), target, start)
            if isinstance(truth, _RigTruth) and kind == "non_congruence":
                strength = min(strength, _moving_gain_cap(dev))
            strength *= sign
        rms, unexpl = effect_rms(strength), unexplained_rms(strength)
    recs = []
    for i, (name, u) in enumerate([(sw_name, sw_u), *exps]):
        if isinstance(truth, _RigTruth):
            ym = truth.measure(u, strength, i, sigma, adc_bits, int(rng.integers(2**31)))
        else:
            ym = _quantise(truth.simulate(u, strength, i), rng, sigma, adc_bits, adc_range)
        recs.append(
            Recording.from_arrays(
                u=u,
                y=ym,
                sample_time=dt,
                experiment=name,
                metadata={"initial_state": "negative_saturation"},
            )
        )
    if isinstance(truth, _RigTruth):
        params = {**params, **truth.describe(strength)}
    info = {
        "generator": generator,
        "strength": strength,
        "params": params,
        "effect_rms": rms,
        "unexplained_rms": unexpl,
        "effect_size": unexpl / sigma if kind != "none" else 0.0,
        "target_size": effect_size,
        "sigma": sigma,
        "seed": seed,
        "adc_bits": adc_bits,
        "scale": scale,
    }
    return Case(kind, recs[0], recs[1:], info, device=(truth, strength))


def run_case(
    kind: str,
    *,
    generator: str = "own",
    seed: int = 0,
    effect_size: float = 3.0,
    sigma: float = 1e-3,
    scale: float = 1.0,
    cv: str = "auto",
    max_effects: int = 3,
) -> dict[str, Any]:
    """Make a case, identify a model from its sweep, diagnose the rest; the outcome as a dict.

    Parameters
    ----------
    kind, generator, seed, effect_size, sigma, scale
        As for :func:`make_case` (``effect_size`` in units of ``sigma``; ``sigma`` in V).
    cv, max_effects
        As for :func:`preisach.diagnose.diagnose`.

    Returns
    -------
    dict
        JSON-friendly: ``kind``, ``generator``, ``seed``, ``size`` (effect size reached, in
        units of ``sigma``), ``sigma`` (V), ``verdict``, ``effects`` (names in the order kept),
        ``gain`` (relative held-out RMSE reduction of the first effect, 0 without one),
        ``params`` (the first effect's fitted values, units as in the report), ``rmse_before``
        and ``rmse_after`` (V), ``baseline_rmse`` (V: the held-out RMSE of diagnosis's own
        baseline, the base model refitted on the training blocks without any effect) and
        ``baseline_ratio`` (that over ``sigma``: about ``sqrt(1 + size**2)`` if the baseline
        saw exactly the calibrated effect size, more when the effect is harder to absorb on
        the training blocks than in the calibration's 41-level fit on all clean data),
        ``checks`` (:func:`physical_checks`), ``truth`` (:attr:`Case.truth`), ``seconds``
        (wall time, s) and ``summary`` (the report's text).

    """
    from ..diagnose import diagnose

    t0 = time.perf_counter()
    case = make_case(
        kind, effect_size=effect_size, seed=seed, sigma=sigma, scale=scale, generator=generator
    )
    rep = diagnose(
        case.identify(),
        case.recordings,
        identification=case.identification,
        cv=cv,
        max_effects=max_effects,
        progress=False,  # a study runs many cases, each in its own process: it shows its own bar
    )
    first = rep.effects[0] if rep.effects else None
    step1 = [c for c in rep.candidates if c["step"] == 1]
    base_rmse = float(step1[0]["baseline_rmse"]) if step1 else float(rep.rmse_before)
    return {
        "kind": kind,
        "generator": generator,
        "seed": seed,
        "size": float(case.truth["effect_size"]),
        "sigma": sigma,
        "verdict": rep.verdict,
        "effects": [e.name for e in rep.effects],
        "gain": 1 - first.heldout_rmse_after / first.heldout_rmse_before if first else 0.0,
        "params": {
            k: float(v["value"])
            for k, v in (first.parameters.items() if first else ())
            if isinstance(v, dict) and "value" in v
        },
        "rmse_before": rep.rmse_before,
        "rmse_after": rep.rmse_after,
        "baseline_rmse": base_rmse,
        "baseline_ratio": base_rmse / sigma,
        "checks": physical_checks(case, rep),
        "truth": case.truth,
        "seconds": time.perf_counter() - t0,
        "summary": rep.summary(),
    }


# ----------------------------------------------------------------------------------------
# physically meaningful comparison of a fitted effect with the truth
# ----------------------------------------------------------------------------------------
def _triangle(f: float, periods: int, model: PreisachModel, dt: float) -> Array:
    """Major-loop triangle wave from ``u_min`` at ``f`` Hz (V)."""
    t = np.arange(int(round(periods / f / dt)) + 1) * dt
    ph = (f * t) % 1.0
    return np.asarray(
        model.u_min + (model.u_max - model.u_min) * (1 - np.abs(2 * ph - 1)), dtype=np.float64
    )


def _mid_width(u: Array, y: Array, n_last: int) -> float:
    """Loop width (V) at mid input over the last ``n_last`` samples: descending - ascending."""
    u, y = u[-n_last:], y[-n_last:]
    mid = 0.5 * (u.min() + u.max())
    du = np.diff(u, prepend=u[0])
    up, dn = du > 0, du < 0
    y_up = np.interp(mid, u[up], y[up])
    o = np.argsort(u[dn])
    y_dn = np.interp(mid, u[dn][o], y[dn][o])
    return float(y_dn - y_up)


def _rate_widening(sim: Callable[[Array], Array], model: PreisachModel, dt: float) -> float:
    """Major-loop width at mid input at 1 Hz minus that at 0.05 Hz (V), second period."""
    w = []
    for f in (1.0, 0.05):
        u = _triangle(f, 2, model, dt)
        w.append(_mid_width(u, sim(u), int(round(1 / f / dt))))
    return w[0] - w[1]


def _creep_movement(sim: Callable[[Array], Array], model: PreisachModel, dt: float) -> float:
    """Output movement (V) from 50 ms to 1 s after a 40 ms step from ``u_min`` to 60 % span."""
    span = model.u_max - model.u_min
    u = legs(
        [model.u_min, model.u_min, model.u_min + 0.6 * span, model.u_min + 0.6 * span],
        [0.3, 0.04, 1.2],
        sample_time=dt,
    ).u
    y = sim(u)
    k_end = int(round(0.34 / dt))
    return float(y[k_end + int(round(1.0 / dt))] - y[k_end + int(round(0.05 / dt))])


def _feedback_slope(f: Callable[[Array], Array], model: PreisachModel) -> float:
    """Secant slope (V/V) of a feedback map over 10-90 % of the output range."""
    y = model.y_min + (model.y_max - model.y_min) * np.array([0.1, 0.9])
    v = f(y)
    return float((v[1] - v[0]) / (y[1] - y[0]))


def physical_checks(case: Case, report: DiagnosisReport) -> dict[str, dict[str, float]]:
    """Physically meaningful quantities of the verdict's effect: fitted and true values.

    The forms of the truth and the candidates differ (see the module docstring), so their
    parameters are compared through what they do, measured identically on both the device
    (:attr:`Case.device`) and the diagnosed model restricted to the verdict's blocks:

    * ``delay``: ``lag`` (s), the fitted delay vs the truth's low-frequency lag;
    * ``structural_resonance``: ``f_n`` (Hz), ``zeta`` (1) and ``participation`` (1): the
      share of a step that arrives through the ring, ``m + r`` for a fit with a reaction;
    * ``creep``: ``creep_50ms_1s`` (V), the output's movement from 50 ms to 1 s after a
      40 ms step from ``u_min`` to 60 % of the input span;
    * ``rate_dependence``: ``widening`` (V), the major loop's width at mid input at 1 Hz
      minus that at 0.05 Hz (triangle waves);
    * ``sensor_drift``: ``peak_to_peak`` (V), the largest drift peak-to-peak over the
      diagnosis recordings;
    * ``non_congruence``: ``feedback_slope`` (V/V), the secant slope of the output feedback
      on the relays' input over 10-90 % of the output range.

    Parameters
    ----------
    case : Case
        A case made by :func:`make_case` (``case.device`` set).
    report : DiagnosisReport
        Its diagnosis.

    Returns
    -------
    dict
        ``{quantity: {"fitted": value, "truth": value}}``; empty when the verdict is not the
        case's kind, for ``"none"``, or without ``case.device``.

    """
    from ..diagnose.augmented import AugmentedModel

    kind = case.kind
    if case.device is None or kind == "none" or report.verdict != kind:
        return {}
    truth, strength = case.device
    dev, dt = truth.model, truth.dt
    p = {k: v["value"] for k, v in report.effects[0].parameters.items() if "value" in v}
    aug = report.model
    mine = AugmentedModel(aug.base, [b for b in aug.blocks if b.kind == kind])

    def fitted(u: Array) -> Array:
        return np.asarray(mine.simulate(u, mine.negative_saturation(), sample_time=dt).output)

    def true(u: Array) -> Array:
        return np.asarray(truth.simulate(u, strength, 0))

    rig = isinstance(truth, _RigTruth)
    out: dict[str, dict[str, float]] = {}

    def put(name: str, f: float, t: float) -> None:
        out[name] = {"fitted": float(f), "truth": float(t)}

    if kind == "delay":
        lag = truth.describe(strength)["lag"] if isinstance(truth, _RigTruth) else strength
        put("lag", p["tau"], lag)
    elif kind == "structural_resonance":
        if isinstance(truth, _RigTruth):
            mode = truth.blocks(strength, 0)[1][0]
            f_n, zeta, part = mode["frequency"], mode["damping"], 1.0
        else:
            f_n, zeta, part = truth.params["f_n"], truth.params["zeta"], strength
        put("f_n", p["f_n"], f_n)
        put("zeta", p["zeta"], zeta)
        # the share of a step that arrives through the ring (m + r: the reaction form's m alone
        # is set by the numerator's small s-term and trades off with r when lightly damped)
        put("participation", p["participation"] + p.get("reaction", 0.0), part)
    elif kind == "creep":
        put("creep_50ms_1s", _creep_movement(fitted, dev, dt), _creep_movement(true, dev, dt))
    elif kind == "rate_dependence":
        put("widening", _rate_widening(fitted, dev, dt), _rate_widening(true, dev, dt))
    elif kind == "sensor_drift":
        p2p = [
            np.ptp(truth.simulate(r.u, strength, i) - truth.simulate(r.u, 0.0, i))
            for i, r in enumerate(case.recordings, start=1)
        ]
        put("peak_to_peak", p["peak_to_peak"], max(p2p))
    elif kind == "non_congruence":
        fb = [b for b in mine.blocks if b.kind == kind][0]
        if rig:
            slope = strength
        else:
            a, yc, Y = strength, truth.params["y_c"], truth.params["Y"]
            slope = _feedback_slope(lambda y: a * Y * np.tanh((y - yc) / Y), dev)
        put("feedback_slope", _feedback_slope(fb.run, dev), slope)
    return out


# ----------------------------------------------------------------------------------------
# the virtual rig's physics blocks as truth
# ----------------------------------------------------------------------------------------
#: Delay cases run the rig at 20 times the recording's sample rate (input held over each
#: recording sample, as a DAC does; output read at the end of each): the measurement chain's
#: latency is then a multiple of 50 us rather than of the 1 ms control clock.
_RIG_OVERSAMPLE = 20
#: Forms of the rig's measurement lag: a pure delay, a moving average, or both in series.
_RIG_LAG_FORMS = ("delay", "moving_average", "delay_and_average")
#: Largest lag (s) of a delay case: the thesis's 10-sample moving average at 1 kHz lags 4.5 ms.
_RIG_MAX_LAG = 5e-3
_RIG_START = {"rate_dependence": 1e-4, "creep": 1e-3, "sensor_drift": 1e-3, "non_congruence": 1.0}
#: Structural-mode frequencies (Hz) of rig cases: below 80 Hz the mode rings the sensor out
#: of its range on these experiments' 40 ms steps, above 250 Hz it is hardly excited.
_RIG_MODE_BAND = (80.0, 250.0)
_LEAD_IN = 0.3  # s held at u_min before each recording (after a ramp down from the rig's reset)


def _rig_params(kind: str, rng: np.random.Generator) -> dict[str, Any]:
    if kind == "structural_resonance":  # the frequency is then set by the effect size
        return {"damping": float(rng.uniform(0.02, 0.08))}
    if kind == "creep":
        return {
            "tau_min": float(10 ** rng.uniform(-2, -1)),
            "tau_max": float(10 ** rng.uniform(1, 2)),
        }
    if kind == "sensor_drift":
        return {"rate_share": float(rng.uniform(-1, 1)), "sigma_share": float(rng.uniform(0.2, 1))}
    if kind == "delay":
        return {"form": str(rng.choice(_RIG_LAG_FORMS))}
    if kind in ("rate_dependence", "non_congruence", "none"):
        return {}
    raise ValueError(f"kind: expected one of {EFFECT_KINDS + ('none',)}, got {kind!r}")


def _moving_gain_cap(model: PreisachModel) -> float:
    """Largest rig moving gain (V/V): loop gain 0.5 at the steepest point of the major loop.

    The rig's moving stage feeds ``k y[k-1]`` back to the relays' input; with
    ``k dy/du >= 1`` the loop would snap (a positive-feedback jump), so cases stay well below.
    """
    u = np.concatenate([np.linspace(model.u_min, model.u_max, 2001)] * 2)
    u[2001:] = u[2001:][::-1]
    y = model.simulate(u, model.negative_saturation()).output
    du = np.diff(u)
    ok = du != 0
    return 0.5 / float(np.max(np.abs(np.diff(y)[ok] / du[ok])))


@dataclass
class _RigTruth:
    kind: str
    model: PreisachModel
    params: dict[str, Any]
    dt: float
    rng_seed: int

    @property
    def oversample(self) -> int:
        return _RIG_OVERSAMPLE if self.kind == "delay" else 1

    def blocks(
        self, strength: float, index: int
    ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], float]:
        """Input blocks, output blocks and moving gain of the rig for ``strength``."""
        p, k = self.params, self.kind
        if k == "none" or strength == 0:
            return [], [], 0.0
        if k == "rate_dependence":
            return [{"kind": "input_lag", "time_constant": strength}], [], 0.0
        if k == "structural_resonance":  # strength = frequency (Hz), full participation
            return (
                [],
                [{"kind": "structural_mode", "frequency": strength, "damping": p["damping"]}],
                0.0,
            )
        if k == "creep":
            return (
                [],
                [
                    {
                        "kind": "creep",
                        "rate": strength,
                        "tau_min": p["tau_min"],
                        "tau_max": p["tau_max"],
                    }
                ],
                0.0,
            )
        if k == "delay":  # strength = lag in samples of the oversampled rig
            s = int(round(strength))
            if p["form"] == "delay":
                return [], [{"kind": "delay", "samples": s}], 0.0
            if p["form"] == "moving_average":  # lags (length - 1) / 2 samples
                return [], [{"kind": "moving_average", "length": 2 * s + 1}], 0.0
            d = s // 2
            return (
                [],
                [
                    {"kind": "delay", "samples": d},
                    {"kind": "moving_average", "length": 2 * (s - d) + 1},
                ],
                0.0,
            )
        if k == "sensor_drift":
            return (
                [],
                [
                    {
                        "kind": "offset_drift",
                        "rate": strength * p["rate_share"],
                        "sigma": strength * p["sigma_share"],
                        "seed": self.rng_seed + 7919 * index,
                    }
                ],
                0.0,
            )
        if k == "non_congruence":
            return [], [], strength
        raise ValueError(f"kind: unknown effect {k!r}")  # pragma: no cover

    def describe(self, strength: float) -> dict[str, Any]:
        """Describe the rig's blocks for ``strength`` (and a delay case's lag in seconds)."""
        ins, outs, g = self.blocks(strength, 0)
        d: dict[str, Any] = {
            "input_blocks": ins,
            "output_blocks": [{k: v for k, v in b.items() if k != "seed"} for b in outs],
            "block_sample_time": self.dt / self.oversample,
        }
        if g:
            d["moving_gain"] = g
        if self.kind == "delay" and strength:
            d["lag"] = round(strength) * self.dt / self.oversample
        return d

    def _fine(self, u: Array) -> tuple[Array, float]:
        """Return the input at the rig's rate after the lead-in (V) and the rig's sample time (s).

        Oversampled, the input is interpolated linearly between the recording's samples (the
        amplifier smooths the DAC's steps), so that sample ``k`` is reached at the end of
        its interval, where the reading is taken.
        """
        q = self.oversample
        dtf = self.dt / q
        m = self.model
        lead = np.concatenate(
            [
                legs([0.0, m.u_min], 0.5, sample_time=dtf).u,  # from the rig's reset at 0 V
                np.full(int(round(_LEAD_IN / dtf)), m.u_min),
            ]
        )
        if q > 1:
            u = np.interp(np.arange(u.size * q) - (q - 1), np.arange(u.size) * q, u)
        return np.concatenate([lead, u]), dtf

    def _coarse(self, y: Array, n: int) -> Array:
        """Pick the reading at the end of every recording sample."""
        q = self.oversample
        return np.asarray(y)[y.size - n * q :][q - 1 :: q]

    def simulate(self, u: Array, strength: float, index: int) -> Array:
        """Clean plant output (V): the rig's block chain without the DAQ."""
        from ..daq.blocks import BlockChain, make_block, preisach_stage

        ins, outs, g = self.blocks(strength, index)
        uf, dtf = self._fine(u)
        m = self.model
        chain = BlockChain(
            [
                *(make_block(b, dtf) for b in ins),
                preisach_stage(m, m.anhysteretic_state(), dtf, g),
                *(make_block(b, dtf) for b in outs),
            ]
        )
        chain.reset(0.0)
        return self._coarse(np.asarray(chain.run(uf)), u.size)

    def measure(
        self, u: Array, strength: float, index: int, sigma: float, bits: int, seed: int
    ) -> Array:
        """Output (V) measured through the virtual rig (DAC, amplifier, plant, noisy ADC)."""
        from ..daq import DevicePlant, virtual_ss15

        ins, outs, g = self.blocks(strength, index)
        uf, dtf = self._fine(u)
        rig = virtual_ss15(
            self.model,
            "anhysteretic",
            sample_time=dtf,
            input_blocks=ins,
            output_blocks=outs,
            moving_gain=g,
            adc_noise=sigma,
            adc_bits=bits,
            seed=seed,
        )
        with tempfile.TemporaryDirectory(prefix="preisach-case-") as folder:
            plant = DevicePlant(rig, record_dir=folder)
            return self._coarse(np.asarray(plant.run_open_loop(uf)), u.size)


class _ClassicalFit:
    """Best classical Preisach model (least squares, 41 levels) for outputs of fixed inputs."""

    def __init__(self, model: PreisachModel, inputs: list[Array], n_levels: int = 41) -> None:
        import scipy.sparse as sp

        from .. import _core

        lv = np.linspace(model.u_min, model.u_max, n_levels)
        p = n_levels * (n_levels - 1) // 2 + 1
        self.R = []
        for u in inputs:
            indptr, idx, data, _ = _core.regressor_rows(lv, u, model.negative_saturation(), "clamp")
            self.R.append(sp.csr_matrix((data, idx.astype(np.int64), indptr), shape=(u.size, p)))
        N = sum((R.T @ R).toarray() for R in self.R)
        N[np.diag_indices(p)] += 1e-9 * np.trace(N) / p
        from scipy import linalg

        self._cho = linalg.cho_factor(N)

    def residual_mse(self, outputs: list[Array]) -> float:
        """Mean-square residual (V^2) on all but the first input (the sweep) after the joint fit."""
        from scipy import linalg

        rhs = sum(R.T @ y for R, y in zip(self.R, outputs))
        theta = linalg.cho_solve(self._cho, rhs)
        res = np.concatenate([y - R @ theta for R, y in zip(self.R[1:], outputs[1:])])
        return float(np.mean(res * res))


_START = {
    "rate_dependence": 0.05,
    "structural_resonance": 0.1,
    "creep": 0.002,
    "delay": 2e-4,
    "sensor_drift": 2e-3,
    "non_congruence": 0.5,
}


def _closest_integer(f: Callable[[float], float], target: float, n_max: int) -> int:
    """Integer ``s`` in ``[1, n_max]`` with ``f(s)`` closest to ``target`` on a log scale.

    ``f`` must be increasing; bisection for the first ``s`` with ``f(s) >= target``, then the
    closer of it and its predecessor.
    """
    lo, hi = 1, n_max
    if f(float(lo)) >= target:
        return lo
    if f(float(hi)) < target:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if f(float(mid)) >= target:
            hi = mid
        else:
            lo = mid
    d_lo = abs(math.log(max(f(float(lo)), 1e-300) / target))
    d_hi = abs(math.log(max(f(float(hi)), 1e-300) / target))
    return lo if d_lo < d_hi else hi


def _solve_strength(f: Callable[[float], float], target: float, s0: float) -> float:
    """Positive ``s`` with ``f(s) = target`` for an increasing ``f`` (bracketing on a log scale)."""
    lo, hi = 0.0, s0
    for _ in range(40):
        if f(hi) >= target:
            break
        lo, hi = hi, hi * 3
    for _ in range(30):
        mid = 0.5 * (lo + hi) if lo == 0 else math.sqrt(lo * hi)
        if f(mid) < target:
            lo = mid
        else:
            hi = mid
        if hi - lo < 2e-3 * hi:
            break
    return 0.5 * (lo + hi)
