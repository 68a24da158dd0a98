r"""The classical Preisach model: construction, states, simulation, read-out, save/load.

Conventions used throughout :mod:`preisach`:

* volts in, volts out, seconds;
* a relay :math:`\gamma_{\alpha\beta}` switches to +1 when ``u >= alpha`` and to -1 when
  ``u <= beta``, with ``alpha >= beta``; in the thesis's other coordinates
  ``r = (alpha - beta) / 2`` (half-width) and ``s = (alpha + beta) / 2`` (offset);
* the Everett function ``E(alpha, beta)`` is the weight inside the triangle
  ``beta <= beta' <= alpha' <= alpha``; from first-order descending (FOD) data
  ``E = (y(alpha, alpha) - y(alpha, beta)) / 2`` (Mayergoyz);
* ``y_min``/``y_max`` are the outputs at negative/positive saturation, and
  ``y_max = y_min + 2 E(u_max, u_min)``.
"""

from __future__ import annotations

import copy
import json
import os
import zipfile
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, NamedTuple, TypeVar, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _core
from ._io import atomic_write, npz_load_error
from .surface import TABLE_3_1, SqrtSurface

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .compensate import InverseResult

__all__ = [
    "BUILTIN_MODELS",
    "BatchResult",
    "PreisachModel",
    "SimulationResult",
    "Slopes",
    "State",
    "state_from_dict",
    "state_to_dict",
]

State = _core.State
PathLike = Union[str, "os.PathLike[str]"]

#: Names accepted by :meth:`PreisachModel.builtin`: the SS15 surfaces of Table 3.1.
BUILTIN_MODELS: dict[str, int] = {"ss15-1hz": 1, "ss15-2hz": 2, "ss15-4hz": 4}

_FORMAT = "preisach-model"
#: Version 2 adds the identification recordings (``ident{k}_t/u/y`` and ``ident_meta``);
#: version 3 the interpolation between the nodes (``interpolation``, written only for a cubic
#: table, so an older package refuses a file it would simulate differently).  A model is
#: written at the lowest version that holds it, and every version loads.
_FORMAT_VERSION = 3
INTERPOLATIONS = ("bilinear", "cubic")
_POLICIES = ("clamp", "raise")
_FIELDS = ("format", "version", "levels", "everett", "y_min", "info")
_T = TypeVar("_T")


# ---------------------------------------------------------------- shared by the model classes
# (PreisachModel here, RateDependentPreisachModel in rate_model.py): policy, input and state
# checks, and the versioned .npz archive's envelope.
class _ModelBase:
    """Name, metadata and input policy: what both model classes keep besides their tables.

    (:class:`PreisachModel` and :class:`~preisach.rate_model.RateDependentPreisachModel`.)
    """

    name: str
    metadata: dict[str, Any]
    out_of_range: str

    def _set_info(self, name: str, metadata: dict[str, Any] | None, out_of_range: str) -> None:
        if out_of_range not in _POLICIES:
            raise ValueError(f"out_of_range: expected 'clamp' or 'raise', got {out_of_range!r}")
        self.name = name
        self.metadata = dict(metadata or {})
        self.out_of_range = out_of_range

    def _info_state(self) -> dict[str, Any]:
        """Return the name, metadata and policy for ``__getstate__``."""
        return {"name": self.name, "metadata": self.metadata, "out_of_range": self.out_of_range}

    def _set_info_state(self, state: dict[str, Any]) -> None:
        self.name = state["name"]
        self.metadata = state["metadata"]
        self.out_of_range = state["out_of_range"]

    def _policy(self, out_of_range: str | None) -> str:
        return _check_policy(self.out_of_range, out_of_range)

    __hash__ = None  # type: ignore[assignment]


def _check_policy(default: str, out_of_range: str | None) -> str:
    """Return the input policy of a call: ``out_of_range`` if given, else ``default``."""
    pol = default if out_of_range is None else out_of_range
    if pol not in _POLICIES:
        raise ValueError(f"out_of_range: expected 'clamp' or 'raise', got {pol!r}")
    return pol


