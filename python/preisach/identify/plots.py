"""Figures of identification and verification (thesis Figs 3.18-3.44, 3.45-3.56).

Every function returns the matplotlib :class:`~matplotlib.figure.Figure` it drew on (none calls
``show()``); axes are labelled with units: inputs alpha, beta, r, s and u in volts (V), outputs
y in volts (V), the density v in V/V^2, kappa in V/V, time in seconds (s).

* :func:`plot_fod_data` - measured FOD curves joined by dashed lines (Figs 3.18-3.20), with a
  model's FOD curves over them;
* :func:`plot_fod_surface` - the FOD surface y(alpha, beta) of a model with the measured points,
  in (alpha, beta) (Figs 3.30-3.32) or (r, s) (Figs 3.33-3.35);
* :func:`plot_weights` - the density v of the weight, in (alpha, beta) (Figs 3.36, 3.38, 3.40) or
  (r, s) (Figs 3.42-3.44);
* :func:`plot_kappa` - the reversible part kappa along the diagonal (Figs 3.37, 3.39, 3.41);
* :func:`plot_cv` - the cross-validation curve of a least-squares identification;
* :func:`plot_report` - the figure of an :class:`~preisach.identify.IdentificationReport`;
* :func:`plot_verification` - measured vs simulated outputs and errors against time (Figs
  3.48, 3.52, 3.56).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._figures import figure, figure_and_axes, figure_and_axes3d

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D

    from ..model import PreisachModel
    from ..verify import VerificationTable
    from .fod_finder import FODData
    from .forc_identify import ForcDiagram
    from .identifiers import IdentificationReport
    from .lsq import LsqDetails

__all__ = [
    "plot_cv",
    "plot_fod_data",
    "plot_fod_surface",
    "plot_forc_diagram",
    "plot_kappa",
    "plot_report",
    "plot_verification",
    "plot_weights",
]

_COORDS = ("alpha-beta", "r-s")


def _prefix(values: NDArray[np.float64]) -> tuple[float, str]:
    """Factor and SI prefix that bring the largest |value| to 0.1 .. 100 (tiny densities)."""
    finite = np.abs(values[np.isfinite(values)])
    top = float(finite.max()) if finite.size else 0.0
    for factor, name in ((1.0, ""), (1e3, "m"), (1e6, "\u00b5"), (1e9, "n")):
        if top * factor >= 0.1:
            return factor, name
    return 1.0, ""


def _check_coords(coords: str) -> None:
    if coords not in _COORDS:
        raise ValueError(f"coords: expected 'alpha-beta' or 'r-s', got {coords!r}")


def _fod_y(
    model: PreisachModel, alpha: NDArray[np.float64], beta: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Model FOD output y(alpha, beta) = y_min + 2 E(alpha, u_min) - 2 E(alpha, beta) (V)."""
    return (
        model.y_min
        + 2.0 * model.everett(alpha, np.full_like(alpha, model.u_min))
        - 2.0 * model.everett(alpha, beta)
    )


