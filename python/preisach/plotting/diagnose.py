"""Figures of a model's disagreement with recordings, and of a diagnosis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..recording import RecordingsInput, as_recordings
from ._common import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..diagnose import DiagnosisReport
    from ..model import PreisachModel

__all__ = ["plot_diagnosis", "plot_residual_map"]


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
    from ..verify import predict

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
