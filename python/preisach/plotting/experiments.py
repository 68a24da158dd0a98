"""Figures of the neutral states and the regulation experiments (thesis chapters 4-5).

Axes carry units: input u and output y in V, time in s, control effort in DAQ volts, the noise
gain K_n dimensionless.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._figures import figure as _figure
from .._figures import figure_and_axes as _figure_and_axes

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..experiments import ClosedLoopResult, DriftResult, Initialisation, SweepResult
    from ..model import PreisachModel
    from ..neutral import NeutralLocus

_MARKERS = {"n": "o", "a": "^", "d": "v"}
_COLORS = {"n": "C0", "a": "C3", "d": "C2"}
_LABEL = {
    "drift": "differential drift ybar(8,10) - ybar(0,2) (V)",
    "closed-loop": "control effort n_c (DAQ V)",
}

__all__ = [
    "plot_closed_loop_trial",
    "plot_drift_summary",
    "plot_drift_trial",
    "plot_effort_increase",
    "plot_effort_summary",
    "plot_initial_states",
    "plot_locus",
    "plot_neutral_locus",
    "plot_paired_differences",
    "plot_sweep",
    "plot_sweep_traces",
    "plot_trial",
]


def plot_locus(
    locus: NeutralLocus,
    *,
    ax: Axes | None = None,
    model: PreisachModel | None = None,
    points: dict[str, tuple[float, float]] | None = None,
    title: str | None = None,
) -> Figure:
    """Plot ``N(l)`` in the input-output plane (dash-dot), optionally inside the major loop.

    ``NeutralLocus.plot`` draws this.

    Parameters
    ----------
    locus : NeutralLocus
        The locus (:func:`preisach.neutral.neutral_locus`).
    ax : matplotlib Axes, optional
        Axes to draw on; a new figure is made otherwise.
    model : PreisachModel, optional
        Draws the model's major loop (ascending from negative, descending from positive
        saturation) behind the locus, as thesis Figs 4.6-4.8.
    points : dict, optional
        Labelled points ``{label: (u, y)}`` (V, V), e.g. the initial states of a regulation
        test.
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure

    """
    fig, ax = _figure_and_axes(ax, figsize=(6.0, 4.5))
    if model is not None:
        up = np.linspace(model.u_min, model.u_max, 801)
        y_up = model.simulate(up, model.negative_saturation()).output
        y_dn = model.simulate(up[::-1], model.positive_saturation()).output
        ax.plot(up, y_up, color="0.35", lw=1.0, label="major loop")
        ax.plot(up[::-1], y_dn, color="0.35", lw=1.0)
    ax.plot(locus.l, locus.N, "-.", color="C3", lw=1.5, label="neutral locus N(l)")
    for k, (label, (u, y)) in enumerate((points or {}).items()):
        ax.plot([u], [y], "o", color=f"C{k}", label=label)
    ax.set_xlabel("input u, l (V)")
    ax.set_ylabel("output y (V)")
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize="small")
    return fig


def plot_neutral_locus(
    model: PreisachModel,
    *,
    y_d: float | None = None,
    states: Mapping[str, Initialisation] | Sequence[Initialisation] | None = None,
    frequency: float = 1.0,
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """Draw the neutral locus N(l) inside the major loop, with psi_n, psi_a, psi_d (Figs 4.6-4.8).

    ``N(l)`` (Eq 2.18) is the output of the neutral state psi_n^l; the thesis's regulation
    experiments start from three states with the same output ``y_d``: the neutral state
    psi_n (on the locus), psi_a (reached on an ascending branch, Eq 4.3) and psi_d (on a
    descending branch, Eq 4.4).  Each is marked at ``(offset, output)``: the input held from
    ``t_1`` and the output there.

    Parameters
    ----------
    model : PreisachModel
        The model (its major loop and exact locus are drawn).
    y_d : float, optional
        Desired output (V).  Without ``states``, the three states are found on the model
        with :func:`preisach.experiments.drive_to_state` at ``frequency``; a dotted line marks
        ``y = y_d``.
    states : mapping or sequence of Initialisation, optional
        Initial states reached already (e.g. ``SweepResult`` runs or ``drive_to_state``).
    frequency : float
        Initialisation frequency (Hz) when the states are found here.
    ax : Axes, optional
        Draw here instead of on a new figure.
    title : str, optional
        Axes title (default the model's name).

    Returns
    -------
    Figure
        Output y (V) against input u and offset l (V).

    """
    from ..neutral import neutral_locus

    inits: list[Initialisation] = []
    if states is not None:
        inits = list(states.values()) if isinstance(states, Mapping) else list(states)
    elif y_d is not None:
        from ..experiments import ModelPlant, drive_to_state, thesis_sample_time

        plant = ModelPlant(model, thesis_sample_time(float(frequency)))
        inits = [drive_to_state(plant, k, float(y_d), float(frequency)) for k in ("n", "a", "d")]
    points = {f"{i.name}: u = {i.offset:.2f} V": (i.offset, i.y_end) for i in inits}
    fig = neutral_locus(model).plot(
        ax=ax, model=model, points=points, title=title or (model.name or "Preisach model")
    )
    target_ax = ax if ax is not None else fig.axes[0]
    target = y_d if y_d is not None else (inits[0].y_d if inits else None)
    if target is not None:
        target_ax.axhline(float(target), color="k", ls=":", lw=0.8, label=f"y_d = {target:g} V")
        target_ax.legend(loc="upper left", fontsize="small")
    return fig


def plot_trial(result: DriftResult | ClosedLoopResult, *, fig: Figure | None = None) -> Figure:
    """Draw one drift trial (Figs 4.9-4.11) or closed-loop trial (Figs 5.2-5.4) against time.

    The same as ``result.plot()``.
    """
    from ..experiments import ClosedLoopResult

    if isinstance(result, ClosedLoopResult):
        return plot_closed_loop_trial(result, fig=fig)
    return plot_drift_trial(result, fig=fig)


def plot_drift_trial(result: DriftResult, *, fig: Figure | None = None) -> Figure:
    """Input and output against time after ``t_1``, with the averaging windows marked."""
    t = result.time
    fig = _figure(fig, figsize=(8.0, 5.0))
    ax_u, ax_y = fig.subplots(2, 1, sharex=True)
    ax_u.plot(t, result.input, lw=0.7)
    ax_u.set_ylabel("input u (V)")
    ax_y.plot(t, result.output, lw=0.8)
    ax_y.axhline(result.ybar_before, color="C1", ls="--", lw=0.8, label="ybar before")
    ax_y.axhline(result.ybar_after, color="C2", ls="--", lw=0.8, label="ybar after")
    ax_y.set_xlabel("time after t1 (s)")
    ax_y.set_ylabel("output y (V)")
    ax_y.legend(fontsize="small")
    ax_u.set_title(
        f"open-loop drift from psi_{result.kind}, f = {result.frequency:g} Hz, "
        f"K_n = {result.gain:g}: drift {result.drift:+.4f} V"
    )
    return fig


def plot_closed_loop_trial(result: ClosedLoopResult, *, fig: Figure | None = None) -> Figure:
    """Output, controller output and input against time after ``t_1``."""
    t = result.time
    fig = _figure(fig, figsize=(8.0, 6.5))
    ax_y, ax_c, ax_u = fig.subplots(3, 1, sharex=True)
    ax_y.plot(t, result.output, lw=0.8)
    ax_y.axhline(result.setpoint, color="k", ls=":", lw=0.8, label="y_d")
    ax_y.set_ylabel("output y (V)")
    ax_y.legend(fontsize="small")
    ax_c.plot(t, result.control, lw=0.7, color="C1")
    ax_c.axhline(result.uc_baseline, color="k", ls=":", lw=0.8)
    ax_c.set_ylabel("controller u_c (DAQ V)")
    ax_u.plot(t, result.input, lw=0.7, color="C2")
    ax_u.set_ylabel("input u (V)")
    ax_u.set_xlabel("time after t1 (s)")
    ax_y.set_title(
        f"closed loop from psi_{result.kind}, f = {result.frequency:g} Hz, K_n = "
        f"{result.gain:g}: n_c = {result.nc:.3f}"
    )
    return fig


def _sweep_of(result: SweepResult, experiment: str, what: str) -> SweepResult:
    if result.experiment != experiment:
        raise ValueError(f"{what}: needs a {experiment!r} sweep, got a {result.experiment!r} sweep")
    return result


def plot_sweep(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Plot the metric against noise gain per frequency: Fig 4.12 (drift), Figs 5.5-5.7 (n_c).

    Markers are the means over seeds, bars one standard deviation; ``SweepResult.plot``.
    """
    from ..experiments.sweep import _stats

    fig, axes = _gain_panels(result, fig)
    gs = np.array(result.gains)
    for ax, f in zip(axes, result.frequencies):
        for j, k in enumerate(result.kinds):
            st = [_stats(result.values(f, k, g)) for g in gs]
            mean = np.array([s["mean"] for s in st])
            sd = np.array([s["std"] for s in st])
            _bars(ax, gs + (j - 1) * 0.06, mean, sd, k, f"psi_{k}")
        if result.experiment == "drift":
            ax.axhline(0.0, color="k", lw=0.6)
    axes[0].set_ylabel(_LABEL[result.experiment])
    axes[0].legend(fontsize="small")
    fig.tight_layout()
    return fig


def _gain_panels(result: SweepResult, fig: Figure | None) -> tuple[Figure, list[Axes]]:
    """One panel per frequency, noise gain on the x axis."""
    fs = result.frequencies
    fig = _figure(fig, figsize=(4.2 * len(fs), 3.8))
    axes = list(fig.subplots(1, len(fs), squeeze=False)[0])
    for ax, f in zip(axes, fs):
        ax.set_title(f"f = {f:g} Hz")
        ax.set_xlabel("noise gain K_n (1)")
        ax.grid(True, alpha=0.3)
    return fig, axes


def _bars(
    ax: Axes,
    x: NDArray[np.float64],
    mean: NDArray[np.float64],
    sd: NDArray[np.float64],
    state: str,
    label: str,
) -> None:
    """Means with one-standard-deviation bars in the state's marker and colour."""
    ax.errorbar(
        x,
        mean,
        yerr=sd,
        fmt=_MARKERS[state],
        color=_COLORS[state],
        ms=5,
        capsize=2,
        lw=0.8,
        label=label,
    )


def plot_drift_summary(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Differential drift against noise gain per frequency and initial state (Fig 4.12).

    Means over seeds with one-standard-deviation bars: what ``SweepResult.plot`` draws for a
    drift sweep (:func:`plot_sweep`).
    """
    return plot_sweep(_sweep_of(result, "drift", "plot_drift_summary"), fig=fig)


def plot_effort_summary(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Control effort n_c against noise gain per frequency and initial state (Figs 5.5-5.7).

    Means over seeds with one-standard-deviation bars: what ``SweepResult.plot`` draws for a
    closed-loop sweep (:func:`plot_sweep`).
    """
    return plot_sweep(_sweep_of(result, "closed-loop", "plot_effort_summary"), fig=fig)


def plot_paired_differences(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Paired differences ``metric(psi_x) - metric(psi_n)`` against gain (Figs 5.10-5.12 style).

    Each trial from psi_a (upward triangles) and psi_d (downward triangles) is compared with
    the psi_n trial of the same seed (same noise); markers are the means over seeds, bars one
    standard deviation.  For the drift the magnitudes are compared, ``|drift(psi_x)| -
    |drift(psi_n)|``: positive means psi_n drifted less.
    """
    if not {"n", "a", "d"} <= set(result.kinds):
        raise ValueError("plot_differences: needs the states n, a and d")
    fig, axes = _gain_panels(result, fig)
    mag = np.abs if result.experiment == "drift" else (lambda v: v)
    gs = np.array(result.gains)
    for ax, f in zip(axes, result.frequencies):
        for j, x in enumerate(("a", "d")):
            diffs = [mag(result.values(f, x, g)) - mag(result.values(f, "n", g)) for g in gs]
            mean = np.array([d.mean() for d in diffs])
            sd = np.array([d.std(ddof=1) if d.size > 1 else np.nan for d in diffs])
            _bars(ax, gs + (j - 0.5) * 0.08, mean, sd, x, f"psi_{x} - psi_n")
        ax.axhline(0.0, color="k", lw=0.6)
    axes[0].set_ylabel(
        "paired difference |drift| (V)"
        if result.experiment == "drift"
        else "paired difference of n_c (DAQ V)"
    )
    axes[0].legend(fontsize="small")
    fig.tight_layout()
    return fig


def plot_sweep_traces(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Plot the output from each initial state per frequency (Figs 4.9-4.11, 5.2-5.4)."""
    if not result.traces:
        raise ValueError("this sweep kept no traces (trace=None)")
    from ..experiments.initialisation import KINDS

    fs = sorted({f for f, _ in result.traces})
    fig = _figure(fig, figsize=(8.0, 2.6 * len(fs)))
    axes = np.atleast_1d(fig.subplots(len(fs), 1, squeeze=False)[:, 0])
    for ax, f in zip(axes, fs):
        gain = None
        for k in KINDS:
            tr = result.traces.get((f, k))
            if tr is None:
                continue
            gain = tr.gain
            ax.plot(tr.time, tr.output, lw=0.7, color=_COLORS[k], label=f"psi_{k}")
        ax.set_ylabel("output y (V)")
        ax.set_title(f"f = {f:g} Hz, K_n = {gain:g}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", ncol=3)
    axes[-1].set_xlabel("time after t1 (s)")
    fig.tight_layout()
    return fig


def plot_initial_states(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Major loop, neutral locus and the initial states, one panel per frequency (Figs 4.6-4.8).

    Needs model plants.
    """
    if not result.models:
        raise ValueError("plot_initial_states: needs the models (sweeps on model plants keep them)")
    from ..neutral import neutral_locus

    fs = sorted(result.models)
    fig = _figure(fig, figsize=(4.5 * len(fs), 4.0))
    axes = np.atleast_1d(fig.subplots(1, len(fs), squeeze=False)[0])
    for ax, f in zip(axes, fs):
        pts = {
            f"psi_{s['state']}": (s["offset"], s["y_end"])
            for s in result.states
            if s["frequency"] == f
        }
        neutral_locus(result.models[f]).plot(
            ax=ax, model=result.models[f], points=pts, title=f"f = {f:g} Hz"
        )
    fig.tight_layout()
    return fig


def plot_effort_increase(
    result: SweepResult, *, ax: Axes | None = None, title: str | None = None
) -> Figure:
    """Table 5.1 as a figure: extra control effort from psi_a and psi_d relative to psi_n.

    ``100 (n_c(psi_x) - n_c(psi_n)) / n_c(psi_n)`` (percent, from the means over seeds)
    against the normalised noise gain ``K_n / max K_n``, one line per initial state and
    frequency (solid psi_a, dashed psi_d).  Positive values mean psi_n needs less effort.

    Parameters
    ----------
    result : SweepResult
        A closed-loop sweep with the states n, a and d.
    ax : Axes, optional
        Draw here instead of on a new figure.
    title : str, optional
        Axes title.

    Returns
    -------
    Figure

    """
    rows = _sweep_of(result, "closed-loop", "plot_effort_increase").percentage_table()
    fig, ax = _figure_and_axes(ax, figsize=(6.0, 4.2))
    x = np.array([r["normalised_gain"] for r in rows])
    for j, f in enumerate(result.frequencies):
        for kind, style, marker in (("a", "-", "^"), ("d", "--", "v")):
            y = np.array([r[f"{kind}_{f:g}"] for r in rows])
            ax.plot(x, y, ls=style, marker=marker, color=f"C{j}", label=f"psi_{kind}, f = {f:g} Hz")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("normalised noise gain K_n / max K_n (1)")
    ax.set_ylabel("n_c increase over psi_n (%)")
    ax.set_title(title or "extra control effort from psi_a and psi_d (Table 5.1)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
    return fig
