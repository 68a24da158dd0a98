"""Figures of the compensation experiments (matplotlib imported only here, on use)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .tracking import TrackingResult

__all__ = ["plot_tracking"]

_STYLE = {
    "uncompensated": ("tab:gray", "-"),
    "feedforward": ("tab:blue", "-"),
    "pi": ("tab:orange", "--"),
    "pi+feedforward": ("tab:green", "-."),
}


def plot_tracking(result: TrackingResult, reference: str | None = None) -> Figure:
    """Three panels: reference vs output, error vs time (one reference), max error vs frequency.

    Parameters
    ----------
    result : TrackingResult
        From :func:`preisach.compensate.tracking.run_tracking`.
    reference : str, optional
        Reference shown in the first two panels; default the 1 Hz sine if there is one,
        else the first reference.

    Returns
    -------
    matplotlib.figure.Figure

    """
    import matplotlib.pyplot as plt

    names = [r.name for r in result.references]
    if reference is None:
        reference = "sine-1Hz" if "sine-1Hz" in names else names[0]
    if reference not in names:
        raise ValueError(f"reference: {reference!r} is not one of {names}")
    modes = [m for m in _STYLE if any(r.mode == m for r in result.runs)]
    fig, axes = plt.subplots(3, 1, figsize=(8, 10))
    ax_y, ax_e, ax_f = axes
    first = result.get(reference, modes[0])
    ax_y.plot(first.t, first.r, "k", lw=2.5, alpha=0.4, label="reference")
    for m in modes:
        run: Any = result.get(reference, m)
        color, ls = _STYLE[m]
        ax_y.plot(run.t, run.y, color=color, ls=ls, lw=1, label=m)
        ax_e.plot(run.t, 100 * (run.r - run.y) / result.stroke, color=color, ls=ls, lw=1, label=m)
    ax_y.set(xlabel="t (s)", ylabel="output (V)", title=f"{reference}: reference vs output")
    ax_e.set(xlabel="t (s)", ylabel="r - y (% of stroke)", title="tracking error")
    ax_y.legend(fontsize=8)
    ax_e.legend(fontsize=8)
    sines = sorted((r for r in result.references if r.kind == "sine"), key=lambda r: r.frequency)
    if sines:
        f = np.array([r.frequency for r in sines])
        for m in modes:
            color, ls = _STYLE[m]
            err = [result.get(r.name, m).max_error_pct for r in sines]
            ax_f.loglog(f, err, color=color, ls=ls, marker="o", label=m)
        ax_f.set(xlabel="sine frequency (Hz)", ylabel="max |r - y| (% of stroke)")
        ax_f.set_title("max tracking error vs frequency")
        ax_f.legend(fontsize=8)
        ax_f.grid(True, which="both", alpha=0.3)
    else:
        ax_f.set_visible(False)
    fig.tight_layout()
    return fig
