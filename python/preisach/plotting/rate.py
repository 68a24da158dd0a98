"""Figures of the rate-dependent model: loops and the Everett function across rates, loop width."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._figures import figure as _figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..rate_model import RateDependentPreisachModel

__all__ = ["loop_width", "plot_everett_across_rates", "plot_loop_width", "plot_rate_loops"]


def _triangle(
    freq: float, amplitude: float, dt: float, periods: float = 2.0
) -> NDArray[np.float64]:
    n = int(round(periods / (freq * dt)))
    # from the sample after -amplitude (a state at -amplitude is the start), so every step
    # has the same |du| and the filtered rate stays at 4 amplitude freq
    ph = np.mod(np.arange(1, n + 1) * dt * freq + 0.5, 1.0)
    return np.asarray(amplitude * (4.0 * np.abs(ph - 0.5) - 1.0), dtype=np.float64)


def loop_width(u: NDArray[np.float64], y: NDArray[np.float64], at: float = 0.0) -> float:
    """Vertical width (V) of a periodic loop at input ``at`` (V): descending minus ascending.

    Uses the last full rise and fall through ``at`` (the loop has settled there); the branch
    outputs are interpolated linearly between the samples around the crossing.
    """
    uu, yy = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    du = np.diff(uu)
    cross = np.nonzero((uu[:-1] - at) * (uu[1:] - at) <= 0)[0]
    cross = cross[du[cross] != 0]
    up = [k for k in cross if du[k] > 0]
    dn = [k for k in cross if du[k] < 0]
    if not up or not dn:
        raise ValueError(f"loop_width: the input does not rise and fall through {at:g} V")

    def at_crossing(k: int) -> float:
        w = (at - uu[k]) / (uu[k + 1] - uu[k])
        return float(yy[k] + w * (yy[k + 1] - yy[k]))

    return at_crossing(dn[-1]) - at_crossing(up[-1])


def plot_rate_loops(
    model: RateDependentPreisachModel,
    frequencies: Sequence[float] = (0.5, 1.0, 2.0, 4.0, 8.0),
    *,
    amplitude: float | None = None,
    sample_time: float = 5e-4,
    fig: Figure | None = None,
) -> Figure:
    """Major loops of full-range triangles at several frequencies (the loops widen with rate).

    Parameters
    ----------
    model : RateDependentPreisachModel
        The model.
    frequencies : sequence of float
        Triangle frequencies (Hz); the rate is ``4 u_hat f`` (V/s).
    amplitude : float, optional
        ``u_hat`` (V); default the model's ``u_max``.
    sample_time : float
        Sampling period (s) of the simulated triangles.
    fig : Figure, optional
        Draw on this figure.

    Returns
    -------
    Figure
        Output y (V) against input u (V), one loop per frequency (its second period).

    """
    fig = _figure(fig, figsize=(6.5, 4.8))
    ax = fig.add_subplot()
    a = model.u_max if amplitude is None else float(amplitude)
    cmap = _cmap(len(frequencies))
    for k, f in enumerate(frequencies):
        u = _triangle(f, a, sample_time)
        res = model.simulate(u, model.negative_saturation(4 * a * f), sample_time=sample_time)
        half = u.size // 2
        ax.plot(
            u[half:],
            res.output[half:],
            color=cmap[k],
            lw=1.2,
            label=f"{f:g} Hz ({4 * a * f:.0f} V/s)",
        )
    ax.set_xlabel("input u (V)")
    ax.set_ylabel("output y (V)")
    ax.set_title(f"{model.name or 'rate-dependent model'}: major loops across rates")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return fig


def plot_everett_across_rates(
    model: RateDependentPreisachModel,
    rates: Sequence[float] | None = None,
    *,
    fig: Figure | None = None,
) -> Figure:
    """FOD curves ``E(alpha, beta)`` of the blended table at several rates, and their spread.

    Left: ``E(u_max, beta)`` (V, the major descending branch's Everett function) against
    ``beta`` at each rate; right: ``E(alpha, u_min)`` against ``alpha``.  Default rates: the
    knots and their geometric midpoints.
    """
    fig = _figure(fig, figsize=(10, 4.2))
    ax1, ax2 = fig.subplots(1, 2)
    kn = model.knots
    if rates is None:
        mids = np.sqrt(kn[:-1] * kn[1:]) if kn.size > 1 else np.zeros(0)
        rates = sorted([*kn.tolist(), *mids.tolist()])
    lv = model.levels
    cmap = _cmap(len(rates))
    for k, r in enumerate(rates):
        m = model.at_rate(float(r))
        e = m.everett_values
        ax1.plot(lv, e[-1, :], color=cmap[k], label=f"{r:.0f} V/s")
        ax2.plot(lv, e[:, 0], color=cmap[k])
    ax1.set_xlabel("beta (V)")
    ax1.set_ylabel("E(u_max, beta) (V)")
    ax2.set_xlabel("alpha (V)")
    ax2.set_ylabel("E(alpha, u_min) (V)")
    ax1.legend(fontsize=8)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.suptitle(f"{model.name or 'rate-dependent model'}: Everett function across rates")
    return fig


def plot_loop_width(
    model: RateDependentPreisachModel,
    data: Sequence[Any] = (),
    *,
    rates: Sequence[float] | None = None,
    at: float = 0.0,
    sample_time: float = 5e-4,
    fig: Figure | None = None,
) -> Figure:
    """Loop width at input ``at`` against the sweep rate: the model's curve and the data.

    Parameters
    ----------
    model : RateDependentPreisachModel
        The model; its curve comes from full-range triangles at each rate.
    data : sequence of Recording
        Periodic recordings (e.g. triangles or sines through ``at``); each is a point at its
        mean ``|du/dt|`` (V/s) with the width of its last loop.
    rates : sequence of float, optional
        Rates (V/s) of the model curve; default 30 log-spaced values over a decade on either
        side of the knots.
    at : float
        Input (V) where the width is measured.
    sample_time : float
        Sampling period (s) of the model's triangles.
    fig : Figure, optional
        Draw on this figure.

    """
    fig = _figure(fig, figsize=(6.5, 4.5))
    ax = fig.add_subplot()
    kn = model.knots
    rr = (
        np.geomspace(kn[0] / 10.0, kn[-1] * 10.0, 30)
        if rates is None
        else np.asarray(rates, dtype=float)
    )
    a = model.u_max
    widths = []
    for r in rr:
        f = r / (4 * a)
        dt = min(sample_time, 1.0 / (400 * f))  # at least 400 samples per period
        u = _triangle(f, a, dt)
        res = model.simulate(u, model.negative_saturation(r), sample_time=dt)
        widths.append(loop_width(u, res.output, at))
    ax.semilogx(rr, widths, "k-", label="model (full-range triangles)")
    for v in kn:
        ax.axvline(v, color="0.7", lw=0.8, ls=":")
    for k, rec in enumerate(data):
        u, y = np.asarray(rec.u, float), np.asarray(rec.y, float)
        rate = float(np.mean(np.abs(np.diff(u)))) / float(rec.sample_time)
        name = str(getattr(rec, "metadata", {}).get("experiment", f"recording {k}"))
        ax.semilogx([rate], [loop_width(u, y, at)], "o", label=name)
    ax.set_xlabel("input rate |du/dt| (V/s)")
    ax.set_ylabel(f"loop width at u = {at:g} V (V)")
    ax.set_title("loop width against rate (dotted: the model's knots)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return fig


def _cmap(n: int) -> list[Any]:
    import matplotlib

    cm = matplotlib.colormaps["viridis"]
    return [cm(x) for x in np.linspace(0.0, 0.9, max(n, 1))]
