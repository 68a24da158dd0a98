r"""Inverse of an augmented model: undo the physics blocks, then the hysteresis.

An augmented model (:class:`preisach.diagnose.AugmentedModel`) is
``input blocks -> Preisach -> output blocks``.  Its inverse runs the chain backwards on the
reference: each output block is inverted (last first), the Preisach stage by the exact
inverse of :func:`preisach.compensate.invert`, then each input block (last first).  Offline
(whole reference known), as feedforward is computed before a run.

What is inverted, and how (``dt`` the sample time):

``delay`` (``y(t) = x(t - tau)``, interpolated)
    By **preview** of the reference: the drive is computed ``tau`` ahead.  With
    ``tau = (n + f) dt`` the block is ``y[k] = (1 - f) x[k-n] + f x[k-n-1]``; for ``f <= 1/2``
    it is solved forwards, for ``f > 1/2`` backwards from the end of the reference (both
    recursions stable), so the interpolation is undone exactly.  The last ``n + 1`` targets
    are held (no preview exists beyond the end).  A delay read by Lagrange interpolation
    (``interpolation = "lagrange"``, a flat magnitude) is undone by reading the reference
    ``tau`` ahead with the same third-order interpolation, centred: exact for whole
    samples, and within that interpolation's error otherwise (for a slow reference far
    below it: a 1 Hz sine at 1 kHz comes back to 1e-10 of its swing).
``structural_mode`` (``y = x + m (G x - x) - r A x``, ``G`` and ``A`` the ZOH-exact
    second-order mode and its acceleration response; ``y = c / a \, x``)
    ``x = a / c \, y`` with ``c = (1 - m) a + m b`` (``r = 0``; else ``c`` the block's whole
    numerator): exact and causal.  Where a root of ``c``
    lies outside the radius ``r_max`` (default 0.95, the ZOH sampling zero near -1 when
    ``m`` is near 1) it is pulled in to ``r_max`` (DC gain kept): the inverse is then exact
    at low frequency and stops compensating near the Nyquist frequency; the band where it
    is within 5 % of exact is reported as ``extra["bandwidth_hz"]``.
``creep`` (``y = x_0 + g (x - x_0) + sum c_i (L_i x - x)``)
    Exact recursion ``x[k] = (y[k] - sum c_i e_i z_i[k-1]) / (g - sum c_i e_i)``,
    ``e_i = exp(-dt / tau_i)``; stable for the fitted (positive) weights.
``gain_offset``, ``sensor_drift``, ``sensor_nonlinearity``
    Static (or known time-dependent) maps inverted exactly.
``rate_dependence`` as a first-order input lag (``tau dz/dt = u - z``)
    ``u[k] = (z[k] - e z[k-1]) / (1 - e)``: exact (a first difference, no bandwidth limit
    in discrete time; the drive grows with the reference's rate, and is clamped to the
    input range, counted in ``extra["clamped"]``).

Not invertible here (:class:`ValueError` naming the block): output feedback (the moving
model), the rate-dependent play, the rate-dependent loop width and the relaxing reversible
response (``rate_dependence`` forms ``relaxation``/``viscous``: it acts on the drive itself,
so the Preisach stage and it would have to be solved together at every sample).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .inverse import InverseResult, invert

__all__ = ["invert_augmented"]

Array = NDArray[np.float64]


def _steady_zi(b: Array, a: Array) -> Array:
    """Return the lfilter state at rest for a unit constant input (DC gain sum(b)/sum(a))."""
    n = max(len(a), len(b))
    bb, aa = np.zeros(n), np.zeros(n)
    bb[: len(b)], aa[: len(a)] = b, a
    g = bb.sum() / aa.sum()
    return np.asarray(np.cumsum((bb - aa * g)[::-1])[::-1][1:])


def _advance(y: Array, d: float) -> Array:
    """``y`` read ``d`` samples ahead by centred third-order Lagrange interpolation.

    The ends are held (no sample exists beyond them).
    """
    m = y.size
    t = np.arange(m) + d
    n = np.floor(t).astype(np.int64)
    f = t - n
    w = (
        -f * (f - 1) * (f - 2) / 6,
        (f + 1) * (f - 1) * (f - 2) / 2,
        -(f + 1) * f * (f - 2) / 2,
        (f + 1) * f * (f - 1) / 6,
    )
    return np.asarray(sum(wk * y[np.clip(n + k - 1, 0, m - 1)] for k, wk in enumerate(w)))


def _inv_delay(blk: Any, y: Array, dt: float) -> Array:
    d = float(blk.params["tau"]) / dt
    if getattr(blk, "interpolation", "linear") == "lagrange":
        return _advance(y, d)
    n = int(math.floor(d))
    f = d - n
    m = y.size
    if f < 1e-12:
        return np.asarray(np.r_[y[n:], np.full(min(n, m), y[-1])][:m], dtype=float)
    out = np.empty(m)
    if f <= 0.5:  # x[j] = (y[j+n] - f x[j-1]) / (1 - f), x[-1] = y[0]
        prev = y[0]
        for j in range(m):
            prev = (y[min(j + n, m - 1)] - f * prev) / (1.0 - f)
            out[j] = prev
        return out
    # f > 1/2: x[j] = (y[j+n+1] - (1 - f) x[j+1]) / f, backwards from x = y[-1] at the end
    nxt = y[-1]
    for j in range(m - 1, -1, -1):
        nxt = (y[min(j + n + 1, m - 1)] - (1.0 - f) * nxt) / f
        out[j] = nxt
    return out


def _limit_roots(c: Array, r_max: float) -> Array:
    """Polynomial in z^-1 with its roots pulled inside radius r_max, same DC gain."""
    if c.size < 2:
        return c
    roots = np.roots(c)
    big = np.abs(roots) > r_max
    if not big.any():
        return c
    roots = roots.copy()
    roots[big] = roots[big] / np.abs(roots[big]) * r_max
    new = np.real(np.poly(roots)) * c[0]
    return np.asarray(new * (c.sum() / new.sum()))


def _inv_linear(
    blk: Any, y: Array, y0: float, dt: float, r_max: float, extra: dict[str, Any]
) -> Array:
    from scipy import signal

    b, a, mix = np.asarray(blk._b), np.asarray(blk._a), float(blk._mix)  # the block's design
    n = max(a.size, b.size)
    bb, aa = np.zeros(n), np.zeros(n)
    bb[: b.size], aa[: a.size] = b, a
    c = (1.0 - mix) * aa + mix * bb
    c_used = _limit_roots(c, r_max)
    if c_used is not c:
        w = np.linspace(1e-3, np.pi, 2000)
        z = np.exp(-1j * w)
        ratio = np.polyval(c[::-1], z) / np.polyval(c_used[::-1], z)
        bad = np.flatnonzero(np.abs(ratio - 1.0) > 0.05)
        f_bw = (w[bad[0]] if bad.size else np.pi) / (2 * np.pi * dt)
        prev = extra.get("bandwidth_hz")
        extra["bandwidth_hz"] = float(f_bw if prev is None else min(prev, f_bw))
    num, den = aa / c_used[0], c_used / c_used[0]  # lfilter's state is for den[0] = 1
    x, _ = signal.lfilter(num, den, y, zi=_steady_zi(num, den) * y0)
    return np.asarray(x)


def _inv_creep(blk: Any, y: Array, y0: float, dt: float) -> Array:
    p = blk.params
    taus, w, g = list(p["taus"]), list(p["weights"]), float(p["gain"])
    e = [math.exp(-dt / t) for t in taus]
    h0 = g - sum(c * ei for c, ei in zip(w, e))
    if abs(h0) < 1e-12:
        raise ValueError("creep: no direct feedthrough (g = sum c_i e_i); not invertible")
    x0 = y0  # settled at x0 the block reads x0 (its gain acts on moves from there)
    z = [x0] * len(taus)
    out = np.empty(y.size)
    for k in range(y.size):
        xk = (y[k] - (1.0 - g) * x0 - sum(c * ei * zi for c, ei, zi in zip(w, e, z))) / h0
        z = [ei * zi + (1.0 - ei) * xk for ei, zi in zip(e, z)]
        out[k] = xk
    return out


def _invert_output_block(
    blk: Any, y: Array, y0: float, dt: float, r_max: float, extra: dict[str, Any]
) -> Array:
    kind = blk.kind
    p = blk.params
    if kind == "delay":
        return _inv_delay(blk, y, dt)
    if kind == "structural_mode":
        return _inv_linear(blk, y, y0, dt, r_max, extra)
    if kind == "creep":
        return _inv_creep(blk, y, y0, dt)
    if kind == "gain_offset":
        return np.asarray((y - float(p["offset"])) / float(p["gain"]), dtype=float)
    if kind == "sensor_drift":
        drift = float(p["offset"]) + float(p["rate"]) * (1 + np.arange(y.size)) * dt
        return np.asarray(y - drift, dtype=float)
    if kind == "sensor_nonlinearity":
        return np.asarray(blk.inverse(y))
    raise ValueError(
        f"{blk.describe()}: this output block is not invertible by preisach.compensate"
    )


def invert_augmented(
    model: Any,
    y_ref: ArrayLike,
    state: Any = None,
    *,
    sample_time: float = 1e-3,
    r_max: float = 0.95,
    nonmonotone: str = "as_is",
) -> InverseResult:
    """Drive (V) that makes an augmented model follow ``y_ref`` (V); see the module docstring.

    Parameters
    ----------
    model : AugmentedModel
        ``input blocks -> Preisach -> output blocks`` (duck-typed: ``base``,
        ``input_blocks``, ``output_blocks``, ``feedback_blocks``, ``simulate``).
    y_ref : array_like, shape (n,)
        Target outputs (V), finite.
    state : State, optional
        Initial boundary of the Preisach stage; default anhysteretic.  Every block starts
        in its steady state, as in ``AugmentedModel.simulate``.
    sample_time : float
        Sample time (s) of the reference and of the blocks.
    r_max : float
        Largest root radius kept in a linear block's inverse (see the module docstring).
    nonmonotone : {"as_is", "project"}
        For the Preisach stage (see :func:`preisach.compensate.invert`).

    Returns
    -------
    InverseResult
        ``input`` the drive (V, clamped to the input range), ``output`` the augmented model's
        output for it; ``reached`` is that of the Preisach stage; ``extra`` holds
        ``preisach_target`` (what the Preisach stage must output), ``bandwidth_hz`` when a
        linear inverse is band-limited, and ``clamped`` (drive samples clamped to the range).

    """
    from ..model import _real_array

    y = _real_array("y_ref", y_ref)
    if y.ndim != 1:
        raise ValueError(f"y_ref: expected a 1-D array of target outputs, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"y_ref[{int(np.argmax(~np.isfinite(y)))}] is not finite")
    dt = float(sample_time)
    if not dt > 0:
        raise ValueError(f"sample_time: must be positive, got {sample_time}")
    if not 0 < r_max < 1:
        raise ValueError(f"r_max: must be in (0, 1), got {r_max}")
    if model.feedback_blocks:
        raise ValueError(
            f"{model.feedback_blocks[0].describe()}: output feedback (a moving model) is not "
            "invertible by preisach.compensate"
        )
    base = model.base
    s0 = base.anhysteretic_state() if state is None else state
    extra: dict[str, Any] = {}
    # steady outputs along the output chain, from the Preisach output of the start state
    outs = model.output_blocks
    levels = [base.readout(s0)]
    for blk in outs:
        levels.append(float(blk.with_dt(dt).reset(levels[-1])))
    x = y
    for i in range(len(outs) - 1, -1, -1):
        blk = outs[i].with_dt(dt)
        x = _invert_output_block(blk, x, levels[i + 1], dt, r_max, extra)
    extra["preisach_target"] = x
    inner = invert(base, x, s0, sample_time=dt, nonmonotone=nonmonotone)
    u = inner.input
    for blk in reversed(model.input_blocks):
        b = blk.with_dt(dt)
        if b.kind == "rate_dependence" and set(b.params) == {"tau"}:
            tau = float(b.params["tau"])
            e = math.exp(-dt / tau) if tau > 0 else 0.0
            prev = np.r_[float(s0.input), u[:-1]]
            u = (u - e * prev) / (1.0 - e)
        else:
            raise ValueError(
                f"{b.describe()}: this input block is not invertible by preisach.compensate"
            )
    clamped = int(np.count_nonzero((u < base.u_min) | (u > base.u_max)))
    u = np.clip(u, base.u_min, base.u_max)
    extra["clamped"] = clamped
    sim = model.simulate(u, s0, sample_time=dt)
    return InverseResult(y, u, sim.output, inner.reached, s0, sim.final_state, dt, extra)