def plot_fod_data(
    fod: FODData | None = None,
    model: PreisachModel | None = None,
    *,
    ax: Axes | None = None,
    points: int = 200,
) -> Figure:
    """Measured FOD curves (dashed, markers) and a model's FOD curves (solid), Figs 3.18-3.20.

    Parameters
    ----------
    fod : FODData, optional
        Measured FOD grid (rows are curves).
    model : PreisachModel, optional
        Model whose FOD curves are drawn at the measured turning values (or at its levels).
    ax : Axes, optional
        Draw here instead of on a new figure.
    points : int
        Points per model curve.

    """
    if fod is None and model is None:
        raise ValueError("plot_fod_data: give fod data, a model, or both")
    fig, ax = figure_and_axes(ax, figsize=(6.5, 4.8))
    alphas: NDArray[np.float64]
    if fod is not None:
        lv, yg = fod.levels, fod.y_grid
        for i in range(lv.size):
            j = np.nonzero(np.isfinite(yg[i, : i + 1]))[0]
            if j.size:
                ax.plot(
                    lv[j],
                    yg[i, j],
                    ls="--",
                    marker="o",
                    ms=2.5,
                    lw=0.7,
                    color="tab:blue",
                    label="measured FOD data" if i == lv.size - 1 else None,
                )
        alphas = lv[np.any(fod.count > 0, axis=1)]
    else:
        assert model is not None
        alphas = model.levels[:: max(1, model.levels.size // 20)]
    if model is not None:
        for k, a in enumerate(alphas):
            if a <= model.u_min:
                continue
            b = np.linspace(model.u_min, a, points)
            ax.plot(
                b,
                _fod_y(model, np.full_like(b, a), b),
                lw=0.9,
                color="tab:red",
                label="model FOD curves" if k == len(alphas) - 1 else None,
            )
    ax.set_xlabel("input u = beta (V)")
    ax.set_ylabel("output y (V)")
    ax.set_title("first-order descending curves")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return fig


def _triangle(model: PreisachModel, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    g = np.linspace(model.u_min, model.u_max, n)
    a, b = np.meshgrid(g, g, indexing="ij")
    keep = a >= b
    return a[keep], b[keep]


def plot_fod_surface(
    model: PreisachModel,
    *,
    fod: FODData | None = None,
    coords: str = "alpha-beta",
    ax: Axes3D | None = None,
    resolution: int = 41,
) -> Figure:
    """Draw the FOD surface y(alpha, beta) of a model as a 3-D surface, with measured points.

    Parameters
    ----------
    model : PreisachModel
        Model whose FOD outputs ``y = y_min + 2 E(alpha, u_min) - 2 E(alpha, beta)`` are drawn.
    fod : FODData, optional
        Measured FOD nodes, drawn as points.
    coords : {"alpha-beta", "r-s"}
        Plane coordinates: (alpha, beta) as Figs 3.30-3.32, or r = (alpha - beta)/2,
        s = (alpha + beta)/2 as Figs 3.33-3.35.
    ax : Axes3D, optional
        Draw here (a 3-D axes) instead of on a new figure.
    resolution : int
        Grid points per side of the triangle.

    """
    _check_coords(coords)
    fig, ax = figure_and_axes3d(ax, figsize=(6.5, 5.5))
    a, b = _triangle(model, resolution)
    y = _fod_y(model, a, b)
    x1, x2 = (a, b) if coords == "alpha-beta" else ((a - b) / 2, (a + b) / 2)
    ax.plot_trisurf(x1, x2, y, cmap="viridis", linewidth=0.1, alpha=0.85)
    if fod is not None:
        aa, bb, yy, _ = fod.nodes()
        p1, p2 = (aa, bb) if coords == "alpha-beta" else ((aa - bb) / 2, (aa + bb) / 2)
        ax.scatter(p1, p2, yy, color="k", s=4, label="measured")
        ax.legend(loc="upper left", fontsize=8)
    names = ("alpha (V)", "beta (V)") if coords == "alpha-beta" else ("r (V)", "s (V)")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel("output y (V)")
    ax.set_title(f"FOD surface in ({coords.replace('-', ', ')})")
    return fig


def plot_weights(
    model: PreisachModel,
    *,
    coords: str = "alpha-beta",
    ax: Axes3D | None = None,
) -> Figure:
    """Draw the density v (V/V^2) of a model's weight as a 3-D surface over the cell centres.

    Parameters
    ----------
    model : PreisachModel
        Model whose cell masses, divided by the cell areas, are drawn (see ``weight_density``).
    coords : {"alpha-beta", "r-s"}
        (alpha, beta) as Figs 3.36/3.38/3.40, or (r, s) as Figs 3.42-3.44.
    ax : Axes3D, optional
        Draw here (a 3-D axes) instead of on a new figure.

    """
    from .identifiers import weight_density

    _check_coords(coords)
    fig, ax = figure_and_axes3d(ax, figsize=(6.5, 5.5))
    v, _ = weight_density(model)
    lv = model.levels
    c = 0.5 * (lv[1:] + lv[:-1])
    i, j = np.tril_indices(c.size, -1)
    a, b, z = c[i], c[j], v[i, j]
    factor, prefix = _prefix(z)
    x1, x2 = (a, b) if coords == "alpha-beta" else ((a - b) / 2, (a + b) / 2)
    if z.size >= 3:
        ax.plot_trisurf(x1, x2, z * factor, cmap="magma", linewidth=0.1)
    names = ("alpha (V)", "beta (V)") if coords == "alpha-beta" else ("r (V)", "s (V)")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel(f"density v ({prefix}V/V^2)")
    ax.set_title(f"weight density v in ({coords.replace('-', ', ')})")
    return fig


def plot_kappa(model: PreisachModel, *, ax: Axes | None = None) -> Figure:
    """Kappa (V/V) of the diagonal half-cells against their centre beta = alpha (V), Eq 2.14."""
    from .identifiers import weight_density

    fig, ax = figure_and_axes(ax, figsize=(6, 4))
    _, kappa = weight_density(model)
    lv = model.levels
    c = 0.5 * (lv[1:] + lv[:-1])
    ax.plot(c, kappa, marker=".", color="tab:green")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("beta = alpha (V)")
    ax.set_ylabel("kappa (V/V)")
    ax.set_title("reversible part kappa on the diagonal")
    ax.grid(alpha=0.3)
    return fig


def plot_cv(details: LsqDetails, *, ax: Axes | None = None) -> Figure:
    """Cross-validated RMS error (V) against the smoothness weight lambda (log axis)."""
    fig, ax = figure_and_axes(ax, figsize=(6, 4))
    lam = np.asarray(details.lambdas, dtype=float)
    x = np.where(lam > 0, lam, np.nan)
    ax.plot(x, details.cv_rms, marker="o", color="tab:purple", label="CV rms (all folds)")
    for k in range(details.cv_fold_rms.shape[1]):
        ax.plot(
            x,
            details.cv_fold_rms[:, k],
            lw=0.6,
            color="0.6",
            label="single held-out block" if k == 0 else None,
        )
    ax.axvline(
        details.chosen_lambda, color="k", ls=":", label=f"chosen {details.chosen_lambda:.2g}"
    )
    if np.any(lam > 0):
        ax.set_xscale("log")
    ax.set_xlabel("smoothness weight lambda (dimensionless)")
    ax.set_ylabel("RMS error on held-out blocks (V)")
    ax.set_title(f"{details.folds}-fold cross-validation over time blocks")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def plot_report(report: IdentificationReport, *, fig: Figure | None = None) -> Figure:
    """Draw an identification report in six panels.

    FOD data and the model's FOD curves (or the CV curve for lsq), the FOD surface in
    (alpha, beta) and (r, s), the density v in (alpha, beta) and (r, s), and kappa.
    """
    fig = figure(fig, figsize=(17, 10))
    m = report.model
    ax0 = fig.add_subplot(2, 3, 1)
    if report.lsq is not None:
        plot_cv(report.lsq, ax=ax0)
    else:
        plot_fod_data(report.fod, m, ax=ax0)
    plot_fod_surface(
        m, fod=report.fod, coords="alpha-beta", ax=fig.add_subplot(2, 3, 2, projection="3d")
    )
    plot_fod_surface(m, fod=report.fod, coords="r-s", ax=fig.add_subplot(2, 3, 3, projection="3d"))
    plot_weights(m, coords="alpha-beta", ax=fig.add_subplot(2, 3, 4, projection="3d"))
    plot_weights(m, coords="r-s", ax=fig.add_subplot(2, 3, 5, projection="3d"))
    plot_kappa(m, ax=fig.add_subplot(2, 3, 6))
    fig.suptitle(f"identification ({report.method}): {m.name or 'model'}")
    fig.subplots_adjust(left=0.05, right=0.97, wspace=0.3, hspace=0.3)
    _relabel_units(fig, report.input_units, report.output_units)
    return fig


def _unit_label(text: str, ui: str, uo: str) -> str:
    """Replace the volts of a panel label by the recording's input/output units."""
    if "(V" not in text and "V)" not in text:
        return text
    if text.startswith("density v"):
        return text.replace("V/V^2", f"{uo}/({ui})^2")
    if text.startswith("kappa"):
        return text.replace("(V/V)", f"({uo}/{ui})")
    is_output = text.startswith(("output", "RMS", "error"))
    return text.replace("(V)", f"({uo if is_output else ui})")


def _relabel_units(fig: Figure, ui: str, uo: str) -> None:
    """Label every axis of a figure in the recording's units (the panels are drawn in V)."""
    if ui == "V" and uo == "V":
        return
    from mpl_toolkits.mplot3d import Axes3D

    for ax in fig.axes:
        ax.set_xlabel(_unit_label(ax.get_xlabel(), ui, uo))
        ax.set_ylabel(_unit_label(ax.get_ylabel(), ui, uo))
        if isinstance(ax, Axes3D):
            ax.set_zlabel(_unit_label(ax.get_zlabel(), ui, uo))


def plot_verification(table: VerificationTable, *, fig: Figure | None = None) -> Figure:
    """Per experiment: measured and simulated output against time (s), and the error (V)."""
    n = len(table.predictions)
    if n == 0:
        raise ValueError("plot_verification: the table has no predictions to draw")
    fig = figure(fig, figsize=(10, 3.2 * n))
    axes = fig.subplots(n, 2, squeeze=False)
    for k, (row, p) in enumerate(zip(table.rows, table.predictions)):
        a1, a2 = axes[k]
        a1.plot(p.t, p.y, color="k", lw=0.8, label="measured")
        a1.plot(p.t, p.y_model, color="tab:red", lw=0.8, ls="--", label="model")
        if p.first:
            a1.axvspan(p.t[0], p.t[p.first], color="0.85", label="burn-in (not scored)")
        a1.set_xlabel("time t (s)")
        a1.set_ylabel("output y (V)")
        a1.set_title(row.experiment)
        a1.legend(fontsize=8, loc="upper right")
        a2.plot(p.t[p.first :], p.error, color="tab:blue", lw=0.7)
        a2.set_xlabel("time t (s)")
        a2.set_ylabel("error model - measured (V)")
        a2.set_title(
            f"max {row.max_error:.3g} V ({row.max_pct:.2f} %), rms {row.rms_error:.3g} V "
            f"({row.rms_pct:.2f} %)"
        )
        for a in (a1, a2):
            a.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_forc_diagram(diagram: ForcDiagram, *, ax: Axes | None = None, levels: int = 21) -> Figure:
    """Draw a FORC diagram: rho in (H_c, H_u) with filled contours (undefined points blank).

    Parameters
    ----------
    diagram : ForcDiagram
        The diagram (:func:`~preisach.identify.forc_diagram`), in its own field and moment units.
    ax : Axes, optional
        Draw here instead of on a new figure.
    levels : int
        Number of contour levels, symmetric about zero.

    Returns
    -------
    Figure

    """
    fig, ax = figure_and_axes(ax, figsize=(6.4, 4.8))
    rho = np.ma.masked_invalid(diagram.rho)
    hc, hu = diagram.h_c, diagram.h_u
    finite = np.isfinite(diagram.rho)
    vmax = float(np.nanmax(np.abs(diagram.rho))) if finite.any() else 1.0
    cs = ax.contourf(hc, hu, rho, levels=np.linspace(-vmax, vmax, levels), cmap="RdBu_r")
    ax.contour(
        hc, hu, rho, levels=np.linspace(-vmax, vmax, levels)[::2], colors="k", linewidths=0.3
    )
    fu, mu = diagram.field_units, diagram.moment_units
    fig.colorbar(cs, ax=ax, label=f"rho ({mu} / {fu}^2)")
    ax.set_xlabel(f"H_c = (H - H_r) / 2 ({fu})")
    ax.set_ylabel(f"H_u = (H + H_r) / 2 ({fu})")
    ax.set_title(
        f"FORC diagram, SF = {diagram.smoothing_factor} (no data, none drawn, where H < H_r)"
    )
    ax.set_xlim(0.0, None)
    return fig
