"""Initial-state policies for simulating a model along a recording whose start state is unknown.

A recording's initial state is unknown.  The policies (``initial_state`` arguments of
:func:`preisach.verify.verify` and the identifiers of :mod:`preisach.identify`):

* ``"burn-in"`` (default): simulate from negative saturation and do not score (or fit) the
  samples before the recording's *burn-in end* (:func:`burn_in_end`);
* ``"negative"``, ``"positive"``, ``"anhysteretic"`` or a :class:`~preisach.State`: every sample
  counts, from that state.

This module sits with the model and its state (it imports only :mod:`preisach.model`), so that
verification and identification both use it without importing each other.
"""

from __future__ import annotations

from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from .model import PreisachModel, State

__all__ = ["POLICIES", "InitialState", "burn_in_end", "check_policy", "initial_state_for"]

#: An initial-state policy: one of :data:`POLICIES` or an explicit State.
InitialState = Union[str, State]
#: The named policies.
POLICIES: tuple[str, ...] = ("burn-in", "negative", "positive", "anhysteretic")
_POLICIES = POLICIES


def burn_in_end(u: ArrayLike, u_min: float, u_max: float) -> tuple[int, bool]:
    """First sample from which a recording's output is determined by its input (see module doc).

    Parameters
    ----------
    u : array_like
        Input samples (V).
    u_min, u_max : float
        Input range of the table (V); inputs outside are clamped by the model.

    Returns
    -------
    index : int
        Samples ``index, index + 1, ...`` are determined (their state no longer depends on the
        initial state, except through relays the recording never switches).
    exact : bool
        ``True`` when the input reached ``u_min`` or ``u_max`` by ``index`` (a saturation: the
        state is exact); ``False`` when only the recording's own extremes were visited.

    """
    uu = np.asarray(u, dtype=float)
    if uu.ndim != 1 or uu.size == 0:
        raise ValueError("u: expected a non-empty 1-D array of input samples (V)")
    sat = np.nonzero((uu <= u_min) | (uu >= u_max))[0]
    k_sat = int(sat[0]) if sat.size else uu.size
    k_own = max(int(np.argmin(uu)), int(np.argmax(uu)))  # first visits of both own extremes
    if k_sat <= k_own:
        return k_sat, True
    return k_own, False


def initial_state_for(
    model_or_range: PreisachModel | tuple[float, float], policy: InitialState
) -> State:
    """Return the state a policy simulates from (``"burn-in"`` starts at negative saturation)."""
    if isinstance(model_or_range, PreisachModel):
        lo, hi = model_or_range.u_min, model_or_range.u_max
    else:
        lo, hi = (float(v) for v in model_or_range)
    if isinstance(policy, State):
        return policy
    if policy in ("burn-in", "negative"):
        return State.negative_saturation(lo, hi)
    if policy == "positive":
        return State.positive_saturation(lo, hi)
    if policy == "anhysteretic":
        l0 = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
        return State.neutral(lo, hi, l0)
    raise ValueError(f"initial_state: expected one of {_POLICIES} or a State, got {policy!r}")


def check_policy(policy: InitialState) -> str:
    """Name of an initial-state policy (``"state"`` for an explicit State); raises on bad input."""
    if isinstance(policy, State):
        return "state"
    if policy not in _POLICIES:
        raise ValueError(f"initial_state: expected one of {_POLICIES} or a State, got {policy!r}")
    return str(policy)
