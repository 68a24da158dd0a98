r"""A rate-dependent Preisach model: Everett tables blended by a filtered input rate.

.. math::

    y(t) = \sum_k b_k(v(t))\, \Gamma_k(\psi(t)), \qquad
    v(t) = v(t-1) + \left(1 - e^{-\Delta t/\tau}\right)\left(\frac{|u(t) - u(t-1)|}{\Delta t}
    - v(t-1)\right)

* ``psi`` is the ordinary Preisach boundary: it depends on the input history only, so the
  ``K`` tables share one boundary (one :class:`~preisach.State`);
* ``Gamma_k`` is the read-out of Everett table ``k`` (all tables on one grid of levels);
* ``v`` (V/s) is a causal first-order low-pass of the input rate ``|du/dt|`` with time
  constant ``tau`` (s); ``tau = 0`` uses the rate of the last step;
* ``b_k`` are hat functions of linear interpolation on the rate knots ``v_0 < ... < v_{K-1}``
  (V/s), in ``ln v`` (``scale="log"``) or in ``v`` (``scale="linear"``), constant outside them
  (below ``v_0`` only table 0 counts, above ``v_{K-1}`` only the last): a partition of unity, so
  at a constant rate the model *is* the classical one with the blended table ``sum_k b_k(v)
  E_k``, and with one table it is the classical model.

**Which scale.**  Between knots the data decide.  The thesis's three SS15 surfaces (Table 3.1)
say the Everett function is close to linear in the rate itself: the 2 Hz surface is nearest
(rms over the nodes, 21 or 201 levels) to the blend 0.34 of the way from the 1 Hz to the 4 Hz
surface, where interpolation in ``v`` puts 800 V/s at 1/3 (1.02x the best blend's distance)
and interpolation in ``ln v`` at 1/2 (6.8x).  :func:`~preisach.identify.rate.identify_rate` chooses
the scale by cross-validation when the data cover rates between the knots, and ``"linear"``
when they cannot tell.  The built-in ``"ss15-rate"`` keeps ``"log"`` by default (its knots hold
all three measured surfaces, so the scales differ only between them).

A held input lets ``v`` decay to 0, so the output relaxes (with ``tau``) from the read-out of
the table of the last rate to that of the slowest table - a creep-like settling whose size is
the difference between the tables.

**Sweep frequency and rate.**  A full-range triangle (input from ``-u_hat`` to ``u_hat`` and
back) at frequency ``f`` has ``|du/dt| = 4 u_hat f`` (:func:`triangle_rate`); so does the mean
of ``|du/dt|`` of a sinusoid of amplitude ``u_hat``.  The thesis's FOD sweeps of the SS15 over
``+/-100`` V at 1, 2 and 4 Hz (Table 3.1) therefore sit at 400, 800 and 1600 V/s: those are the
knots of the built-in ``"ss15-rate"``, whose tables are the three Table 3.1 surfaces.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _core
from ._io import atomic_write
from .model import (
    BUILTIN_MODELS,
    PreisachModel,
    SimulationResult,
    Slopes,
    State,
    _batch_rows,
    _damaged,
    _input_and_times,
    _model_info,
    _ModelBase,
    _read_archive,
    _read_envelope,
    _real_array,
    state_from_dict,
    state_to_dict,
)

__all__ = [
    "BUILTIN_RATE_MODELS",
    "RATE_SCALES",
    "SS15_RATE_TAU",
    "RateDependentPreisachModel",
    "RateSimulationResult",
    "RateState",
    "triangle_rate",
]

PathLike = Union[str, "os.PathLike[str]"]

_FORMAT = "preisach-rate-model"
#: Version 2 adds the field ``scale``; a model with the default ``"log"`` scale is written as
#: version 1 (readable by older packages), version-1 files load with ``"log"``.
_FORMAT_VERSION = 2
_FIELDS = ("format", "version", "levels", "everett", "y_min", "knots", "tau", "info")
#: Coordinates the basis can interpolate in between knots (module docstring).
RATE_SCALES: tuple[str, ...] = ("log", "linear")

#: Rate-filter time constant (s) of the built-in ``"ss15-rate"``: long enough that a 1-4 Hz
#: sinusoid of the initialisation waveforms reads as its mean rate ``4 u_hat f`` (the ripple of
#: ``|sin|`` at 2 f is attenuated 2.3-8x), short enough that the model follows a change of
#: drive frequency within a period.
SS15_RATE_TAU: float = 0.25

#: Built-in rate-dependent models: name -> identification frequencies (Hz) of Table 3.1.
BUILTIN_RATE_MODELS: dict[str, tuple[int, ...]] = {"ss15-rate": (1, 2, 4)}


def triangle_rate(frequency: float, amplitude: float = 100.0) -> float:
    """Return ``|du/dt| = 4 u_hat f`` (V/s) of a full-range triangle at ``f`` Hz.

    Parameters
    ----------
    frequency : float
        Sweep frequency ``f`` (Hz).
    amplitude : float
        ``u_hat`` (V); the SS15's range is ``+/-100`` V.

    """
    f, a = float(frequency), float(amplitude)
    if not (math.isfinite(f) and f > 0 and math.isfinite(a) and a > 0):
        raise ValueError(
            f"frequency and amplitude: must be positive, got {frequency!r}, {amplitude!r}"
        )
    return 4.0 * a * f


@dataclass(frozen=True)
class RateState:
    """State of a rate-dependent model: the Preisach boundary and the filtered rate.

    Attributes
    ----------
    boundary : State
        The boundary (shared by all tables); its input is the current input (V).
    rate : float
        The filtered input rate ``v`` (V/s, >= 0); 0 is "at rest".

    """

    boundary: State
    rate: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.boundary, State):
            raise TypeError(
                f"boundary: expected a preisach State, got {type(self.boundary).__name__}"
            )
        r = float(self.rate)
        if not (math.isfinite(r) and r >= 0):
            raise ValueError(f"rate: the filtered input rate must be >= 0 V/s, got {self.rate!r}")
        object.__setattr__(self, "rate", r)

    @property
    def input(self) -> float:
        """Current input (V)."""
        return float(self.boundary.input)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly description: the boundary (:func:`~preisach.state_to_dict`) and rate."""
        return {"boundary": state_to_dict(self.boundary), "rate": self.rate}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RateState:
        """Inverse of :meth:`to_dict`."""
        try:
            return cls(state_from_dict(data["boundary"]), float(data["rate"]))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"rate state: malformed description ({exc!r})") from exc


