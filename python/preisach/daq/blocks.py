"""Physics blocks: the dynamics a classical Preisach model leaves out, as composable pieces.

A block is a single-input single-output discrete-time system sampled every ``dt`` seconds,
with a few named parameters (:attr:`~preisach._core.Block.params`), a state,
:meth:`~preisach._core.Block.reset`, :meth:`~preisach._core.Block.step` and a vectorised
:meth:`~preisach._core.Block.run` (C++, GIL released).  ``step(x)`` holds ``x`` over one
sample interval (zero-order hold) and returns the output at its end; linear blocks are
discretised exactly under that convention.  Blocks compose into a :class:`BlockChain`::

    input blocks -> PreisachStage -> output blocks

which the virtual rig (:func:`preisach.daq.virtual_ss15`) uses to make realistic recordings and
which diagnosis can fit.  Every block is off unless you add it; all random ones are seeded.

=====================  ======  =============================================================
block                  side    physics (see each class for the model and its parameters)
=====================  ======  =============================================================
:class:`InputLag`      input   SA11 amplifier driving the capacitive bimorph (RC lag); makes
                               loops widen in proportion to the input rate (rate-dependent
                               hysteresis), ``time_constant`` (s)
:class:`PreisachStage` --      the Preisach model; ``moving_gain`` (V/V) > 0 feeds the output
                               back (moving Preisach model: non-congruent minor loops)
:class:`StructuralMode` output the bimorph's bending mode, ``frequency`` (Hz, thesis 37.62),
                               ``damping`` (zeta)
:class:`Creep`         output logarithmic creep toward equilibrium, ``rate`` per decade of
                               time between ``tau_min`` and ``tau_max`` (s)
:class:`OffsetDrift`   output strain-gauge offset drift: ``rate`` (V/s) and a random walk
                               ``sigma`` (V/sqrt(s)), ``seed``
:class:`Delay`         output measurement latency, ``samples``
:class:`MovingAverage` output the thesis's 10-sample ADC moving average, ``length``
=====================  ======  =============================================================

:func:`make_block` builds a block from a ``{"kind": ..., **params}`` mapping (the form used in
trial files).  Every block here derives from the C++ base :data:`RigBlock` and satisfies the
package's one block interface, :class:`preisach.types.Block` (``reset``/``step``/``run``), as
diagnosis's effect blocks do.  This module mirrors ``cpp/include/preisach/blocks/``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

from .. import _core
from ..model import PreisachModel, State

#: C++ base class of the rig's blocks (the virtual rig accepts only these).
RigBlock = _core.Block
BlockChain = _core.BlockChain
StructuralMode = _core.StructuralMode
InputLag = _core.InputLag
Creep = _core.Creep
Delay = _core.Delay
MovingAverage = _core.MovingAverage
OffsetDrift = _core.OffsetDrift
PreisachStage = _core.PreisachStage

__all__ = [
    "BLOCK_KINDS",
    "RigBlock",
    "BlockChain",
    "Creep",
    "Delay",
    "InputLag",
    "MovingAverage",
    "OffsetDrift",
    "PreisachStage",
    "StructuralMode",
    "make_block",
    "preisach_stage",
]

#: Block kinds usable in :func:`make_block`, with their parameters and defaults.
BLOCK_KINDS: dict[str, tuple[type, dict[str, Any]]] = {
    "structural_mode": (StructuralMode, {"frequency": 37.62, "damping": 0.02}),
    "input_lag": (InputLag, {"time_constant": 1e-3}),
    "creep": (Creep, {"rate": 0.01, "tau_min": 0.1, "tau_max": 100.0}),
    "delay": (Delay, {"samples": 1}),
    "moving_average": (MovingAverage, {"length": 10}),
    "offset_drift": (OffsetDrift, {"rate": 0.0, "sigma": 0.0, "seed": 0}),
}

_INT_PARAMS = {"samples", "length", "seed"}


def make_block(spec: Mapping[str, Any], dt: float) -> RigBlock:
    """Build a block from ``{"kind": name, **params}``.

    Parameters
    ----------
    spec : mapping
        ``kind`` is one of :data:`BLOCK_KINDS`; the other keys are that block's parameters
        (missing ones take their defaults).
    dt : float
        Sample time (s).

    Returns
    -------
    RigBlock

    Raises
    ------
    ValueError
        For an unknown kind, an unknown parameter (named), or an invalid value.
    TypeError
        For a parameter of the wrong type.

    """
    if "kind" not in spec:
        raise ValueError(f"block {dict(spec)!r}: missing 'kind' (one of {sorted(BLOCK_KINDS)})")
    kind = spec["kind"]
    if kind not in BLOCK_KINDS:
        raise ValueError(f"block kind {kind!r} is unknown; choose from {sorted(BLOCK_KINDS)}")
    cls, defaults = BLOCK_KINDS[kind]
    params = {k: v for k, v in spec.items() if k != "kind"}
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ValueError(
            f"block {kind!r}: unknown parameter(s) {unknown}; it takes {sorted(defaults)}"
        )
    args: dict[str, Any] = {}
    for name, default in defaults.items():
        value = params.get(name, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeError(f"block {kind!r}: parameter {name} must be a number, got {value!r}")
        if name in _INT_PARAMS:
            if int(value) != value or value < 0:
                raise ValueError(
                    f"block {kind!r}: parameter {name} must be a whole number >= 0, got {value!r}"
                )
            value = int(value)
        args[name] = value
    return cast(RigBlock, cls(dt, **args))


def preisach_stage(
    model: PreisachModel, state: State | None = None, dt: float = 1e-3, moving_gain: float = 0.0
) -> PreisachStage:
    """Make the Preisach stage of a chain from a :class:`~preisach.PreisachModel`.

    Parameters
    ----------
    model : PreisachModel
        The model (input V, output V).
    state : State, optional
        Starting state; default the model's anhysteretic state.
    dt : float
        Sample time (s).
    moving_gain : float
        Output feedback ``k`` (V/V): the relays see ``u + k * y`` (moving Preisach model).

    """
    st = model.anhysteretic_state() if state is None else state
    return PreisachStage(dt, model.table, st, moving_gain)
