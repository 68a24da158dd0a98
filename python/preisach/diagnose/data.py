"""Recordings prepared for diagnosis: initial states, burn-in masks, time blocks, noise level."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model import PreisachModel, State
from ..recording import Recording

__all__ = ["Rec", "noise_sigma", "prepare_recordings"]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass
class Rec:
    """A recording prepared for diagnosis."""

    name: str
    t: Array
    u: Array
    y: Array
    dt: float
    state0: State
    usable: Mask
    block: NDArray[np.int64]
    fold: NDArray[np.int64]
    start: str
    ident: bool = False

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.u.size)


def _rec_name(rec: Recording, i: int) -> str:
    for key in ("name", "experiment"):
        v = rec.metadata.get(key)
        if isinstance(v, str) and v:
            return v
    return f"recording {i}"


def _burn_in(u: Array, tol: float) -> int:
    """Return the number of samples to skip when the initial state is unknown.

    Once the input has visited its maximum and its minimum the Preisach state no longer
    depends on the unknown start; a block acting before the relays (a lag, a play) may still
    carry the start a little further, so the burn-in runs to the next visit of the first
    extreme (max -> min -> max, or min -> max -> min), or, if there is none, 5 % of the
    recording beyond the second extreme.
    """
    at_hi, at_lo = u >= u.max() - tol, u <= u.min() + tol
    i_hi, i_lo = int(np.argmax(at_hi)), int(np.argmax(at_lo))
    second = max(i_hi, i_lo)
    again = np.flatnonzero((at_hi if i_hi < i_lo else at_lo)[second:])
    if again.size:
        return second + int(again[0])
    return min(u.size, second + max(1, u.size // 20))


def _initial_state(model: PreisachModel, u: Array, y: Array) -> tuple[State, str]:
    """Choose an unknown initial state: a nuisance parameter, not a reason to discard data.

    The candidates are the states that histories of up to three turns leave at the first
    input ``u[0]``: from negative (positive) saturation straight to ``u[0]``; via one turning
    point ``a`` on a 41-level grid; via two, ``a`` and ``b``, on an 11-level grid; and the
    anhysteretic state.  The one whose simulation by the given model fits the recording best
    (least squares over all its samples, which differ only until the input has wiped the
    start out) is taken, and every sample is scored, so a ring after the first step counts
    as evidence.
    """
    from .. import _core

    table = model.table
    lo, hi = model.u_min, model.u_max
    u0 = float(np.clip(u[0], lo, hi))
    neg, pos = model.negative_saturation(), model.positive_saturation()
    paths: list[tuple[str, State, list[float]]] = [
        ("anhysteretic", model.anhysteretic_state(), []),
        ("rose from negative saturation", neg, [u0]),
        ("fell from positive saturation", pos, [u0]),
    ]
    fine = np.linspace(lo, hi, 41)
    coarse = np.linspace(lo, hi, 11)
    for a in fine:
        if a > u0:
            paths.append((f"from negative saturation via {a:.3g} V", neg, [a, u0]))
        elif a < u0:
            paths.append((f"from positive saturation via {a:.3g} V", pos, [a, u0]))
    for a in coarse:
        for b in coarse:
            if a > u0 > b:
                paths.append((f"from negative saturation via {a:.3g}, {b:.3g} V", neg, [a, b, u0]))
            elif a < u0 < b:
                paths.append((f"from positive saturation via {a:.3g}, {b:.3g} V", pos, [a, b, u0]))
    best: tuple[float, str, State] | None = None
    for what, s0, path in paths:
        st = _core.simulate(table, np.array(path), s0, "clamp")[1] if path else s0
        sse = float(np.sum((y - _core.simulate(table, u, st, "clamp")[0]) ** 2))
        if best is None or sse < best[0]:
            best = (sse, what, st)
    assert best is not None
    return best[2], f"unknown: {best[1]}"


def prepare_recordings(
    model: PreisachModel,
    recordings: Sequence[Recording],
    *,
    initial_states: Sequence[State | str | None] | None = None,
    block_length: float | None = None,
    identification: Sequence[Recording] = (),
) -> list[Rec]:
    """Prepare the recordings: initial states, burn-in masks, time blocks and fold parities.

    Identification recordings come last in the returned list, flagged ``ident``.
    """
    if not recordings:
        raise ValueError("recordings: need at least one recording to diagnose")
    if initial_states is not None and len(initial_states) != len(recordings):
        raise ValueError(
            f"initial_states: expected {len(recordings)} entries (one per recording), "
            f"got {len(initial_states)}"
        )
    span = model.u_max - model.u_min
    tol = 0.01 * span
    durations = [float(r.t[-1] - r.t[0]) if len(r.t) > 1 else 0.0 for r in recordings]
    if block_length is None:
        block_length = float(np.clip(max(durations) / 10.0, 0.25, 2.0))
    if not block_length > 0:
        raise ValueError(f"block_length: must be positive, got {block_length}")
    out: list[Rec] = []
    next_block = 0
    all_recs = [(r, False) for r in recordings] + [(r, True) for r in identification]
    for i, (r, ident) in enumerate(all_recs):
        name = _rec_name(r, i)
        if ident:
            name = f"identification: {name}"
        if len(r.t) < 20:
            raise ValueError(
                f"recording {name!r}: too short ({len(r.t)} samples; need at least 20)"
            )
        dt = float(np.median(np.diff(r.t)))
        u = np.clip(r.u, model.u_min, model.u_max)
        spec = None if (initial_states is None or ident) else initial_states[i]
        if spec is None:
            meta = r.metadata.get("initial_state")
            spec = meta if isinstance(meta, str) else None
        if spec is None:
            if u[0] <= model.u_min + tol:
                spec = "negative_saturation"
            elif u[0] >= model.u_max - tol:
                spec = "positive_saturation"
            else:
                spec = "unknown"
        usable = np.ones(u.size, bool)
        if isinstance(spec, State):
            s0, start = spec, "given"
        elif spec == "negative_saturation":
            s0, start = model.negative_saturation(), spec
        elif spec == "positive_saturation":
            s0, start = model.positive_saturation(), spec
        elif spec == "anhysteretic":
            s0, start = model.anhysteretic_state(), spec
        elif spec == "unknown":
            s0, start = _initial_state(model, u, np.asarray(r.y, float))
        elif spec == "burn_in":
            s0, start = model.anhysteretic_state(), spec
            usable[: _burn_in(u, tol)] = False
        else:
            raise ValueError(
                f"initial state of {name!r}: expected a State or one of "
                f"'negative_saturation', 'positive_saturation', 'anhysteretic', 'unknown', "
                "'burn_in'; "
                f"got {spec!r}"
            )
        if usable.sum() < 20:
            raise ValueError(
                f"recording {name!r}: fewer than 20 usable samples after the burn-in "
                "(the input must visit its maximum and minimum to fix the unknown initial state)"
            )
        blk = np.floor((r.t - r.t[0]) / block_length).astype(np.int64) + next_block
        next_block = int(blk[-1]) + 1
        out.append(
            Rec(
                name,
                np.asarray(r.t, float),
                u,
                np.asarray(r.y, float),
                dt,
                s0,
                usable,
                blk,
                (blk % 2).astype(np.int64),
                start,
                ident,
            )
        )
    return out


def noise_sigma(residual: Array) -> float:
    """Robust noise standard deviation (V) from third differences of a residual."""
    d = np.diff(residual, 3)
    if d.size < 10:
        return float("nan")
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / math.sqrt(20.0))
