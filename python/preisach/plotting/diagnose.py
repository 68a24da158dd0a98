"""Figures of a model's disagreement with recordings, and of a diagnosis."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .._figures import figure as _figure
from ..recording import RecordingsInput, as_recordings

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..diagnose import DiagnosisReport
    from ..model import PreisachModel

__all__ = ["plot_diagnosis", "plot_residual_map"]


def plot_diagnosis(report: DiagnosisReport, *, fig: Figure | None = None) -> Figure:
    """Residual maps, spectra, covariates and the held-out fit of a diagnosis (``report.plot``)."""
    from matplotlib.figure import Figure

    if fig is None:
        fig = Figure(figsize=(14, 12))
    axs = fig.subplots(3, 2)
    mv, unit = report.display_unit()  # volts are drawn in mV
    recs = report._recs
    # (a) residual against time, recordings side by side
    ax = axs[0, 0]
    offset = 0.0
    for i, r in enumerate(recs):
        t = r.t - r.t[0] + offset
        rb = np.where(r.usable, r.y - report._pred_before[i], np.nan)
        ax.plot(t, mv * rb, color="0.6", lw=0.5, label="given model" if i == 0 else None)
        ax.plot(
            t,
            mv * report._res_after[i],
            color="C3",
            lw=0.5,
            label="augmented (held-out)" if i == 0 else None,
        )
        ax.axvline(offset, color="k", lw=0.5)
        ax.text(offset, 1.0, f" {r.name}", transform=ax.get_xaxis_transform(), va="top", fontsize=7)
        offset = t[-1] + 0.5
    ax.set_xlabel("time, recordings in sequence (s)")
    ax.set_ylabel(f"residual y_meas - y_sim ({unit})")
    ax.set_title("where in time: residual per recording")
    ax.legend(loc="lower right", fontsize=7)
    # (b) spectra
    ax = axs[0, 1]
    sb, sa = report.before.spectrum, report.after.spectrum
    if sb:
        ax.semilogy(sb["f"], sb["output_psd"], color="0.3", lw=0.8, label="output y")
        ax.semilogy(sb["f"], sb["residual_psd"], color="0.6", lw=0.8, label="residual, given model")
    if sa:
        ax.semilogy(sa["f"], sa["residual_psd"], color="C3", lw=0.8, label="residual, augmented")
    if recs and report.noise_sigma > 0:
        dt = min(r.dt for r in recs)
        ax.axhline(
            2 * report.noise_sigma**2 * dt, color="C0", ls="--", lw=0.8, label="white-noise floor"
        )
    for pk in report.before.spectrum.get("peaks", []):
        ax.annotate(
            f"{pk['f']:.3g} Hz",
            (pk["f"], np.interp(pk["f"], sb["f"], sb["residual_psd"])),
            fontsize=7,
        )
    ax.set_xscale("log")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"PSD ({report.unit}²/Hz)")
    ax.set_title("which band: Welch spectra")
    ax.legend(fontsize=7)
    # (c) residual map over input level and direction
    ax = axs[1, 0]
    im, ia = report.before.input_map, report.after.input_map
    for key, col in (("rising", "C1"), ("falling", "C0"), ("holding", "C2")):
        ax.plot(im["levels"], mv * im[f"{key}_mean"], "-o", ms=3, color=col, label=f"{key}, given")
        ax.plot(
            ia["levels"],
            mv * ia[f"{key}_mean"],
            "--",
            color=col,
            lw=0.8,
            label=f"{key}, augmented",
        )
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("input u (V)")
    ax.set_ylabel(f"mean residual ({unit})")
    ax.set_title("which input range and direction: residual map")
    ax.legend(fontsize=6, ncol=2)
    # (d) what the residual follows
    ax = axs[1, 1]
    names = list(report.before.covariates)
    x = np.arange(len(names))
    eb = [report.before.covariates[n].eta2 for n in names]
    ea = [report.after.covariates[n].eta2 if n in report.after.covariates else 0.0 for n in names]
    ax.bar(x - 0.2, eb, 0.4, color="0.6", label="given model")
    ax.bar(x + 0.2, ea, 0.4, color="C3", label="augmented")
    for xi, n in zip(x, names):
        p = report.before.covariates[n].p_value
        ax.text(xi - 0.2, eb[xi], "*" if p < 0.01 else "", ha="center", fontsize=9)
    ax.set_xticks(x)
    ax.set_xticklabels([n.replace("_", "\n") for n in names], fontsize=7)
    ax.set_ylabel("eta² (share of residual variance, 1)")
    ax.set_title("what the residual follows (* p < 0.01, block permutation)")
    ax.legend(fontsize=7)
    # (e) held-out fit, zoom where the augmented model helps most
    ax = axs[2, 0]
    if recs:
        gains = []
        for i, r in enumerate(recs):
            c = np.where(r.usable, report._pred_after[i] - report._pred_before[i], 0.0)
            gains.append(float(np.max(np.abs(c))) if c.size else 0.0)
        i = int(np.argmax(gains))
        r = recs[i]
        c = np.abs(np.where(r.usable, report._pred_after[i] - report._pred_before[i], 0.0))
        k = int(np.argmax(c))
        w = int(round(0.5 / r.dt))
        sl = slice(max(0, k - w), min(r.n, k + w))
        ax.plot(
            r.t[sl],
            mv * (r.y[sl] - report._pred_before[i][sl]),
            color="0.5",
            lw=0.8,
            label="measured - given model",
        )
        ax.plot(
            r.t[sl],
            mv * report._res_after[i][sl],
            color="C3",
            lw=0.8,
            label="measured - augmented (held-out)",
        )
        ax.axhline(0, color="k", lw=0.5)
        ax2 = ax.twinx()
        ax2.plot(r.t[sl], r.u[sl], color="C0", lw=0.6, alpha=0.5)
        ax2.set_ylabel("input u (V)", color="C0")
        ax.set_title(f"before/after, 1 s of {r.name}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"residual ({unit})")
        ax.legend(fontsize=7, loc="lower left")
    # (f) candidates
    ax = axs[2, 1]
    step1 = [c for c in report.candidates if c["step"] == 1]
    if step1:
        xx = np.arange(len(step1))
        ax.bar(
            xx,
            [mv * c["heldout_rmse"] for c in step1],
            color=["C3" if c["kept"] else "0.6" for c in step1],
        )
        ax.axhline(mv * report.rmse_before, color="k", lw=0.8, label="given model")
        ax.axhline(
            mv * step1[0]["baseline_rmse"],
            color="k",
            ls=":",
            lw=0.8,
            label="baseline of the selection",
        )
        ax.axhline(mv * report.noise_sigma, color="C0", ls="--", lw=0.8, label="noise")
        ax.set_xticks(xx)
        ax.set_xticklabels(
            [c["name"].replace("_", "\n").replace("/", "/\n") for c in step1], fontsize=6
        )
        ax.set_ylabel(f"held-out RMSE ({unit})")
        ax.set_title(f"candidates, first step (verdict: {report.verdict})")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


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