def _check_scale(scale: str) -> str:
    if scale not in RATE_SCALES:
        raise ValueError(f"scale: expected one of {RATE_SCALES}, got {scale!r}")
    return scale


def _as_rate_state(state: RateState | State | None, default: RateState) -> RateState:
    if state is None:
        return default
    if isinstance(state, RateState):
        return state
    if isinstance(state, State):
        return RateState(state, 0.0)
    raise TypeError(f"state: expected a RateState or State, got {type(state).__name__}")


@dataclass
class RateSimulationResult(SimulationResult):
    """Result of :meth:`RateDependentPreisachModel.simulate`.

    As :class:`~preisach.SimulationResult` (``initial_state`` and ``final_state`` are the
    boundaries), plus the filtered rate.

    Attributes
    ----------
    rate : ndarray
        Filtered input rate ``v`` (V/s) after each sample.
    initial_rate, final_rate : float
        ``v`` before the first and after the last sample (V/s).

    """

    rate: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    initial_rate: float = 0.0
    final_rate: float = 0.0

    @property
    def final_rate_state(self) -> RateState:
        """Boundary and rate after the last sample (continue a simulation from here)."""
        return RateState(self.final_state, self.final_rate)

    @property
    def initial_rate_state(self) -> RateState:
        """Boundary and rate before the first sample."""
        return RateState(self.initial_state, self.initial_rate)


