r"""Inverse of the rate-dependent model (:class:`~preisach.rate_model.RateDependentPreisachModel`).

Its output ``y = sum_k b_k(v) Gamma_k(psi)`` blends the tables' read-outs by weights of the
filtered input rate ``v``, and ``v`` of a sample depends on that sample's input step
``|u - u_prev|``: the output along an input excursion is no longer piecewise polynomial, so
this inverse is **not** closed-form.  Holding the input still moves the output (the rate
decays), and a small step can move it either way, so for each target it walks the grid levels
outward from the current input in both directions, takes in each the first grid interval
whose end values bracket the target, solves there by the Illinois (modified regula falsi)
method to ``tol`` volts, and keeps the root nearer the current input,
evaluating the model's own C++ step from the current state each time.  The rate-dependent
output is continuous in the input, so a bracket always holds a root; a target that no point
of the excursion brackets is unreachable: it gets the input of the nearest output found (the
grid levels and the excursion's end), counted in ``unreachable``.  The input is then applied
to the model, so the state (boundary and filtered rate) is tracked as in ``simulate``.
Cost: one C++ step per grid level crossed plus ~10-40 per target; offline feedforward, not a
real-time inverse.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .inverse import InverseResult

__all__ = ["invert_rate"]


def invert_rate(
    model: Any,
    y_ref: ArrayLike,
    state: Any = None,
    *,
    sample_time: float = 1e-3,
    tol: float = 1e-10,
) -> InverseResult:
    """Drive (V) that makes a rate-dependent model follow ``y_ref`` (V); see the module docstring.

    Parameters
    ----------
    model : RateDependentPreisachModel
        The model.
    y_ref : array_like, shape (n,)
        Target outputs (V), finite.
    state : RateState or State, optional
        Initial boundary and filtered rate (a bare State: at rest); default anhysteretic.
    sample_time : float
        Sampling period (s): the ``dt`` of the rate.
    tol : float
        Output tolerance (V) of the root inside a bracket.

    Returns
    -------
    InverseResult
        ``initial_state`` and ``final_state`` are the boundaries; ``extra["final_rate"]`` is
        the filtered rate at the end (V/s).

    """
    from ..model import _real_array

    y = _real_array("y_ref", y_ref)
    if y.ndim != 1:
        raise ValueError(f"y_ref: expected a 1-D array of target outputs, got shape {y.shape}")
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise ValueError(f"y_ref[{int(bad[0])}] is not finite")
    if not sample_time > 0:
        raise ValueError(f"sample_time: must be positive, got {sample_time}")
    sim = model.simulator(state, sample_time=sample_time)
    probe = model.simulator(state, sample_time=sample_time)
    s0 = sim.state
    levels = np.asarray(model.levels, dtype=float)
    lo, hi = float(model.u_min), float(model.u_max)
    n = y.size
    u_out, y_out = np.empty(n), np.empty(n)
    reached = np.ones(n, dtype=bool)
    for k in range(n):
        target = float(y[k])
        b, v, u0 = sim.state, sim.rate, sim.input

        def f(u: float, b: Any = b, v: float = v) -> float:
            probe.reset(b, v)
            return float(probe.step(u))

        y_hold = f(u0)  # holding the input still moves the output: the rate decays
        u = u0
        if target != y_hold:
            best_u, best_err = u0, abs(y_hold - target)
            found: list[float] = []
            for up in (True, False):
                grid = levels[levels > u0] if up else levels[levels < u0][::-1]
                a_u, a_y = u0, y_hold
                for x in [*grid, hi if up else lo]:
                    fx = f(float(x))
                    if (a_y - target) * (fx - target) <= 0:
                        found.append(_illinois(f, a_u, a_y, float(x), fx, target, tol))
                        break
                    if abs(fx - target) < best_err:
                        best_u, best_err = float(x), abs(fx - target)
                    a_u, a_y = float(x), fx
            if found:
                u = min(found, key=lambda c: abs(c - u0))
            else:
                u, reached[k] = best_u, False
        u_out[k] = min(max(u, lo), hi)
        y_out[k] = sim.step(u_out[k])
    extra = {"final_rate": float(sim.rate)}
    return InverseResult(y, u_out, y_out, reached, s0, sim.state, float(sample_time), extra)


def _illinois(f: Any, a: float, fa: float, b: float, fb: float, target: float, tol: float) -> float:
    """Root of ``f(u) = target`` in the bracket ``[a, b]`` (Illinois regula falsi)."""
    fa, fb = fa - target, fb - target
    if fa == 0:
        return a
    if fb == 0:
        return b
    side = 0
    c = b
    for _ in range(200):
        c = (a * fb - b * fa) / (fb - fa)
        fc = f(c) - target
        if abs(fc) <= tol or abs(b - a) < 1e-13 * (1.0 + abs(c)):
            return c
        if fc * fb > 0:  # c replaces b
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:  # c replaces a
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
    return c
