"""Figures of the Preisach model (thesis chapter 2): loops, simulations, the plane, Everett.

Axes carry units: inputs alpha, beta, r, s, u in V; output y in V; time in s.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .._figures import figure as _figure
from .._figures import figure_and_axes as _figure_and_axes
from .._figures import figure_and_axes3d as _figure_and_axes3d

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D

    from ..model import PreisachModel, SimulationResult, State

__all__ = [
    "boundary_polyline",
    "fod_sweep_input",
    "plot_boundary",
    "plot_everett",
    "plot_major_loop",
    "plot_simulation",
]


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
    fig, ax = _figure_and_axes(ax, figsize=(6, 4.5))
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
    return fig


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
    fig, ax = _figure_and_axes(ax, figsize=(5, 5))
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
    return fig


def plot_everett(
    model: PreisachModel,
    *,
    coords: str = "alpha-beta",
    ax: Axes3D | None = None,
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
    fig, ax = _figure_and_axes3d(ax, figsize=(6.5, 5.5))
    g = np.linspace(model.u_min, model.u_max, n)
    a, b = np.meshgrid(g, g, indexing="ij")
    keep = a >= b
    a, b = a[keep], b[keep]
    e = np.asarray(model.everett(a, b), dtype=float)
    x1, x2 = (a, b) if coords == "alpha-beta" else ((a - b) / 2, (a + b) / 2)
    ax.plot_trisurf(x1, x2, e, cmap="viridis", linewidth=0.1)
    names = ("alpha (V)", "beta (V)") if coords == "alpha-beta" else ("r (V)", "s (V)")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel("Everett function E (V)")
    ax.set_title(f"Everett function in ({coords.replace('-', ', ')})")
    return fig
