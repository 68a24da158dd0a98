"""Recordings prepared for diagnosis: initial states, burn-in masks, time blocks, noise level."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model import PreisachModel, State
from ..recording import Recording

__all__ = [
    "History",
    "Rec",
    "noise_sigma",
    "prepare_recordings",
    "session_history",
    "state_options",
]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class History:
    """An input history before a recording: it sets the unknown initial state.

    ``kind`` says where it starts: ``"range"`` - the relays were driven over the recording's
    own input range (up to its maximum, down to its minimum), as in a run that goes on the way
    it was recorded; ``"positive"`` / ``"negative"`` - from a saturation; ``"anhysteretic"`` -
    from the demagnetised state.  Then the relays saw the turning points ``turns`` (fractions
    of the recording's own range: 0 its minimum, 1 its maximum) and then the recording's first
    input.  :meth:`state` builds the state from the input the relays actually see, so an input
    block that changes that input (a lag started mid-sweep lowers its first value and its
    extremes) keeps the history and moves its ends with it.

    ``"session"``: the state the previous recording of the same session left (``left``: its
    relays' state at its end, turning points in absolute volts), then a move to this
    recording's first input - the recordings of one lab session made one after another, as
    given.  It has no free parameter (see :func:`session_history`).
    """

    label: str
    u_range: tuple[float, float]
    kind: str = "range"
    turns: tuple[float, ...] = ()
    anhysteretic: State | None = None
    left: State | None = None

    def state(self, x: Array, left: State | None = None) -> State:
        """Return the relays' state after this history, for the relay input ``x`` (V) after it.

        ``left``: for a session history, the previous recording's end state to start from
        instead of :attr:`left` (with a feedback effect its relays saw a shifted input,
        :meth:`~preisach.diagnose.context.Context.session_left`).
        """
        return self.state_of(float(x[0]), float(np.min(x)), float(np.max(x)), left)

    def state_of(self, first: float, lo: float, hi: float, left: State | None = None) -> State:
        """:meth:`state` for a relay input given by its first value, minimum and maximum (V)."""
        if self.kind == "anhysteretic" and self.anhysteretic is not None:
            return self.anhysteretic.apply([first])
        if self.kind == "session" and self.left is not None:
            end = self.left if left is None else left
            return end.apply([float(np.clip(first, *self.u_range))])
        pts = [lo + f * (hi - lo) for f in self.turns] + [first]
        if self.kind == "range":
            pts = [hi, lo, *pts]
        start = (
            State.positive_saturation(*self.u_range)
            if self.kind == "positive"
            else State.negative_saturation(*self.u_range)
        )
        return start.apply(np.clip(pts, *self.u_range).tolist())


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
    #: when the initial state is unknown: the history chosen with the given model (``state0``
    #: is its state at the first input), a nuisance re-chosen for every fitted chain (see
    #: :meth:`Context.choose_states`)
    history: History | None = None
    #: when the initial state is unknown and a recording came before this one in the
    #: session: the state it left (:func:`session_history`), one more option of the choice
    session: History | None = None

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


def state_options(model: PreisachModel, x: Array, kind: str | None = None) -> list[History]:
    """Candidate histories of up to three turns before a recording whose relays see ``x`` (V).

    Of every kind (see :class:`History`; only ``kind`` when given): the first input reached
    straight from the start, via one turning point on a 41-level grid of the recording's own
    range, or via two on an 11-level grid; and the anhysteretic state.
    """
    rng = (model.u_min, model.u_max)
    lo, hi = float(np.min(x)), float(np.max(x))
    span = hi - lo
    f0 = (float(x[0]) - lo) / span if span > 0 else 0.0

    def v(f: float) -> str:
        return f"{lo + f * span:.3g}"

    after = f"after {v(0)}-{v(1)} V"
    out: list[History] = []
    if kind in (None, "anhysteretic"):
        out.append(History("anhysteretic", rng, "anhysteretic", (), model.anhysteretic_state()))
    fine = [float(a) for a in np.linspace(0.0, 1.0, 41)[1:-1]]
    coarse = [float(c) for c in np.linspace(0.0, 1.0, 11)]
    if kind in (None, "range"):
        out.append(History(f"rose from {v(0)} V ({after})", rng))
        out.append(History(f"fell from {v(1)} V ({after})", rng, "range", (1.0,)))
        for a in fine:
            if a > f0:
                out.append(History(f"via {v(a)} V ({after})", rng, "range", (a,)))
            elif a < f0:
                out.append(History(f"via {v(a)} V ({after})", rng, "range", (1.0, a)))
        for a in coarse:
            for b in coarse:
                if a > f0 > b:
                    out.append(History(f"via {v(a)}, {v(b)} V ({after})", rng, "range", (a, b)))
                elif a < f0 < b:
                    out.append(
                        History(f"via {v(a)}, {v(b)} V ({after})", rng, "range", (1.0, a, b))
                    )
    for sat, word, sign in (("negative", "rose", 1), ("positive", "fell", -1)):
        if kind not in (None, sat):
            continue
        out.append(History(f"{word} from {sat} saturation", rng, sat))
        for a in fine:
            if sign * (a - f0) > 0:
                out.append(History(f"from {sat} saturation via {v(a)} V", rng, sat, (a,)))
        for a in coarse:
            for b in coarse:
                if sign * (a - f0) > 0 > sign * (b - f0):
                    out.append(
                        History(f"from {sat} saturation via {v(a)}, {v(b)} V", rng, sat, (a, b))
                    )
    return out


def session_history(model: PreisachModel, prev: Rec) -> History:
    """Return the history "left by the previous recording": ``prev`` run from its start.

    Recordings of one lab session are made one after another, so a recording starts from
    the state the previous one left (then the input moves to its first value).  A recording
    that never reaches the range ends keeps, for its whole length, what an earlier one left
    beyond its range - which no history within its own range can give, and the histories
    from a saturation can give only at the BIC charge of a free offset.  This option has no
    free parameter: the previous recording's input turning points in absolute volts, from
    its initial state as chosen with the given model.
    """
    left = prev.state0.apply(prev.u.tolist())
    return History(f"left by {prev.name!r}", (model.u_min, model.u_max), "session", left=left)


def _initial_history(
    model: PreisachModel, u: Array, y: Array, session: History | None = None
) -> History:
    """Choose an unknown initial state: a nuisance parameter, not a reason to discard data.

    The candidates are the histories of :func:`state_options`.  The one whose simulation by
    the given model fits the recording best (least squares over all its samples) is taken,
    and every sample is scored, so a ring after the first step counts as evidence.  A history
    from a saturation must fit clearly better than every history within the recording's own
    range and the anhysteretic state - by more than the BIC charge of two parameters,
    ``n ln(SSE_within / SSE_saturation) > 2 ln n`` - because it leaves the relays the input
    never reaches in a different state: a free output offset per recording, which a refit
    with an input lag or a feedback turns into per-recording offsets of its weights.
    The choice among histories of the chosen kind is made again for every chain of effects
    fitted during the diagnosis (:meth:`Context.choose_states`).  ``session`` (the state the
    previous recording left, :func:`session_history`) is one more option, uncharged like
    those within the range: it has no free parameter.
    """
    from .. import _core

    best: dict[bool, tuple[float, History]] = {}
    opts = state_options(model, u) + ([session] if session is not None else [])
    for h in opts:
        sse = float(np.sum((y - _core.simulate(model.table, u, h.state(u), "clamp")[0]) ** 2))
        within = h.kind in ("range", "anhysteretic", "session")
        if within not in best or sse < best[within][0]:
            best[within] = (sse, h)
    n = u.size
    (s_in, h_in), (s_out, h_out) = best[True], best[False]
    if s_out <= 0 or n * math.log(max(s_in, 1e-300) / s_out) > 2 * math.log(n):
        return h_out
    return h_in


def prepare_recordings(
    model: PreisachModel,
    recordings: Sequence[Recording],
    *,
    initial_states: Sequence[State | str | None] | None = None,
    block_length: float | None = None,
    identification: Sequence[Recording] = (),
) -> list[Rec]:
    """Prepare the recordings: initial states, burn-in masks, time blocks and fold parities.

    Identification recordings come last in the returned list, flagged ``ident``.  The
    diagnosed recordings are taken as one lab session in the order given: one whose initial
    state is unknown may start from the state the previous one left (:func:`session_history`).
    The identification recordings do not count as earlier in that session: nothing says when
    they were recorded (a model file may be days older than the experiments).
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
        history: History | None = None
        session: History | None = None
        if isinstance(spec, State):
            s0, start = spec, "given"
        elif spec == "negative_saturation":
            s0, start = model.negative_saturation(), spec
        elif spec == "positive_saturation":
            s0, start = model.positive_saturation(), spec
        elif spec == "anhysteretic":
            s0, start = model.anhysteretic_state(), spec
        elif spec == "unknown":
            prev = out[-1] if out and not ident else None
            session = session_history(model, prev) if prev is not None else None
            history = _initial_history(model, u, np.asarray(r.y, float), session)
            s0, start = history.state(u), f"unknown: {history.label}"
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
                history,
                session,
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
