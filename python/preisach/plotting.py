"""Every figure of :mod:`preisach` in one place: each returns the Figure, none calls show().

Axes are labelled with units: inputs alpha, beta, r, s and u in volts (V), outputs y in volts
(V), time in seconds (s), rates in V/s, the weight density in V/V^2, kappa in V/V, control
effort in DAQ volts.  Functions that live next to the objects they draw are re-exported here
unchanged (the same function objects), so ``preisach.plotting`` is where users find them all:

Preisach model (chapter 2)
    :func:`plot_major_loop` (major loop and FOD curves), :func:`plot_simulation`,
    :func:`plot_boundary` (the Preisach plane with P+ / P- and the boundary psi of a state, in
    (alpha, beta) or (r, s)), :func:`plot_everett` (the Everett function E as a surface in
    (alpha, beta) or (r, s)).
Identification (chapter 3, from :mod:`preisach.identify.plots`)
    :func:`plot_fod_data` (Figs 3.18-3.20), :func:`plot_fod_surface` (Figs 3.30-3.35),
    :func:`plot_weights` (the density of mu, Figs 3.36-3.44), :func:`plot_kappa` (Figs 3.37,
    3.39, 3.41), :func:`plot_cv`, :func:`plot_identification` (six panels of an
    identification report) and :func:`plot_verification` (Figs 3.48, 3.52, 3.56).
Neutral states and regulation (chapters 4-5, from :mod:`preisach.neutral` and
:mod:`preisach.experiments`)
    :func:`plot_neutral_locus` (N(l) over the major loop with psi_n, psi_a, psi_d marked,
    Figs 4.6-4.8), :func:`plot_trial` (one drift or PI trial, Figs 4.9-4.11 / 5.2-5.4),
    :func:`plot_drift_summary` (Fig 4.12), :func:`plot_effort_summary` (Figs 5.5-5.7),
    :func:`plot_effort_increase` (Table 5.1 as a figure), :func:`plot_paired_differences`,
    :func:`plot_sweep_traces`, :func:`plot_initial_states`.
Diagnosis (:mod:`preisach.diagnose`)
    :func:`plot_residual_map` (mean residual over input level and input rate, and along the
    loop) and :func:`plot_diagnosis` (residual maps, spectra and the held-out fit of a
    :class:`~preisach.DiagnosisReport`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .identify.plots import (
    plot_cv,
    plot_fod_data,
    plot_fod_surface,
    plot_kappa,
    plot_verification,
    plot_weights,
)
from .identify.plots import plot_report as plot_identification
from .recording import RecordingsInput, as_recordings

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .diagnose import DiagnosisReport
    from .experiments import ClosedLoopResult, DriftResult, Initialisation, SweepResult
    from .model import PreisachModel, SimulationResult, State

__all__ = [
    "boundary_polyline",
    "fod_sweep_input",
    "plot_boundary",
    "plot_cv",
    "plot_diagnosis",
    "plot_drift_summary",
    "plot_effort_increase",
    "plot_effort_summary",
    "plot_everett",
    "plot_fod_data",
    "plot_fod_surface",
    "plot_identification",
    "plot_initial_states",
    "plot_kappa",
    "plot_major_loop",
    "plot_neutral_locus",
    "plot_paired_differences",
    "plot_residual_map",
    "plot_simulation",
    "plot_sweep_traces",
    "plot_trial",
    "plot_verification",
    "plot_weights",
]


def _figure(fig: Figure | None, **kwargs: object) -> Figure:
    if fig is not None:
        return fig
    from matplotlib.figure import Figure as _Figure

    return _Figure(**kwargs)  # type: ignore[arg-type]


def fod_sweep_input(
    u_min: float, u_max: float, alphas: Sequence[float], points_per_volt: float = 2.0
) -> tuple[np.ndarray, list[slice]]:
    """Input of an FOD sweep: for each ``alpha``, rise from ``u_min`` to ``alpha`` and fall back.

    Returns the input (V) and, for each curve, the slice of samples on its falling branch.
    """
    parts: list[np.ndarray] = []
    falls: list[slice] = []
    n0 = 0
    for a in alphas:
        k = max(2, int(abs(a - u_min) * points_per_volt) + 1)
        up = np.linspace(u_min, a, k)
        down = np.linspace(a, u_min, k)
        parts += [up, down]
        falls.append(slice(n0 + k, n0 + 2 * k))
        n0 += 2 * k
    return np.concatenate(parts), falls


def plot_major_loop(
    model: PreisachModel, n_fod: int = 10, *, ax: Axes | None = None, title: str | None = None
) -> Figure:
    """Draw the major loop and first-order descending (FOD) curves of a model (Figs 3.18-3.20).

    Parameters
    ----------
    model : PreisachModel
        The model; it is simulated from negative saturation.
    n_fod : int
        Number of FOD curves, turning at ``n_fod`` equally spaced levels up to ``u_max``.
    ax : Axes, optional
        Draw here instead of on a new figure.
    title : str, optional
        Axes title (default the model's name).

    Returns
    -------
    Figure
        Output y (V) against input u (V); the last curve (turning at ``u_max``) is the major
        loop.

    """
    if ax is None:
        fig = _figure(None, figsize=(6, 4.5))
        ax = fig.add_subplot()
    else:
        fig = ax.figure  # type: ignore[assignment]
    alphas = np.linspace(model.u_min, model.u_max, n_fod + 1)[1:]
    u, falls = fod_sweep_input(model.u_min, model.u_max, alphas.tolist())
    res = model.simulate(u, model.negative_saturation())
    for k, sl in enumerate(falls):
        ax.plot(
            u[sl], res.output[sl], color="tab:blue", lw=0.8, label="FOD curves" if k == 0 else None
        )
    last = slice(falls[-1].start - (falls[-1].stop - falls[-1].start), falls[-1].stop)
    ax.plot(u[last], res.output[last], color="k", lw=1.6, label="major loop")
    ax.set_xlabel("input u (V)")
    ax.set_ylabel("output y (V)")
    ax.set_title(title or (model.name or "Preisach model"))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left")
    return fig  # type: ignore[return-value]


def plot_simulation(result: SimulationResult, *, fig: Figure | None = None) -> Figure:
    """Draw input and output against time (s), and the input-output plane (V, V)."""
    fig = _figure(fig, figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(result.time, result.input, color="tab:gray", lw=0.8)
    ax1.set_xlabel("time t (s)")
    ax1.set_ylabel("input u (V)", color="tab:gray")
    ax1b = ax1.twinx()
    ax1b.plot(result.time, result.output, color="tab:blue", lw=0.9)
    ax1b.set_ylabel("output y (V)", color="tab:blue")
    ax2.plot(result.input, result.output, color="tab:blue", lw=0.8)
    ax2.set_xlabel("input u (V)")
    ax2.set_ylabel("output y (V)")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def boundary_polyline(state: State, points_per_piece: int = 2) -> np.ndarray:
    """Return the vertices ``(alpha, beta)`` (V) of the boundary of a state.

    From ``(phi(u_min), u_min)`` to the diagonal point ``(u, u)``; ``points_per_piece``
    points on every piece (antidiagonal pieces of neutral states are straight lines).
    """
    pts: list[tuple[float, float]] = []
    b0, v, ad = state.b0, state.v, state.antidiag
    for k in range(len(b0)):
        end = b0[k + 1] if k + 1 < len(b0) else state.input
        for beta in np.linspace(b0[k], end, max(2, points_per_piece)):
            pts.append(((v[k] - beta) if ad[k] else v[k], beta))
    pts.append((state.input, state.input))
    return np.asarray(pts, dtype=float)


def plot_boundary(state: State, *, ax: Axes | None = None, coords: str = "alpha-beta") -> Figure:
    """Draw the Preisach plane with P+ / P- shaded and the boundary psi of a state.

    P+ (relays at +1) lies between the diagonal and the boundary, P- (relays at -1) above it.

    Parameters
    ----------
    state : State
        The state to draw.
    ax : Axes, optional
        Draw here instead of on a new figure.
    coords : {"alpha-beta", "r-s"}
        Draw in ``(alpha, beta)`` (alpha horizontal) or ``(r, s)`` with
        ``r = (alpha - beta) / 2``, ``s = (alpha + beta) / 2``.

    Returns
    -------
    Figure

    """
    if ax is None:
        fig = _figure(None, figsize=(5, 5))
        ax = fig.add_subplot()
    else:
        fig = ax.figure  # type: ignore[assignment]
    lo, hi = state.u_min, state.u_max
    poly = boundary_polyline(state)
    # P+ = {(alpha, beta): beta <= alpha <= phi(beta)}: below the boundary, above the diagonal.
    tri = np.array([[lo, lo], [hi, lo], [hi, hi]])

    def tr(p: np.ndarray) -> np.ndarray:
        if coords == "r-s":
            return np.column_stack([(p[:, 0] - p[:, 1]) / 2, (p[:, 0] + p[:, 1]) / 2])
        return p

    if coords not in ("alpha-beta", "r-s"):
        raise ValueError(f"coords: expected 'alpha-beta' or 'r-s', got {coords!r}")
    t = tr(tri)
    ax.fill(t[:, 0], t[:, 1], color="tab:red", alpha=0.15, label="P- (relays at -1)")
    if len(state.b0):
        c = tr(np.vstack([[[lo, lo]], poly]))
        ax.fill(c[:, 0], c[:, 1], color="#9cc0e6", label="P+ (relays at +1)")
    b = tr(poly) if len(poly) else np.empty((0, 2))
    if len(b):
        ax.plot(b[:, 0], b[:, 1], color="k", lw=1.5, label="boundary psi")
    if coords == "r-s":
        ax.set_xlabel("r (V)")
        ax.set_ylabel("s (V)")
    else:
        ax.set_xlabel("alpha (V)")
        ax.set_ylabel("beta (V)")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize=8)
    return fig  # type: ignore[return-value]


# ------------------------------------------------------------------------------------------
# Everett function
# ------------------------------------------------------------------------------------------
def plot_everett(
    model: PreisachModel,
    *,
    coords: str = "alpha-beta",
    ax: Axes | None = None,
    resolution: int = 41,
) -> Figure:
    """Draw the Everett function E(alpha, beta) (V) of a model as a surface over the triangle.

    ``E(alpha, beta) = (y(alpha, alpha) - y(alpha, beta)) / 2`` on the FOD curves (Mayergoyz,
    thesis §2.6); it is zero on the diagonal and grows towards ``(u_max, u_min)``, where
    ``2 E = y_max - y_min``.

    Parameters
    ----------
    model : PreisachModel
        The model.
    coords : {"alpha-beta", "r-s"}
        Plane coordinates: (alpha, beta), or ``r = (alpha - beta) / 2``,
        ``s = (alpha + beta) / 2``.
    ax : Axes3D, optional
        A 3-D axes to draw on; a new figure is made otherwise.
    resolution : int
        Grid points per side of the triangle (at least 3).

    Returns
    -------
    Figure

    """
    if coords not in ("alpha-beta", "r-s"):
        raise ValueError(f"coords: expected 'alpha-beta' or 'r-s', got {coords!r}")
    n = int(resolution)
    if n < 3:
        raise ValueError(f"resolution: need at least 3 points per side, got {resolution!r}")
    if ax is None:
        fig = _figure(None, figsize=(6.5, 5.5))
        ax = fig.add_subplot(projection="3d")
    else:
        fig = ax.figure  # type: ignore[assignment]
    g = np.linspace(model.u_min, model.u_max, n)
    a, b = np.meshgrid(g, g, indexing="ij")
    keep = a >= b
    a, b = a[keep], b[keep]
    e = np.asarray(model.everett(a, b), dtype=float)
    x1, x2 = (a, b) if coords == "alpha-beta" else ((a - b) / 2, (a + b) / 2)
    ax.plot_trisurf(x1, x2, e, cmap="viridis", linewidth=0.1)  # type: ignore[attr-defined,union-attr]
    names = ("alpha (V)", "beta (V)") if coords == "alpha-beta" else ("r (V)", "s (V)")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel("Everett function E (V)")  # type: ignore[attr-defined,union-attr]
    ax.set_title(f"Everett function in ({coords.replace('-', ', ')})")
    return fig  # type: ignore[return-value]


# ------------------------------------------------------------------------------------------
# neutral states and the regulation experiments
# ------------------------------------------------------------------------------------------
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
    from .neutral import neutral_locus

    inits: list[Initialisation] = []
    if states is not None:
        inits = list(states.values()) if isinstance(states, Mapping) else list(states)
    elif y_d is not None:
        from .experiments import ModelPlant, drive_to_state, thesis_sample_time

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
    return result.plot(fig=fig)


def _dimensionless_gain(fig: Figure) -> Figure:
    """Name the unit of the noise gain K_n (dimensionless) on sweep figures."""
    for ax in fig.axes:
        if ax.get_xlabel() == "noise gain K_n":
            ax.set_xlabel("noise gain K_n (1)")
    return fig


def _sweep_of(result: SweepResult, experiment: str, what: str) -> SweepResult:
    if result.experiment != experiment:
        raise ValueError(f"{what}: needs a {experiment!r} sweep, got a {result.experiment!r} sweep")
    return result


def plot_drift_summary(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Differential drift against noise gain per frequency and initial state (Fig 4.12).

    Means over seeds with one-standard-deviation bars (``SweepResult.plot`` of a drift sweep).
    """
    return _dimensionless_gain(_sweep_of(result, "drift", "plot_drift_summary").plot(fig=fig))


def plot_effort_summary(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Control effort n_c against noise gain per frequency and initial state (Figs 5.5-5.7).

    Means over seeds with one-standard-deviation bars (``SweepResult.plot`` of a closed-loop
    sweep).
    """
    return _dimensionless_gain(
        _sweep_of(result, "closed-loop", "plot_effort_summary").plot(fig=fig)
    )


def plot_paired_differences(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Paired differences psi_a - psi_n and psi_d - psi_n per seed (``plot_differences``)."""
    return _dimensionless_gain(result.plot_differences(fig=fig))


def plot_sweep_traces(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Output from each initial state against time, per frequency (``plot_traces``)."""
    return result.plot_traces(fig=fig)


def plot_initial_states(result: SweepResult, *, fig: Figure | None = None) -> Figure:
    """Major loop, N(l) and the initial states of a sweep, one panel per frequency."""
    return result.plot_initial_states(fig=fig)


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
    if ax is None:
        fig = _figure(None, figsize=(6.0, 4.2))
        ax = fig.add_subplot()
    else:
        fig = ax.figure  # type: ignore[assignment]
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
    return fig  # type: ignore[return-value]


# ------------------------------------------------------------------------------------------
# diagnosis
# ------------------------------------------------------------------------------------------
def plot_diagnosis(report: DiagnosisReport, *, fig: Figure | None = None) -> Figure:
    """Residual maps, spectra, covariates and the held-out fit of a diagnosis (``report.plot``)."""
    return report.plot(fig=fig)


def plot_residual_map(
    model: PreisachModel,
    recordings: RecordingsInput,
    *,
    delay: int = 0,
    initial_state: Any = "burn-in",
    bins: tuple[int, int] = (24, 15),
    min_count: int = 5,
    fig: Figure | None = None,
) -> Figure:
    """Map where a model and recordings disagree: over input level and rate, and on the loop.

    The residual ``r = y_measured - y_model`` (V, shown in mV) of every scored sample (see
    :func:`preisach.verify.predict` for the initial-state policy) is drawn twice:

    * left, its mean in bins of the input ``u`` (V) and the input rate ``du/dt`` (V/s): a
      measurement lag shows as opposite signs for rising and falling inputs, growing with the
      rate; rate-dependent loops as a residual that grows with ``|du/dt|``; a level-dependent
      gain or a sensor curve as a pattern along ``u`` alone; creep near ``du/dt = 0``;
    * right, the measured loop (y against u) coloured by the residual.

    Parameters
    ----------
    model : PreisachModel
        The model.
    recordings : Recording, path, object with t/u/y, or a sequence of them
        The recordings (s, V, V); see :func:`preisach.recording.as_recordings`.
    delay : int
        Output delay in samples (``y[k + delay]`` answers ``u[k]``).
    initial_state : str or State
        Initial-state policy of :func:`preisach.verify.predict` (default ``"burn-in"``).
    bins : (int, int)
        Bins along ``u`` and along ``du/dt``.
    min_count : int
        Bins with fewer samples are left blank.
    fig : Figure, optional
        Draw on this figure.

    Returns
    -------
    Figure
        The left axes' mesh holds the binned means (mV), NaN where blank.

    """
    from .verify import predict

    nu, nr = (int(v) for v in bins)
    if nu < 1 or nr < 1:
        raise ValueError(f"bins: need positive numbers of bins, got {bins!r}")
    us, rates, res, ys = [], [], [], []
    for rec in as_recordings(recordings):
        p = predict(model, rec, initial_state=initial_state, delay=delay)
        sl = slice(p.first, None)
        rate = np.gradient(p.u, p.t) if p.u.size > 1 else np.zeros_like(p.u)
        us.append(p.u[sl])
        rates.append(rate[sl])
        res.append(p.y[sl] - p.y_model[sl])
        ys.append(p.y[sl])
    u, rate, r, y = (np.concatenate(v) for v in (us, rates, res, ys))
    mv = 1e3 * r
    rmax = float(np.percentile(np.abs(rate), 99.0)) if rate.size else 0.0
    rmax = rmax if rmax > 0 else 1.0
    ue = np.linspace(model.u_min, model.u_max, nu + 1)
    re = np.linspace(-rmax, rmax, nr + 1)
    iu = np.clip(np.searchsorted(ue, u, side="right") - 1, 0, nu - 1)
    ir = np.clip(np.searchsorted(re, rate, side="right") - 1, 0, nr - 1)
    total = np.zeros((nr, nu))
    count = np.zeros((nr, nu))
    np.add.at(total, (ir, iu), mv)
    np.add.at(count, (ir, iu), 1.0)
    mean = np.full((nr, nu), np.nan)
    ok = count >= max(1, int(min_count))
    mean[ok] = total[ok] / count[ok]
    lim = float(np.nanmax(np.abs(mean))) if np.any(ok) else 1.0
    lim = lim if lim > 0 else 1.0
    fig = _figure(fig, figsize=(12, 4.6))
    ax1, ax2 = fig.subplots(1, 2)
    mesh = ax1.pcolormesh(ue, re, np.ma.masked_invalid(mean), cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(mesh, ax=ax1, label="mean residual y_meas - y_model (mV)")
    ax1.axhline(0.0, color="k", lw=0.5)
    ax1.set_xlabel("input u (V)")
    ax1.set_ylabel("input rate du/dt (V/s)")
    ax1.set_title("residual map over input level and rate")
    order = np.argsort(np.abs(mv))
    sc = ax2.scatter(
        u[order],
        y[order],
        c=mv[order],
        s=2,
        cmap="RdBu_r",
        vmin=-float(np.max(np.abs(mv)) or 1.0),
        vmax=float(np.max(np.abs(mv)) or 1.0),
    )
    fig.colorbar(sc, ax=ax2, label="residual y_meas - y_model (mV)")
    ax2.set_xlabel("input u (V)")
    ax2.set_ylabel("measured output y (V)")
    ax2.set_title(
        f"residual along the loop: rms {1e3 * float(np.sqrt(np.mean(r * r))):.3g} mV, "
        f"{r.size} samples"
    )
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    return fig
