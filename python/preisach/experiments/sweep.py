"""Sweeps of the regulation experiments over frequencies, initial states, noise gains and seeds.

:func:`regulation_sweep` runs the open-loop drift test (chapter 4) or the closed-loop PI test
(chapter 5) for every initialisation frequency (each with its own plant - for the SS15 the model
identified at that frequency), every initial state psi_n/psi_a/psi_d, every noise gain ``K_n``
and every seed, and returns a :class:`SweepResult`: a tidy table (one row per trial) with
summaries over seeds, the state-by-state comparisons the thesis draws, the percentage table of
Table 5.1, the slopes of Appendix A at each initial state, and figures in the style of
Fig 4.12 (drift), Figs 5.5-5.7 (control effort), Figs 4.9-4.11 / 5.2-5.4 (example traces) and
Figs 4.6-4.8 (initial states on the major loop and the neutral locus).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._io import write_text
from ..execution import run_tasks
from ..model import PreisachModel, State
from .closed_loop import ClosedLoopResult, closed_loop_trials
from .drift import DriftResult, drift_trials
from .initialisation import KINDS, Initialisation, drive_to_state
from .plant import ModelPlant, Plant, ss15_plants, thesis_sample_time
from .protocol import THESIS_GAINS, ClosedLoopProtocol, DriftProtocol

if TYPE_CHECKING:  # pragma: no cover
    from distributed import Client
    from matplotlib.figure import Figure

__all__ = ["EXPERIMENTS", "SweepResult", "regulation_sweep", "state_slopes"]

#: Experiments a sweep can run.
EXPERIMENTS: tuple[str, ...] = ("drift", "closed-loop")
_METRIC = {"drift": "drift", "closed-loop": "nc"}


def state_slopes(
    model: PreisachModel, state: State, amplitude: float | None = None
) -> dict[str, float]:
    """How the output answers small and finite input moves at a state (Appendix A).

    Parameters
    ----------
    model : PreisachModel
        The model.
    state : State
        The state (its input is the current input ``u``).
    amplitude : float, optional
        A finite input excursion ``a`` (V), e.g. the peak of the injected noise.

    Returns
    -------
    dict
        ``dy_du_rising``, ``dy_du_falling`` (V/V): the one-sided derivatives of Eq A.13 and
        A.27.  With ``amplitude``: ``secant_rising = (y(u + a) - y) / a`` and ``secant_falling
        = (y - y(u - a)) / a`` (V/V), and ``residual_up`` / ``residual_down`` (V): the output
        change left behind by one excursion ``u -> u + a -> u`` or ``u -> u - a -> u`` - zero-mean
        noise drifts the output by the imbalance of these two.

    """
    sl = model.slopes(state)
    out = {"dy_du_rising": float(sl.rising), "dy_du_falling": float(sl.falling)}
    if amplitude is not None:
        a = float(amplitude)
        if not (math.isfinite(a) and a > 0):
            raise ValueError(f"amplitude: must be positive (V), got {amplitude!r}")
        u = state.input
        y = model.readout(state)
        up, dn = min(u + a, model.u_max), max(u - a, model.u_min)
        y_up = model.readout(state.apply([up]))
        y_dn = model.readout(state.apply([dn]))
        out.update(
            {
                "amplitude": a,
                "secant_rising": (y_up - y) / a,
                "secant_falling": (y - y_dn) / a,
                "residual_up": model.readout(state.apply([up, u])) - y,
                "residual_down": model.readout(state.apply([dn, u])) - y,
            }
        )
    return out


def _stats(v: np.ndarray) -> dict[str, float]:
    n = v.size
    std = float(np.std(v, ddof=1)) if n > 1 else float("nan")
    return {
        "n": int(n),
        "mean": float(np.mean(v)),
        "std": std,
        "sem": std / math.sqrt(n) if n > 1 else float("nan"),
        "min": float(np.min(v)),
        "max": float(np.max(v)),
    }


@dataclass
class SweepResult:
    """Results of :func:`regulation_sweep`.

    Attributes
    ----------
    experiment : str
        ``"drift"`` or ``"closed-loop"``.
    rows : list of dict
        One row per trial: ``frequency``, ``state`` (``"n"``, ``"a"``, ``"d"``), ``gain``,
        ``seed``, ``offset`` and the metrics (``drift``, ``ybar_before``, ``ybar_after``; or
        ``nc``, ``nc_l2``, ``uc_baseline``, ``error_rms``, ``error_final``).
    states : list of dict
        One entry per (frequency, initial state): offset, output at ``t_1``, search runs and,
        for model plants, the slopes of :func:`state_slopes`.
    traces : dict
        ``{(frequency, state): DriftResult | ClosedLoopResult}`` with arrays, for one gain and
        seed (see ``trace`` of :func:`regulation_sweep`).
    config : dict
        Protocol, gains, seeds and plant sample times.

    """

    experiment: str
    rows: list[dict[str, Any]]
    states: list[dict[str, Any]]
    traces: dict[tuple[float, str], DriftResult | ClosedLoopResult] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    models: dict[float, PreisachModel] = field(default_factory=dict, repr=False)

    @property
    def metric(self) -> str:
        """The headline metric: ``"drift"`` or ``"nc"``."""
        return _METRIC[self.experiment]

    @property
    def frequencies(self) -> list[float]:
        """Initialisation frequencies (Hz), increasing."""
        return sorted({r["frequency"] for r in self.rows})

    @property
    def gains(self) -> list[float]:
        """Noise gains, increasing."""
        return sorted({r["gain"] for r in self.rows})

    @property
    def kinds(self) -> list[str]:
        """Initial states present, in the order n, a, d."""
        present = {r["state"] for r in self.rows}
        return [k for k in KINDS if k in present]

    # ---------------------------------------------------------------- tables
    def to_records(self) -> list[dict[str, Any]]:
        """Return the tidy table: a list of one dict per trial (copies)."""
        return [dict(r) for r in self.rows]

    def to_csv(self, path: str | None = None) -> str:
        """Return the tidy table as CSV text (header row first); also write it to ``path``."""
        buf = io.StringIO()
        keys = list(self.rows[0]) if self.rows else []
        w = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        for r in self.rows:
            w.writerow({k: (repr(float(v)) if isinstance(v, float) else v) for k, v in r.items()})
        text = buf.getvalue()
        if path is not None:
            write_text(path, text, what="CSV table")
        return text

    def values(
        self, frequency: float, state: str, gain: float, metric: str | None = None
    ) -> np.ndarray:
        """Return the metric over seeds for one cell, ordered by seed."""
        m = self.metric if metric is None else metric
        sel = sorted(
            (r["seed"], r[m])
            for r in self.rows
            if r["frequency"] == frequency and r["state"] == state and r["gain"] == gain
        )
        return np.array([v for _, v in sel], dtype=float)

    def summary(self, metric: str | None = None) -> list[dict[str, Any]]:
        """Summarise per (frequency, state, gain): n, mean, std (ddof 1), sem, min, max."""
        m = self.metric if metric is None else metric
        out = []
        for f in self.frequencies:
            for k in self.kinds:
                for g in self.gains:
                    v = self.values(f, k, g, m)
                    if v.size:
                        out.append(
                            {"frequency": f, "state": k, "gain": g, "metric": m, **_stats(v)}
                        )
        return out

    def comparisons(self) -> list[dict[str, Any]]:
        """Check the thesis's claims per (frequency, gain) on the means over seeds.

        For both experiments: ``n_smallest`` - ``|mean(psi_n)|`` below ``|mean(psi_a)|`` and
        ``|mean(psi_d)|`` - and the fractions of seeds where ``|psi_n| < |psi_a|`` and
        ``|psi_n| < |psi_d|`` in the paired trials (same noise).  For the drift also
        ``a_up`` (mean drift from psi_a > 0) and ``d_down`` (mean drift from psi_d < 0).
        """
        out: list[dict[str, Any]] = []
        if not {"n", "a", "d"} <= set(self.kinds):
            return out
        for f in self.frequencies:
            for g in self.gains:
                vn, va, vd = (self.values(f, k, g) for k in ("n", "a", "d"))
                if not (vn.size == va.size == vd.size and vn.size):
                    continue
                row: dict[str, Any] = {
                    "frequency": f,
                    "gain": g,
                    "mean_n": float(vn.mean()),
                    "mean_a": float(va.mean()),
                    "mean_d": float(vd.mean()),
                    "n_smallest": bool(
                        abs(vn.mean()) < abs(va.mean()) and abs(vn.mean()) < abs(vd.mean())
                    ),
                    "frac_n_below_a": float(np.mean(np.abs(vn) < np.abs(va))),
                    "frac_n_below_d": float(np.mean(np.abs(vn) < np.abs(vd))),
                }
                if self.experiment == "drift":
                    row["a_up"] = bool(va.mean() > 0)
                    row["d_down"] = bool(vd.mean() < 0)
                out.append(row)
        return out

    def percentage_table(self) -> list[dict[str, Any]]:
        """Table 5.1: ``100 (n_c(psi_x) - n_c(psi_n)) / n_c(psi_n)`` per gain and frequency.

        Computed from the means over seeds (the thesis used the mean of seven trials).  Each row
        has ``gain``, ``normalised_gain`` (``K_n / max K_n``, the thesis's first column) and
        ``a_<f>`` / ``d_<f>`` for every frequency ``f`` (percent).
        """
        if self.experiment != "closed-loop":
            raise ValueError("percentage_table: only for the closed-loop experiment (n_c)")
        gmax = max(self.gains)
        rows = []
        for g in self.gains:
            row: dict[str, Any] = {"gain": g, "normalised_gain": g / gmax}
            for x in ("a", "d"):
                for f in self.frequencies:
                    vn, vx = self.values(f, "n", g), self.values(f, x, g)
                    row[f"{x}_{f:g}"] = (
                        float(100.0 * (vx.mean() - vn.mean()) / vn.mean())
                        if vn.size and vx.size
                        else float("nan")
                    )
            rows.append(row)
        return rows

    def format_summary(self) -> str:
        """Mean +/- std over seeds per frequency and gain, the three states side by side."""
        m = self.metric
        lines = []
        kinds = self.kinds
        head = f"{'f (Hz)':>6} {'K_n':>5} " + " ".join(
            f"{'psi_' + k + ' mean +/- std':>24}" for k in kinds
        )
        lines.append(head)
        for f in self.frequencies:
            for g in self.gains:
                cells = []
                for k in kinds:
                    v = self.values(f, k, g, m)
                    sd = np.std(v, ddof=1) if v.size > 1 else float("nan")
                    cells.append(f"{v.mean():>+12.4f} +/- {sd:<8.4f}")
                lines.append(f"{f:>6g} {g:>5.1f} " + " ".join(f"{c:>24}" for c in cells))
        return "\n".join(lines)

    def format_percentage_table(self) -> str:
        """Table 5.1 as text (percent)."""
        rows = self.percentage_table()
        fs = self.frequencies
        head = (
            f"{'K_n/max':>8} "
            + " ".join(f"{'a ' + format(f, 'g') + ' Hz':>9}" for f in fs)
            + "  "
            + " ".join(f"{'d ' + format(f, 'g') + ' Hz':>9}" for f in fs)
        )
        lines = [head]
        for r in rows:
            lines.append(
                f"{r['normalised_gain']:>8.4f} "
                + " ".join(f"{r[f'a_{f:g}']:>9.3f}" for f in fs)
                + "  "
                + " ".join(f"{r[f'd_{f:g}']:>9.3f}" for f in fs)
            )
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """HTML for Jupyter: mean +/- std per state, Table 5.1, the thesis's claims."""
        from .._display import sweep_html

        return sweep_html(self)

    def to_dict(self) -> dict[str, Any]:
        """Everything but the traces, JSON-serialisable."""
        d: dict[str, Any] = {
            "experiment": self.experiment,
            "config": self.config,
            "states": self.states,
            "rows": self.rows,
            "summary": self.summary(),
            "comparisons": self.comparisons(),
        }
        if self.experiment == "closed-loop":
            d["percentage_table"] = self.percentage_table()
        return d

    # ---------------------------------------------------------------- figures
    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Plot the metric against noise gain per frequency: Fig 4.12 or Figs 5.5-5.7.

        Drawn by :func:`preisach.plotting.plot_sweep`.
        """
        from ..plotting.experiments import plot_sweep

        return plot_sweep(self, fig=fig)

    def plot_differences(self, *, fig: Figure | None = None) -> Figure:
        """Paired differences psi_x - psi_n against gain.

        Drawn by :func:`preisach.plotting.plot_paired_differences`.
        """
        from ..plotting.experiments import plot_paired_differences

        return plot_paired_differences(self, fig=fig)

    def plot_traces(self, *, fig: Figure | None = None) -> Figure:
        """Output from each initial state per frequency.

        Drawn by :func:`preisach.plotting.plot_sweep_traces`.
        """
        from ..plotting.experiments import plot_sweep_traces

        return plot_sweep_traces(self, fig=fig)

    def plot_initial_states(self, *, fig: Figure | None = None) -> Figure:
        """Major loop, neutral locus and the initial states per frequency.

        Drawn by :func:`preisach.plotting.plot_initial_states`.
        """
        from ..plotting.experiments import plot_initial_states

        return plot_initial_states(self, fig=fig)


@dataclass(frozen=True)
class _SweepTask:
    """One task of a sweep: every seed at one frequency, initial state and gain."""

    frequency: float
    kind: str
    gain: float
    keep_traces: bool

    @property
    def key(self) -> str:
        return f"f{self.frequency:g}-{self.kind}-g{self.gain:.17g}"


def _sweep_task(
    task: _SweepTask,
    *,
    plants: Mapping[float, Plant],
    experiment: str,
    protocol: DriftProtocol | ClosedLoopProtocol,
    seeds: list[int],
    y_d: float,
    init_options: Mapping[str, Any],
    amplitude: float,
) -> tuple[dict[str, Any], list[dict[str, Any]], list[DriftResult | ClosedLoopResult]]:
    """Initialise the plant, run every seed at one gain: (init info, rows, kept traces)."""
    f, k = task.frequency, task.kind
    plant = plants[f]
    model = getattr(plant, "model", None)
    init: Initialisation = drive_to_state(plant, k, y_d, f, **dict(init_options))
    info: dict[str, Any] = {"frequency": f, "state": k, **init.to_dict()}
    info.pop("kind")
    if isinstance(model, PreisachModel) and init.state is not None:
        info.update(state_slopes(model, init.state, amplitude))
        if k == "n" and init.l_inverse is not None:
            exact = model.slopes(model.neutral_state(init.l_inverse))
            info["exact_dy_du_rising"] = float(exact.rising)
            info["exact_dy_du_falling"] = float(exact.falling)
    gains = [task.gain] * len(seeds)
    keep = task.keep_traces
    results: list[DriftResult] | list[ClosedLoopResult]
    if experiment == "drift":
        assert isinstance(protocol, DriftProtocol)
        results = drift_trials(plant, init, gains, seeds, protocol, keep_traces=keep)
    else:
        assert isinstance(protocol, ClosedLoopProtocol)
        results = closed_loop_trials(plant, init, gains, seeds, protocol, keep_traces=keep)
    rows: list[dict[str, Any]] = []
    kept: list[DriftResult | ClosedLoopResult] = []
    for res in results:
        d = res.to_dict()
        del d["frequency"]
        row = {
            "frequency": f,
            "state": d.pop("kind"),
            "gain": d.pop("gain"),
            "seed": d.pop("seed"),
        }
        row.update(d)
        rows.append(row)
        if task.keep_traces:
            kept.append(res)
    return info, rows, kept


def _plants(plants: Mapping[float, Plant | PreisachModel] | None) -> dict[float, Plant]:
    if plants is None:
        return dict(ss15_plants())
    out: dict[float, Plant] = {}
    for f, p in plants.items():
        fk = float(f)
        if isinstance(p, PreisachModel):
            out[fk] = ModelPlant(p, thesis_sample_time(fk))
        elif isinstance(p, Plant):
            out[fk] = p
        else:
            raise TypeError(
                f"plants[{f!r}]: expected a Plant or a PreisachModel, got {type(p).__name__}"
            )
    return out


def regulation_sweep(
    experiment: str,
    plants: Mapping[float, Plant | PreisachModel] | None = None,
    *,
    states: Sequence[str] = KINDS,
    gains: Sequence[float] = THESIS_GAINS,
    seeds: Iterable[int] = range(20),
    y_d: float = 1.0,
    protocol: DriftProtocol | ClosedLoopProtocol | None = None,
    init_options: Mapping[str, Any] | None = None,
    trace: tuple[float, int | None] | None = (1.6, None),
    slope_gain: float = 1.6,
    scheduler: str | None = "serial",
    client: Client | None = None,
    store: str | os.PathLike[str] | None = None,
    progress: bool = True,
) -> SweepResult:
    """Run the drift or closed-loop experiment over frequencies, states, gains and seeds.

    Parameters
    ----------
    experiment : {"drift", "closed-loop"}
        Chapter 4's open-loop drift test or chapter 5's PI test.
    plants : mapping, optional
        ``{frequency (Hz): Plant or PreisachModel}``; a model is wrapped in a
        :class:`ModelPlant` at :func:`thesis_sample_time`.  Default :func:`ss15_plants`: the
        built-in SS15 models, each at its identification frequency.
    states : sequence of {"n", "a", "d"}
        Initial states.
    gains : sequence of float
        Noise gains ``K_n``; default ``0.8 i``, ``i = 1..7``.
    seeds : iterable of int
        Noise seeds; the same seeds are used for every state and frequency (paired trials).
    y_d : float
        Desired output (V); the thesis uses 1 V.
    protocol : DriftProtocol or ClosedLoopProtocol, optional
        Timing, noise and controller; thesis defaults.
    init_options : mapping, optional
        Keyword arguments of :func:`drive_to_state` (``cycles``, ``tolerance``, ...).
    trace : (gain, seed) or None
        Keep the arrays of this trial for every (frequency, state); seed ``None`` means the
        first seed.  Default: ``K_n = 1.6`` as in Figs 4.9-4.11 and 5.2-5.4.
    slope_gain : float
        ``K_n`` whose noise peak is the finite excursion of :func:`state_slopes`.
    scheduler : str, optional
        Where the (frequency, state, gain) tasks run: ``"serial"`` (default), ``"processes[:N]"``,
        ``"local[:N]"`` (a Dask LocalCluster) or a Dask scheduler address
        (:mod:`preisach.execution`).  Every scheduler gives the same result, bit for bit.
    client : distributed.Client, optional
        A running Dask client (overrides ``scheduler``).
    store : str or path-like, optional
        Keep each finished task in this folder; a rerun with the same folder and parameters
        skips them (resume after an interruption).
    progress : bool
        Show a progress bar over the tasks (``False``: nothing).

    Returns
    -------
    SweepResult

    """
    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiment: expected one of {EXPERIMENTS}, got {experiment!r}")
    if experiment == "drift":
        proto = DriftProtocol() if protocol is None else protocol
        if not isinstance(proto, DriftProtocol):
            raise TypeError(
                f"protocol: the drift experiment needs a DriftProtocol, got {type(proto).__name__}"
            )
    else:
        proto = ClosedLoopProtocol() if protocol is None else protocol
        if not isinstance(proto, ClosedLoopProtocol):
            raise TypeError(
                "protocol: the closed-loop experiment needs a ClosedLoopProtocol, got "
                f"{type(proto).__name__}"
            )
    pl = _plants(plants)
    seed_list = [int(s) for s in seeds]
    gain_list = [float(g) for g in gains]
    if not seed_list or not gain_list:
        raise ValueError("seeds and gains: need at least one of each")
    kinds = [str(k) for k in states]
    for k in kinds:
        if k not in KINDS:
            raise ValueError(f"states: expected entries 'n', 'a', 'd', got {k!r}")
    tr_gain, tr_seed = (None, None) if trace is None else trace
    if trace is not None and tr_seed is None:
        tr_seed = seed_list[0]
    amp = proto.noise.amplitude * proto.input_gain * float(slope_gain)
    freqs = sorted(pl)
    tasks = [
        _SweepTask(
            f,
            k,
            g,
            tr_gain is not None and math.isclose(g, tr_gain) and tr_seed in seed_list,
        )
        for f in freqs
        for k in kinds
        for g in gain_list
    ]
    shared = {
        "plants": pl,
        "experiment": experiment,
        "protocol": proto,
        "seeds": seed_list,
        "y_d": y_d,
        "init_options": dict(init_options or {}),
        "amplitude": amp,
    }
    tag = repr((experiment, freqs, kinds, gain_list, seed_list, y_d, proto.to_dict(), amp))
    outs = run_tasks(
        _sweep_task,
        tasks,
        keys=[f"{i:05d}-{t.key}" for i, t in enumerate(tasks)],
        scheduler=scheduler,
        client=client,
        shared=shared,
        store=store,
        store_tag="regulation_sweep " + tag,
        progress=progress,
        desc=f"{experiment} sweep",
    )
    rows: list[dict[str, Any]] = []
    infos: list[dict[str, Any]] = []
    traces: dict[tuple[float, str], DriftResult | ClosedLoopResult] = {}
    models: dict[float, PreisachModel] = {}
    initialised: set[tuple[float, str]] = set()
    for task, (info, task_rows, kept) in zip(tasks, outs):
        model = getattr(pl[task.frequency], "model", None)
        if isinstance(model, PreisachModel):
            models[task.frequency] = model
        if (task.frequency, task.kind) not in initialised:  # one per (frequency, state)
            initialised.add((task.frequency, task.kind))
            infos.append(info)
        rows.extend(task_rows)
        for res in kept:
            if res.seed == tr_seed:
                traces[(task.frequency, task.kind)] = res
    config = {
        "experiment": experiment,
        "y_d": y_d,
        "gains": gain_list,
        "seeds": seed_list,
        "states": kinds,
        "protocol": proto.to_dict(),
        "init_options": dict(init_options or {}),
        "sample_times": {f"{f:g}": float(p.sample_time) for f, p in pl.items()},
        "plants": {f"{f:g}": repr(p) for f, p in pl.items()},
        "slope_amplitude": amp,
    }
    return SweepResult(experiment, rows, infos, traces, config, models)