def _input_and_times(
    u: ArrayLike, t: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Check a simulation's 1-D input ``u`` (V) and optional sample times ``t`` (s)."""
    uu = _real_array("u", u)
    if uu.ndim != 1:
        raise ValueError(f"u: expected a 1-D array of input samples, got shape {uu.shape}")
    if t is None:
        return uu, None
    tt = _real_array("t", t)
    if tt.shape != uu.shape:
        raise ValueError(f"t: shape {tt.shape} does not match u {uu.shape}")
    _check_times(tt)
    return uu, tt


def _batch_rows(uu: NDArray[np.float64], n_states: int, many: bool) -> NDArray[np.float64]:
    """Return the (runs, n) input of a batch, one row broadcast to ``n_states`` starts.

    ``many``: the states were given as a sequence (a 1-D ``uu`` is then one row).
    """
    if uu.ndim == 1 and many:
        uu = uu[None, :]  # one input, many initial states
    if uu.ndim != 2:
        raise ValueError(
            f"u: expected a 2-D array (runs, samples), or a 1-D input with a sequence of "
            f"states, got shape {uu.shape}"
        )
    if uu.shape[0] == 1 and n_states > 1:
        return np.ascontiguousarray(np.broadcast_to(uu, (n_states, uu.shape[1])))
    if n_states not in (1, uu.shape[0]):
        raise ValueError(
            f"states: need one state or one per input row: got {n_states} states for "
            f"{uu.shape[0]} rows"
        )
    return uu


def _model_info(path: PathLike, name: str, metadata: dict[str, Any], out_of_range: str) -> str:
    """Return the JSON ``info`` of a model archive (TypeError naming ``path`` if impossible)."""
    try:
        return json.dumps({"name": name, "metadata": metadata, "out_of_range": out_of_range})
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"{os.fspath(path)}: cannot save the model: metadata is not JSON-serialisable ({exc})"
        ) from exc