class RateDependentPreisachModel(_ModelBase):
    """Preisach model whose Everett function depends on the filtered input rate.

    ``E(alpha, beta; v) = sum_k b_k(v) E_k(alpha, beta)`` (see the module docstring for the
    filter and the basis).  Build one with :meth:`from_models` or :meth:`builtin`, or identify
    one with :func:`preisach.identify.rate.identify_rate`; load one with :meth:`load`.

    Parameters
    ----------
    core : preisach._core.RateDependentModel
        The C++ model (tables, knots, ``tau``).
    name : str, optional
        Free-form name, kept by :meth:`save`.
    metadata : dict, optional
        JSON-serialisable information, kept by :meth:`save`.
    out_of_range : {"clamp", "raise"}
        What :meth:`simulate` does with inputs outside ``[u_min, u_max]``.

    """

    def __init__(
        self,
        core: _core.RateDependentModel,
        *,
        name: str = "",
        metadata: dict[str, Any] | None = None,
        out_of_range: str = "clamp",
    ) -> None:
        if not isinstance(core, _core.RateDependentModel):
            raise TypeError(
                f"core: expected preisach._core.RateDependentModel, got {type(core).__name__}"
            )
        self._set_info(name, metadata, out_of_range)
        self._core = core

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_models(
        cls,
        models: Sequence[PreisachModel],
        rates: ArrayLike,
        tau: float,
        *,
        scale: str = "log",
        **kwargs: Any,
    ) -> RateDependentPreisachModel:
        """Blend classical models identified at the given rates.

        Parameters
        ----------
        models : sequence of PreisachModel
            One model per rate, all on the same grid of levels.
        rates : array_like
            Strictly increasing rates (V/s) at which the models hold, e.g. :func:`triangle_rate`
            of each identification frequency.
        tau : float
            Time constant (s) of the rate filter; 0 uses the rate of the last step.
        scale : {"log", "linear"}
            Interpolate between the rates in ``ln v`` or in ``v`` (module docstring).
        **kwargs
            Passed to the constructor.

        """
        ms = list(models)
        bad = [k for k, m in enumerate(ms) if not isinstance(m, PreisachModel)]
        if bad:
            raise TypeError(
                f"models[{bad[0]}]: expected a PreisachModel, got {type(ms[bad[0]]).__name__}"
            )
        r = np.atleast_1d(np.asarray(rates, dtype=float))
        core = _core.RateDependentModel(
            [m.table for m in ms], [float(x) for x in r], float(tau), _check_scale(scale)
        )
        kwargs.setdefault("metadata", {"source": "models", "names": [m.name for m in ms]})
        return cls(core, **kwargs)

    @classmethod
    def builtin(
        cls,
        name: str = "ss15-rate",
        levels: ArrayLike | int = 201,
        *,
        tau: float = SS15_RATE_TAU,
        scale: str = "log",
    ) -> RateDependentPreisachModel:
        """Return the SS15 rate-dependent model: the Table 3.1 surfaces at their sweep rates.

        Tables ``ss15-1hz``, ``ss15-2hz``, ``ss15-4hz`` (:meth:`PreisachModel.builtin`) at the
        knots ``4 * 100 V * f`` = 400, 800 and 1600 V/s (:func:`triangle_rate`): a full-range
        triangle at 1, 2 or 4 Hz reproduces the corresponding classical model; rates below
        400 V/s use the 1 Hz surface and above 1600 V/s the 4 Hz one.

        Parameters
        ----------
        name : {"ss15-rate"}
            The built-in's name.
        levels : int or array_like
            Grid of the tables (default 201 levels, 1 V apart).
        tau : float
            Rate-filter time constant (s), default :data:`SS15_RATE_TAU`.
        scale : {"log", "linear"}
            Interpolation between the knots (module docstring).

        """
        key = name.lower()
        if key not in BUILTIN_RATE_MODELS:
            raise ValueError(
                f"name: unknown built-in rate-dependent model {name!r}; choose from "
                f"{sorted(BUILTIN_RATE_MODELS)}"
            )
        freqs = BUILTIN_RATE_MODELS[key]
        names = [n for f in freqs for n, g in BUILTIN_MODELS.items() if g == f]
        models = [PreisachModel.builtin(n, levels) for n in names]
        out = cls.from_models(
            models,
            [triangle_rate(f) for f in freqs],
            tau,
            scale=scale,
            name=key,
            metadata={"builtin": key, "tables": names, "frequencies_hz": list(freqs)},
        )
        return out

    # ------------------------------------------------------------------ properties
    @property
    def core(self) -> _core.RateDependentModel:
        """The C++ model."""
        return self._core

    @property
    def knots(self) -> NDArray[np.float64]:
        """Rate knots (V/s), one per table."""
        return np.asarray(self._core.knots, dtype=float)

    @property
    def tau(self) -> float:
        """Rate-filter time constant (s)."""
        return float(self._core.tau)

    @property
    def scale(self) -> str:
        """Coordinate of the interpolation between knots: ``"log"`` (ln v) or ``"linear"``."""
        return str(self._core.scale)

    @property
    def n_tables(self) -> int:
        """Number of tables ``K``."""
        return int(self._core.size)

    @property
    def levels(self) -> NDArray[np.float64]:
        """Grid levels (V), shared by all tables."""
        return np.asarray(self._core.table(0).levels)

    @property
    def u_min(self) -> float:
        """Lower end of the input range (V)."""
        return float(self._core.u_min)

    @property
    def u_max(self) -> float:
        """Upper end of the input range (V)."""
        return float(self._core.u_max)

    @property
    def models(self) -> list[PreisachModel]:
        """The classical model of each knot (table ``k`` alone)."""
        return [
            PreisachModel(t, name=f"{self.name or 'rate'}@{v:g}V/s", out_of_range=self.out_of_range)
            for t, v in zip(self._core.tables, self.knots)
        ]

    @property
    def table(self) -> _core.EverettTable:
        """The Everett table at rest (rate below the first knot): what a held input settles to.

        The neutral locus of the model at rest (:func:`preisach.neutral.neutral_locus`) uses it.
        """
        return self._core.table(0)

    def at_rate(self, rate: float) -> PreisachModel:
        """Return the classical model of a constant rate (V/s): the table ``sum_k b_k E_k``."""
        r = float(rate)
        if not (math.isfinite(r) and r >= 0):
            raise ValueError(f"rate: must be >= 0 V/s, got {rate!r}")
        return PreisachModel(
            self._core.blended(r),
            name=f"{self.name or 'rate'}@{r:g}V/s",
            metadata={"source": "rate_model", "rate": r},
            out_of_range=self.out_of_range,
        )

    def weights(self, rate: ArrayLike) -> NDArray[np.float64]:
        """Basis weights ``b_k(rate)``, shape ``rate.shape + (K,)``, for rates in V/s."""
        r = np.asarray(rate, dtype=float)
        w = np.asarray(self._core.weights(np.ascontiguousarray(r.ravel())))
        return w.reshape(r.shape + (self.n_tables,))

    # ------------------------------------------------------------------ states
    def negative_saturation(self, rate: float = 0.0) -> RateState:
        """Every relay at -1, input ``u_min``; filtered rate ``rate`` (V/s)."""
        return RateState(State.negative_saturation(self.u_min, self.u_max), rate)

    def positive_saturation(self, rate: float = 0.0) -> RateState:
        """Every relay at +1, input ``u_max``; filtered rate ``rate`` (V/s)."""
        return RateState(State.positive_saturation(self.u_min, self.u_max), rate)

    def neutral_state(self, l: float, rate: float = 0.0) -> RateState:  # noqa: E741
        """Neutral state psi_n^l (Eq 2.17) of the shared boundary, at filtered rate ``rate``."""
        return RateState(State.neutral(self.u_min, self.u_max, float(l)), rate)

    def anhysteretic_state(self, rate: float = 0.0) -> RateState:
        """Anhysteretic state (boundary ``s = 0``, input 0 V) at rest by default."""
        l0 = 0.0 if self.u_min <= 0.0 <= self.u_max else 0.5 * (self.u_min + self.u_max)
        return self.neutral_state(l0, rate)

    def readout(self, state: RateState | State) -> float:
        """Output (V) of a state: ``sum_k b_k(v) Gamma_k(psi)`` (a bare State is at rest)."""
        st = _as_rate_state(state, self.anhysteretic_state())
        w = self.weights(st.rate)
        return float(
            sum(
                wk * _core.readout(t, st.boundary) for wk, t in zip(w, self._core.tables) if wk != 0
            )
        )

    def slopes(self, state: RateState | State) -> Slopes:
        """One-sided dy/du (V/V) at a state with the rate held (Appendix A per table, blended)."""
        st = _as_rate_state(state, self.anhysteretic_state())
        return Slopes(*self.simulator(st, sample_time=1.0).slopes())

    # ------------------------------------------------------------------ simulation
    def simulator(
        self, state: RateState | State | None = None, *, sample_time: float = 1e-3
    ) -> _core.RateSimulator:
        """Step-by-step simulator (``step(u)``, ``run(u)``, ``state``, ``rate``, ``slopes()``)."""
        st = _as_rate_state(state, self.anhysteretic_state())
        return _core.RateSimulator(self._core, st.boundary, st.rate, float(sample_time))

    def simulate(
        self,
        u: ArrayLike,
        state: RateState | State | None = None,
        t: ArrayLike | None = None,
        *,
        sample_time: float = 1e-3,
        out_of_range: str | None = None,
    ) -> RateSimulationResult:
        """Simulate the output for the input samples ``u`` (V).

        Parameters
        ----------
        u : array_like, shape (n,)
            Input (V), real and finite.
        state : RateState or State, optional
            Initial boundary and filtered rate; a bare :class:`~preisach.State` starts at rest
            (rate 0).  Default: the anhysteretic state at rest.
        t : array_like, optional
            Sample times (s); must be uniformly spaced (the rate filter runs at one sample
            time), which then replaces ``sample_time``.
        sample_time : float
            Sampling period (s): the ``dt`` of the rate ``|du|/dt``.
        out_of_range : {"clamp", "raise"}, optional
            Overrides the model's policy.

        Returns
        -------
        RateSimulationResult

        """
        pol = self._policy(out_of_range)
        uu, tt = _input_and_times(u, t)
        st = _as_rate_state(state, self.anhysteretic_state())
        ts = float(sample_time)
        if tt is not None:
            if tt.size >= 2:
                d = np.diff(tt)
                ts = float(np.mean(d))
                if np.max(np.abs(d - ts)) > 1e-6 * ts:
                    raise ValueError(
                        "t: the rate-dependent model needs uniformly spaced samples (the rate "
                        f"filter runs at one sample time); steps range {d.min():g}..{d.max():g} s"
                    )
        if not (math.isfinite(ts) and ts > 0):
            raise ValueError(f"sample_time: must be positive, got {sample_time}")
        y, v, final, vfin = _core.simulate_rate(self._core, uu, st.boundary, st.rate, ts, pol)
        return RateSimulationResult(
            uu,
            y,
            st.boundary,
            final,
            ts,
            self.name,
            _time=tt,
            rate=v,
            initial_rate=st.rate,
            final_rate=float(vfin),
        )

    def simulate_batch(
        self,
        u: ArrayLike,
        states: RateState | State | Sequence[RateState | State] | None = None,
        *,
        sample_time: float = 1e-3,
        threads: int = 0,
        out_of_range: str | None = None,
    ) -> tuple[NDArray[np.float64], list[RateState]]:
        """Simulate many runs at once on all cores (the GIL is released).

        Parameters
        ----------
        u : array_like, shape (runs, n) or (n,)
            One input (V) per row; a single row is run from each of several ``states``.
        states : RateState, State or sequence of them, optional
            One initial state for all rows, one per row, or several for a single input row;
            default the anhysteretic state at rest.
        sample_time : float
            Sampling period (s).
        threads : int
            Worker threads; 0 uses every core.
        out_of_range : {"clamp", "raise"}, optional
            Overrides the model's policy.

        Returns
        -------
        y : ndarray, shape (runs, n)
            Outputs (V); row ``r`` equals ``simulate(u[r], states[r]).output``.
        final_states : list of RateState

        """
        uu = _real_array("u", u)
        single = states is None or isinstance(states, (RateState, State))
        if single:
            st = [_as_rate_state(states, self.anhysteretic_state())]  # type: ignore[arg-type]
        else:
            st = [_as_rate_state(s, self.anhysteretic_state()) for s in states]  # type: ignore[union-attr]
            if not st:
                raise ValueError("states: need at least one initial state")
        uu = _batch_rows(uu, len(st), not single)
        if threads < 0:
            raise ValueError(f"threads: must be >= 0, got {threads}")
        y, finals, rates = _core.simulate_rate_batch(
            self._core,
            uu,
            [s.boundary for s in st],
            [s.rate for s in st],
            float(sample_time),
            self._policy(out_of_range),
            threads,
        )
        return y, [RateState(b, float(r)) for b, r in zip(finals, rates)]

    # ------------------------------------------------------------------ persistence
    def save(self, path: PathLike) -> None:
        """Write the model to an ``.npz`` file (versioned, exact round trip, atomic).

        Raises
        ------
        TypeError
            If :attr:`metadata` is not JSON-serialisable (``path`` is not touched).

        """
        info = _model_info(path, self.name, self.metadata, self.out_of_range)
        tables = self._core.tables
        arrays: dict[str, Any] = {
            "format": np.array(_FORMAT),
            "version": np.array(1 if self.scale == "log" else _FORMAT_VERSION),
            "levels": self.levels,
            "everett": np.stack([np.asarray(t.values) for t in tables]),
            "y_min": np.array([t.y_min for t in tables], dtype=float),
            "knots": self.knots,
            "tau": np.array(self.tau),
            "info": np.array(info),
        }
        if self.scale != "log":
            arrays["scale"] = np.array(self.scale)
        atomic_write(path, lambda f: np.savez(f, **arrays), binary=True, what="model")

    @classmethod
    def load(cls, path: PathLike) -> RateDependentPreisachModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        ValueError
            Naming the file: unreadable, damaged, not a rate-dependent model, missing fields,
            or a format version newer than this package understands.

        """
        p = os.fspath(path)

        def read(p: str, data: Any) -> tuple[Any, ...]:
            def fields() -> tuple[Any, ...]:
                _, meta = _read_envelope(
                    p, data, _FORMAT, _FIELDS, _FORMAT_VERSION, "rate-dependent preisach model"
                )
                return (
                    np.asarray(data["levels"], dtype=float),
                    np.asarray(data["everett"], dtype=float),
                    np.asarray(data["y_min"], dtype=float),
                    np.asarray(data["knots"], dtype=float),
                    float(data["tau"]),
                    str(data["scale"]) if "scale" in data.files else "log",
                    meta,
                )

            return _damaged(p, fields)

        levels, everett, y_min, knots, tau, scale, meta = _read_archive(path, read)
        try:
            if everett.ndim != 3 or y_min.shape != (everett.shape[0],):
                raise ValueError("everett must be (K, n, n) with one y_min per table")
            tables = [_core.EverettTable(levels, e, float(y)) for e, y in zip(everett, y_min)]
            core = _core.RateDependentModel(tables, [float(x) for x in knots], tau, scale)
            return cls(
                core,
                name=str(meta.get("name", "")),
                metadata=meta.get("metadata", {}),
                out_of_range=meta.get("out_of_range", "clamp"),
            )
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{p}: damaged model file ({exc})") from exc

    def __getstate__(self) -> dict[str, Any]:
        return {
            "tables": list(self._core.tables),
            "knots": [float(x) for x in self.knots],
            "tau": self.tau,
            "scale": self.scale,
            **self._info_state(),
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._core = _core.RateDependentModel(
            state["tables"], state["knots"], state["tau"], state.get("scale", "log")
        )
        self._set_info_state(state)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RateDependentPreisachModel):
            return NotImplemented
        a, b = self._core.tables, other._core.tables
        return (
            np.array_equal(self.knots, other.knots)
            and self.tau == other.tau
            and self.scale == other.scale
            and len(a) == len(b)
            and all(
                np.array_equal(np.asarray(x.levels), np.asarray(z.levels))
                and np.array_equal(np.asarray(x.values), np.asarray(z.values))
                and x.y_min == z.y_min
                for x, z in zip(a, b)
            )
        )

    def _repr_html_(self) -> str:
        """HTML for Jupyter: rates, filter, grid and the major loop at each rate."""
        from ._display import rate_model_html

        return rate_model_html(self)

    def __repr__(self) -> str:
        nm = f"{self.name!r}, " if self.name else ""
        knots = ", ".join(f"{v:g}" for v in self.knots)
        return (
            f"RateDependentPreisachModel({nm}{self.n_tables} tables at [{knots}] V/s, "
            f"tau={self.tau:g} s, {self.scale} scale, {len(self.levels)} levels on "
            f"[{self.u_min:g}, {self.u_max:g}] V)"
        )