def _read_archive(path: PathLike, read: Callable[[str, Any], _T]) -> _T:
    """Open a model archive and return ``read(p, data)`` (ValueError naming the file if bad)."""
    p = os.fspath(path)
    try:
        f = open(path, "rb")  # opened here: np.load leaks its handle on a bad zip file
    except OSError as exc:
        raise ValueError(f"{p}: not a readable model file ({exc})") from exc
    with f:
        try:
            data = np.load(f, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ValueError(f"{p}: not a readable model file ({npz_load_error(exc)})") from exc
        if not hasattr(data, "files"):  # a bare .npy array
            raise ValueError(f"{p}: not a preisach model file (a single array, not an archive)")
        with data:
            return read(p, data)


def _read_envelope(
    p: str, data: Any, fmt: str, fields: Sequence[str], version_max: int, kind: str
) -> tuple[int, dict[str, Any]]:
    """Check an open archive's format, fields and version; return the version and ``info``.

    Call inside :func:`_damaged`'s ``try`` (a KeyError or zip error is a damaged file).
    """
    if "format" not in data.files or str(data["format"]) != fmt:
        raise ValueError(f"{p}: not a {kind} file")
    missing = [k for k in fields if k not in data.files]
    if missing:
        raise ValueError(f"{p}: incomplete model file: missing {', '.join(map(repr, missing))}")
    version = int(data["version"])
    if version > version_max:
        raise ValueError(
            f"{p}: {kind} format version {version} is newer than this package supports "
            f"({version_max}); upgrade preisach"
        )
    meta = json.loads(str(data["info"]))
    if not isinstance(meta, dict):
        raise ValueError(f"{p}: damaged model file: 'info' is not a JSON object")
    return version, meta


def _damaged(p: str, read: Callable[[], _T]) -> _T:
    """Run ``read()``; errors not already naming the file become ``ValueError`` naming it."""
    try:
        return read()
    except ValueError as exc:
        if str(exc).startswith(p):
            raise
        raise ValueError(f"{p}: damaged model file ({exc})") from exc
    except (KeyError, EOFError, zipfile.BadZipFile, zlib.error, OSError) as exc:
        raise ValueError(f"{p}: damaged or truncated model file ({exc!r})") from exc


def state_to_dict(state: State) -> dict[str, Any]:
    """JSON-friendly description of a state (volts): range, input and boundary pieces.

    Each piece is ``[b0, v, kind]``: from ``beta = b0`` up to the next piece (or the input),
    ``phi(beta) = v`` for ``kind == "constant"`` and ``phi(beta) = v - beta`` for
    ``kind == "antidiagonal"``.
    """
    u_min, u_max, u, b0, v, ad = state.to_tuple()
    return {
        "u_min": float(u_min),
        "u_max": float(u_max),
        "input": float(u),
        "pieces": [
            [float(a), float(b), "antidiagonal" if c else "constant"] for a, b, c in zip(b0, v, ad)
        ],
    }


def state_from_dict(data: dict[str, Any]) -> State:
    """Inverse of :func:`state_to_dict`; the boundary is validated."""
    try:
        pieces = data["pieces"]
        kinds = [p[2] for p in pieces]
        bad = [k for k in kinds if k not in ("constant", "antidiagonal")]
        if bad:
            raise ValueError(f"state: unknown piece kind {bad[0]!r}")
        return State(
            float(data["u_min"]),
            float(data["u_max"]),
            float(data["input"]),
            np.array([p[0] for p in pieces], float),
            np.array([p[1] for p in pieces], float),
            np.array([k == "antidiagonal" for k in kinds], bool),
        )
    except (KeyError, IndexError, TypeError) as exc:
        raise ValueError(f"state: malformed description ({exc!r})") from exc


class Slopes(NamedTuple):
    """One-sided derivatives dy/du (V/V) of the output at a state (Appendix A).

    Attributes
    ----------
    rising : float
        Slope if the input increases next (Eq A.13).
    falling : float
        Slope if the input decreases next (Eq A.27).

    """

    rising: float
    falling: float

    @property
    def interval(self) -> tuple[float, float]:
        """Subderivative interval at a reversal (Eq A.31): ``(min, max)`` of the two slopes."""
        return (min(self.rising, self.falling), max(self.rising, self.falling))


class BatchResult(NamedTuple):
    """Outputs and final states of :meth:`PreisachModel.simulate_batch`.

    Unpacks like a pair: ``y, final_states = model.simulate_batch(u)``.

    Attributes
    ----------
    output : ndarray, shape (runs, n)
        Outputs (V); row ``r`` equals ``simulate(u[r], states[r]).output``.
    final_states : list of State
        The state after the last sample of each run.

    """

    output: NDArray[np.float64]
    final_states: list[State]


@dataclass
class SimulationResult:
    """Result of :meth:`PreisachModel.simulate`.

    Unpacks like a tuple: ``t, y = model.simulate(u)``.

    Attributes
    ----------
    time : ndarray
        Sample times (s); built on first access when the simulation was given only a
        sample time.
    input : ndarray
        Input samples (V) as given (values outside the model range were clamped by the
        simulator, or raised, per ``out_of_range``).
    output : ndarray
        Output samples (V).
    initial_state, final_state : State
        Boundary before the first and after the last sample.
    sample_time : float
        Sampling period (s) used when no time array was given.

    """

    input: NDArray[np.float64]
    output: NDArray[np.float64]
    initial_state: State
    final_state: State
    sample_time: float = 1e-3
    model_name: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    _time: NDArray[np.float64] | None = field(default=None, repr=False)

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times (s)."""
        if self._time is None:
            self._time = np.arange(self.output.size, dtype=np.float64) * float(self.sample_time)
        return self._time

    def __iter__(self) -> Iterator[NDArray[np.float64]]:
        yield self.time
        yield self.output

    def __len__(self) -> int:
        return len(self.output)

    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Plot input and output against time, and the input-output loop; returns the figure."""
        from .plotting.model import plot_simulation

        return plot_simulation(self, fig=fig)


def _as_levels(levels: ArrayLike | int, u_min: float, u_max: float) -> NDArray[np.float64]:
    if np.ndim(levels) == 0:
        n = int(np.asarray(levels))
        if n < 2:
            raise ValueError(f"levels: need at least 2 grid levels, got {n}")
        return np.linspace(u_min, u_max, n)
    lv = np.asarray(levels, dtype=float)
    if lv.ndim != 1 or lv.size < 2:
        raise ValueError("levels: expected an increasing 1-D array of at least 2 input levels (V)")
    if not np.all(np.isfinite(lv)) or np.any(np.diff(lv) <= 0):
        raise ValueError("levels: must be finite and strictly increasing")
    return lv


def _real_array(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """``values`` as a C-contiguous float64 array; only real numbers (dtype kind f, i, u)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiu":
        raise ValueError(
            f"{name}: expected real numbers (float or integer dtype), got dtype {arr.dtype}"
        )
    return np.ascontiguousarray(arr, dtype=np.float64)


def _check_times(t: NDArray[np.float64]) -> None:
    """Raise ValueError unless the sample times ``t`` (s) are finite and strictly increasing."""
    bad = ~np.isfinite(t)
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"t: t[{k}] = {t[k]} is not finite")
    steps = np.diff(t) <= 0
    if steps.any():
        k = int(np.argmax(steps)) + 1
        raise ValueError(
            f"t: sample times must be strictly increasing, but t[{k}] = {t[k]} s <= "
            f"t[{k - 1}] = {t[k - 1]} s"
        )


def _lower_grid(levels: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a, b = np.meshgrid(levels, levels, indexing="ij")
    return a, np.minimum(b, a)


class PreisachModel(_ModelBase):
    """Classical Preisach model held as an Everett table; simulation runs in C++.

    Build one with :meth:`from_fod_grid`, :meth:`from_everett`, :meth:`from_weights`,
    :meth:`from_surface` or :meth:`builtin`; load one with :meth:`load`.

    Parameters
    ----------
    table : preisach._core.EverettTable
        The tabulated Everett function (V) on a grid of input levels (V).
    name : str, optional
        Free-form name, kept by :meth:`save`.
    metadata : dict, optional
        JSON-serialisable information about the model's origin, kept by :meth:`save`.
    out_of_range : {"clamp", "raise"}
        What :meth:`simulate` does with inputs outside ``[u_min, u_max]``: clamp them to the
        range (default) or raise :class:`ValueError` naming the first offending sample.

    Attributes
    ----------
    identification : list of Recording
        The recordings the model was identified from (``preisach identify`` stores them), kept
        by :meth:`save`; :func:`preisach.diagnose` refits the weights on them by default.
        Empty when unknown.

    """

    def __init__(
        self,
        table: _core.EverettTable,
        *,
        name: str = "",
        metadata: dict[str, Any] | None = None,
        out_of_range: str = "clamp",
    ) -> None:
        if not isinstance(table, _core.EverettTable):
            raise TypeError(
                f"table: expected preisach._core.EverettTable, got {type(table).__name__}"
            )
        self._set_info(name, metadata, out_of_range)
        self._table = table
        self.identification: list[Any] = []

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_fod_grid(cls, levels: ArrayLike, y_grid: ArrayLike, **kwargs: Any) -> PreisachModel:
        """Mayergoyz identification from first-order descending (FOD) curve samples.

        Parameters
        ----------
        levels : array_like, shape (n,)
            Increasing input levels (V).
        y_grid : array_like, shape (n, n)
            ``y_grid[i, j]`` is the output (V) at input ``levels[j]`` on the FOD curve that rose
            from negative saturation to ``levels[i]``; needed for ``j <= i`` (the rest is
            ignored).  ``y_grid[i, i]`` is the output at the turning point.
        **kwargs
            Passed to the constructor (``name``, ``metadata``, ``out_of_range``).

        Returns
        -------
        PreisachModel
            ``E[i, j] = (y_grid[i, i] - y_grid[i, j]) / 2``; ``y_min`` is the mean of the FOD
            end points ``y_grid[:, 0]``.

        """
        lv = _as_levels(levels, 0.0, 1.0)
        y = np.asarray(y_grid, dtype=float)
        kwargs.setdefault("metadata", {"source": "fod_grid"})
        return cls(_core.EverettTable.from_fod(lv, y), **kwargs)

    @classmethod
    def from_everett(
        cls,
        func: Callable[[NDArray[np.float64], NDArray[np.float64]], ArrayLike],
        levels: ArrayLike | int,
        *,
        y_min: float | None = None,
        u_range: tuple[float, float] | None = None,
        interpolation: str = "bilinear",
        **kwargs: Any,
    ) -> PreisachModel:
        """Tabulate a Python Everett function on a grid.

        Parameters
        ----------
        func : callable
            ``func(alpha, beta)`` returning ``E`` (V) for arrays with ``alpha >= beta`` (V);
            called once, vectorised, on the whole grid.
        levels : array_like or int
            Input levels (V), or their number when ``u_range`` is given.
        y_min : float, optional
            Output at negative saturation (V).  Default: ``-E(u_max, u_min)``, the symmetric
            model whose saturated outputs are ``-/+ E(u_max, u_min)``.
        u_range : (float, float), optional
            ``(u_min, u_max)`` (V) when ``levels`` is a count.
        interpolation : {"bilinear", "cubic"}
            How the table is interpolated between its nodes (see :attr:`interpolation`).
        **kwargs
            Passed to the constructor.

        """
        if np.ndim(levels) == 0 and u_range is None:
            raise ValueError("u_range: needed when levels is a number of levels")
        lo, hi = u_range if u_range is not None else (0.0, 1.0)
        lv = _as_levels(levels, lo, hi)
        a, b = _lower_grid(lv)
        values = np.asarray(func(a, b), dtype=float)
        if values.shape != a.shape:
            raise ValueError(f"func: returned shape {values.shape}, expected {a.shape}")
        values = np.where(a > b, values, 0.0)
        if not np.all(np.isfinite(values)):
            i, j = np.argwhere(~np.isfinite(values))[0]
            raise ValueError(f"func: E({lv[i]}, {lv[j]}) is not finite")
        ym = -float(values[-1, 0]) if y_min is None else float(y_min)
        kwargs.setdefault("metadata", {"source": "everett_function"})
        return cls(_core.EverettTable(lv, values, ym, interpolation), **kwargs)

    @classmethod
    def from_weights(
        cls,
        levels: ArrayLike,
        weights: ArrayLike,
        *,
        y_min: float | None = None,
        **kwargs: Any,
    ) -> PreisachModel:
        """Build from a discrete relay-weight matrix.

        Parameters
        ----------
        levels : array_like, shape (n,)
            Increasing input levels (V); they bound the cells.
        weights : array_like, shape (n-1, n-1)
            ``weights[i, j]`` (V) is the mass of the Preisach weight in the cell
            ``[levels[i], levels[i+1]] x [levels[j], levels[j+1]]`` (alpha x beta), ``j <= i``;
            the diagonal cells are the half-cells below the diagonal and hold the reversible
            part (kappa).  Entries above the diagonal must be zero.
        y_min : float, optional
            Output at negative saturation (V).  Default ``-weights.sum()``: the classical
            model ``y = sum(w * gamma)``.
        **kwargs
            Passed to the constructor.

        """
        lv = _as_levels(levels, 0.0, 1.0)
        w = np.asarray(weights, dtype=float)
        if w.shape == (lv.size - 1, lv.size - 1) and np.any(np.triu(w, 1) != 0):
            raise ValueError("weights: entries above the diagonal (beta > alpha) must be zero")
        ym = -float(np.sum(w)) if y_min is None else float(y_min)
        kwargs.setdefault("metadata", {"source": "weights"})
        return cls(_core.EverettTable.from_weights(lv, w, ym), **kwargs)

    @classmethod
    def from_surface(
        cls, surface: SqrtSurface, levels: ArrayLike | int = 201, **kwargs: Any
    ) -> PreisachModel:
        """Tabulate a square-root FOD surface (Eq 3.2) on ``levels`` (count or array, V)."""
        kwargs.setdefault("metadata", {"source": "sqrt_surface", "surface": surface.to_dict()})
        return cls.from_everett(
            surface.everett,
            levels,
            y_min=surface.y_min,
            u_range=(surface.u_min, surface.u_max),
            **kwargs,
        )

    @classmethod
    def builtin(cls, name: str = "ss15-1hz", levels: ArrayLike | int = 201) -> PreisachModel:
        """Return an SS15 piezo bimorph model of the thesis, rebuilt from Table 3.1 via Eq 3.2.

        Parameters
        ----------
        name : {"ss15-1hz", "ss15-2hz", "ss15-4hz"}
            Identification frequency of the surface.
        levels : int or array_like
            Grid on which the surface is tabulated (default 201 levels, 1 V apart).

        Returns
        -------
        PreisachModel
            Input ``V_in`` (V, amplifier output) on [-100, 100]; output the strain-gauge
            voltage (V).

        """
        key = name.lower()
        if key == "ss15-rate":
            raise ValueError(
                "name: 'ss15-rate' is rate-dependent; use "
                "preisach.rate_model.RateDependentPreisachModel.builtin('ss15-rate')"
            )
        if key not in BUILTIN_MODELS:
            raise ValueError(
                f"name: unknown built-in model {name!r}; choose from {sorted(BUILTIN_MODELS)}"
            )
        surf = TABLE_3_1[BUILTIN_MODELS[key]]
        model = cls.from_surface(surf, levels, name=key)
        model.metadata["builtin"] = key
        return model

    # ------------------------------------------------------------------ properties
    @property
    def table(self) -> _core.EverettTable:
        """The C++ Everett table."""
        return self._table

    @property
    def levels(self) -> NDArray[np.float64]:
        """Grid levels (V)."""
        return np.asarray(self._table.levels)

    @property
    def interpolation(self) -> str:
        """How the Everett table is interpolated between its nodes: ``"bilinear"`` or ``"cubic"``.

        Bilinear (the default) in each grid cell; cubic is the C1 tensor-product cubic Hermite
        interpolant whose node slopes are those of the parabola through each node and its
        neighbours (Catmull-Rom on a uniform grid), through the antisymmetric extension
        ``E(a, b) = -E(b, a)``.  Both pass through the nodes and are linear in them (so
        identification and diagnosis refit either); a smooth density tabulated on a coarse
        grid is followed about ten times more closely by the cubic one (21-level FOD grid:
        13-36 mV against 0.2-5 mV RMS on blind densities).  :func:`preisach.identify` chooses
        it from the identification sweep.  The inverse of a cubic model is computed on a
        bilinear resampling four times finer (:func:`preisach.compensate.invert`).
        """
        return str(self._table.interpolation)

    def with_interpolation(self, interpolation: str) -> PreisachModel:
        """Return a copy with the same nodes interpolated by ``"bilinear"`` or ``"cubic"``."""
        if interpolation not in INTERPOLATIONS:
            raise ValueError(
                f"interpolation: expected 'bilinear' or 'cubic', got {interpolation!r}"
            )
        new = copy.copy(self)
        new._table = self._table.with_interpolation(interpolation)
        new.metadata = dict(self.metadata)
        new.identification = list(self.identification)
        return new

    @property
    def everett_values(self) -> NDArray[np.float64]:
        """Everett table ``E[i, j] = E(levels[i], levels[j])`` (V), zero for ``j >= i``."""
        return np.asarray(self._table.values)

    @property
    def u_min(self) -> float:
        """Lower end of the input range (V)."""
        return float(self._table.u_min)

    @property
    def u_max(self) -> float:
        """Upper end of the input range (V)."""
        return float(self._table.u_max)

    @property
    def y_min(self) -> float:
        """Output at negative saturation (V)."""
        return float(self._table.y_min)

    @property
    def y_max(self) -> float:
        """Output at positive saturation (V)."""
        return float(self._table.y_max)

    def everett(self, alpha: ArrayLike, beta: ArrayLike) -> NDArray[np.float64]:
        """Interpolated Everett function ``E(alpha, beta)`` (V); zero where ``alpha <= beta``."""
        return np.asarray(self._table(alpha, beta), dtype=float)

    def cell_weights(self) -> NDArray[np.float64]:
        """Relay masses per grid cell (V), the mixed second differences of the table.

        ``w[i, j]`` for ``j < i`` is the mass of ``[levels[i], levels[i+1]] x [levels[j],
        levels[j+1]]``; ``w[i, i]`` is the mass of the diagonal half-cell (the reversible
        part).  Negative entries mean the model is not in the class ``Mp``.
        """
        return np.asarray(self._table.cell_weights())

    def fod_grid(self) -> NDArray[np.float64]:
        """Model FOD outputs ``y(levels[i], levels[j])`` (V) for ``j <= i``, NaN above."""
        e = self.everett_values
        y = self.y_min + 2.0 * e[:, :1] - 2.0 * e
        y[np.triu_indices(len(e), 1)] = np.nan
        return y

    # ------------------------------------------------------------------ states
    def negative_saturation(self) -> State:
        """Every relay at -1; input at ``u_min``."""
        return State.negative_saturation(self.u_min, self.u_max)

    def positive_saturation(self) -> State:
        """Every relay at +1; input at ``u_max``."""
        return State.positive_saturation(self.u_min, self.u_max)

    def neutral_state(self, l: float) -> State:  # noqa: E741 (the thesis's symbol)
        """Neutral state psi_n^l of Eq 2.17: boundary ``s = l`` near ``r = 0``, held exactly.

        Parameters
        ----------
        l : float
            Offset of the horizontal boundary segment (V), in ``[u_min, u_max]``; the input
            of the state is ``l``.

        """
        return State.neutral(self.u_min, self.u_max, float(l))

    def anhysteretic_state(self) -> State:
        """Anhysteretic (demagnetised) state: boundary ``s = 0`` (``alpha = -beta``), input 0 V.

        This is the neutral state with ``l = 0`` (the midpoint of the range when 0 V lies
        outside it), reached by a decaying sinusoid about 0 V; the thesis's initial state.
        """
        l0 = 0.0 if self.u_min <= 0.0 <= self.u_max else 0.5 * (self.u_min + self.u_max)
        return self.neutral_state(l0)

    def state_from_extrema(self, extrema: Sequence[float], start: str = "negative") -> State:
        """State reached from a saturation by visiting the given input values in order.

        Parameters
        ----------
        extrema : sequence of float
            Input values (V), e.g. an alternating sequence of maxima and minima; values that
            are not dominant are wiped out as the model would.
        start : {"negative", "positive"}
            Saturation the input starts from.

        """
        if start not in ("negative", "positive"):
            raise ValueError(f"start: expected 'negative' or 'positive', got {start!r}")
        s0 = self.negative_saturation() if start == "negative" else self.positive_saturation()
        return s0.apply([float(x) for x in extrema])

    def readout(self, state: State) -> float:
        """Output Gamma(psi) of a state (V), without simulating (Eq 2.16)."""
        return float(_core.readout(self._table, state))

    def slopes(self, state: State) -> Slopes:
        """One-sided derivatives dy/du (V/V) at a state (Appendix A, Eq A.13/A.27/A.31)."""
        return Slopes(*_core.Simulator(self._table, state).slopes())

    # ------------------------------------------------------------------ simulation
    def simulator(self, state: State | None = None) -> _core.Simulator:
        """Return a step-by-step simulator (``step(u)``, ``run(u)``, ``state``, ``slopes()``)."""
        return _core.Simulator(self._table, self.anhysteretic_state() if state is None else state)

    def inverse(
        self,
        y_ref: ArrayLike,
        state: State | None = None,
        t: ArrayLike | None = None,
        **kwargs: Any,
    ) -> InverseResult:
        """Input (V) that makes the output follow ``y_ref`` (V): the exact inverse.

        ``simulate(r.input, state).output`` reproduces ``y_ref`` wherever it is reachable;
        unreachable targets get the nearest output and are counted.  See
        :func:`preisach.compensate.invert` for the parameters (``sample_time``,
        ``nonmonotone``).
        """
        from .compensate import invert

        return invert(self, y_ref, state, t, **kwargs)

    def inverter(self, state: State | None = None, **kwargs: Any) -> _core.Inverter:
        """Target-by-target inverse: ``step(y)`` returns the input (V).

        See :func:`preisach.compensate.inverter`.
        """
        from .compensate import inverter

        return inverter(self, state, **kwargs)

    def simulate(
        self,
        u: ArrayLike,
        state: State | None = None,
        t: ArrayLike | None = None,
        *,
        sample_time: float = 1e-3,
        out_of_range: str | None = None,
    ) -> SimulationResult:
        """Simulate the output for the input samples ``u``.

        Parameters
        ----------
        u : array_like, shape (n,)
            Input (V), real numbers (float or integer dtype; complex, bool, string and object
            arrays raise :class:`ValueError`).  NaN or inf raises :class:`ValueError` naming
            the sample index.
        state : State, optional
            Initial boundary; default the anhysteretic state.  The first sample moves the
            input from ``state.input`` to ``u[0]``.
        t : array_like, optional
            Sample times (s), finite and strictly increasing (:class:`ValueError` names the
            first bad index); default ``arange(n) * sample_time``.
        sample_time : float
            Sampling period (s) used when ``t`` is not given.
        out_of_range : {"clamp", "raise"}, optional
            Overrides the model's policy for inputs outside ``[u_min, u_max]``.

        Returns
        -------
        SimulationResult

        """
        pol = self._policy(out_of_range)
        uu, tt = _input_and_times(u, t)
        s0 = self.anhysteretic_state() if state is None else state
        if not isinstance(s0, State):
            raise TypeError(
                f"state: expected a preisach.State (e.g. model.negative_saturation(), "
                f"model.positive_saturation(), model.anhysteretic_state()), got {state!r}"
            )
        if not sample_time > 0:
            raise ValueError(f"sample_time: must be positive, got {sample_time}")
        y, final = _core.simulate(self._table, uu, s0, pol)
        return SimulationResult(uu, y, s0, final, float(sample_time), self.name, _time=tt)

    def simulate_batch(
        self,
        u: ArrayLike,
        states: State | Sequence[State] | None = None,
        *,
        threads: int = 0,
        out_of_range: str | None = None,
    ) -> BatchResult:
        """Simulate many runs at once on all cores (the GIL is released).

        Parameters
        ----------
        u : array_like, shape (runs, n) or (n,)
            One input (V) per row (real numbers, as for :meth:`simulate`).  A single row
            (shape ``(1, n)``, or a 1-D input given with a sequence of states) is broadcast:
            it is run once from each of the ``states``, so ``runs = len(states)``.
        states : State or sequence of State, optional
            One initial state for all rows, one per row, or several for a single input row
            (see ``u``); default anhysteretic.
        threads : int
            Worker threads; 0 uses every core.
        out_of_range : {"clamp", "raise"}, optional
            Overrides the model's policy.

        Returns
        -------
        BatchResult
            ``output`` (ndarray, shape (runs, n), V; row ``r`` equals
            ``simulate(u[r], states[r]).output``) and ``final_states`` (list of State);
            unpacks as ``y, final_states``.

        Raises
        ------
        ValueError
            On inputs that are not real numbers, of the wrong shape, non-finite (naming the
            row and sample) or a number of states that is neither 1 nor the number of rows.

        """
        uu = _real_array("u", u)
        if states is None:
            st = [self.anhysteretic_state()]
        elif isinstance(states, State):
            st = [states]
        else:
            st = list(states)
            if not st:
                raise ValueError("states: need at least one initial state")
            bad = [k for k, s in enumerate(st) if not isinstance(s, State)]
            if bad:
                raise TypeError(
                    f"states[{bad[0]}]: expected a preisach State, got {type(st[bad[0]]).__name__}"
                )
        uu = _batch_rows(uu, len(st), states is not None and not isinstance(states, State))
        if threads < 0:
            raise ValueError(f"threads: must be >= 0, got {threads}")
        y, finals = _core.simulate_batch(self._table, uu, st, self._policy(out_of_range), threads)
        return BatchResult(y, list(finals))

    # ------------------------------------------------------------------ persistence
    def save(self, path: PathLike) -> None:
        """Write the model to an ``.npz`` file (versioned format, exact round trip).

        The file is written to a temporary file in the same folder and renamed over ``path``,
        so an existing file is replaced only by a complete model.

        Raises
        ------
        TypeError
            If :attr:`metadata` holds a value that is not JSON-serialisable (``path`` is not
            touched).

        """
        info = _model_info(path, self.name, self.metadata, self.out_of_range)
        cubic = self.interpolation == "cubic"
        arrays: dict[str, Any] = {
            "format": np.array(_FORMAT),
            "version": np.array(3 if cubic else 2 if self.identification else 1),
            "levels": self.levels,
            "everett": self.everett_values,
            "y_min": np.array(self.y_min),
            "info": np.array(info),
        }
        if cubic:
            arrays["interpolation"] = np.array("cubic")
        if self.identification:
            metas = []
            for k, rec in enumerate(self.identification):
                arrays[f"ident{k}_t"], arrays[f"ident{k}_u"] = rec.t, rec.u
                arrays[f"ident{k}_y"] = rec.y
                metas.append(rec.metadata)
            arrays["ident_meta"] = np.array(json.dumps(metas))
        atomic_write(path, lambda f: np.savez(f, **arrays), binary=True, what="model")

    @classmethod
    def load(cls, path: PathLike) -> PreisachModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        ValueError
            Naming the file: if it cannot be read, is empty, truncated or damaged, is not a
            preisach model, misses fields, or its format version is newer than this package
            understands.

        """
        p = os.fspath(path)
        levels, everett, y_min, meta, interp, ident = _read_archive(
            path, lambda p, data: (*cls._read_fields(p, data), cls._read_identification(p, data))
        )
        try:
            table = _core.EverettTable(levels, everett, y_min, interp)
            model = cls(
                table,
                name=str(meta.get("name", "")),
                metadata=meta.get("metadata", {}),
                out_of_range=meta.get("out_of_range", "clamp"),
            )
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{p}: damaged model file ({exc})") from exc
        model.identification = ident
        return model

    @staticmethod
    def _read_identification(p: str, data: Any) -> list[Any]:
        """Return the identification recordings of a version-2 archive (none in version 1)."""
        if "ident_meta" not in data.files:
            return []
        from .recording import Recording

        try:
            metas = json.loads(str(data["ident_meta"]))
            return [
                Recording(data[f"ident{k}_t"], data[f"ident{k}_u"], data[f"ident{k}_y"], metadata=m)
                for k, m in enumerate(metas)
            ]
        except (KeyError, ValueError, TypeError, zipfile.BadZipFile, zlib.error, OSError) as exc:
            raise ValueError(f"{p}: damaged identification recordings ({exc!r})") from exc

    @staticmethod
    def _read_fields(
        p: str, data: Any
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, dict[str, Any], str]:
        """Levels, Everett values, y_min, info and interpolation of an open model archive."""

        def read() -> tuple[NDArray[np.float64], NDArray[np.float64], float, dict[str, Any], str]:
            _, meta = _read_envelope(p, data, _FORMAT, _FIELDS, _FORMAT_VERSION, "preisach model")
            interp = str(data["interpolation"]) if "interpolation" in data.files else "bilinear"
            return data["levels"], data["everett"], float(data["y_min"]), meta, interp

        return _damaged(p, read)

    def __getstate__(self) -> dict[str, Any]:
        return {
            "table": self._table,
            **self._info_state(),
            "identification": self.identification,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._table = state["table"]
        self._set_info_state(state)
        self.identification = list(state.get("identification", []))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PreisachModel):
            return NotImplemented
        return (
            np.array_equal(self.levels, other.levels)
            and np.array_equal(self.everett_values, other.everett_values)
            and self.y_min == other.y_min
            and self.interpolation == other.interpolation
        )

    def _repr_html_(self) -> str:
        """HTML for Jupyter: levels, input and output range, a major-loop thumbnail."""
        from ._display import model_html

        return model_html(self)

    def __repr__(self) -> str:
        nm = f"{self.name!r}, " if self.name else ""
        return (
            f"PreisachModel({nm}{len(self.levels)} levels on [{self.u_min:g}, {self.u_max:g}] V, "
            f"y in [{self.y_min:.4g}, {self.y_max:.4g}] V"
            + (", cubic)" if self.interpolation == "cubic" else ")")
        )
