"""Interfaces shared across layers (the lowest layer: imports nothing of the package).

:class:`Block` is the one block interface: a single-input single-output discrete-time system
sampled every ``dt`` seconds.  The virtual rig's C++ blocks (:mod:`preisach.daq.blocks`) and
diagnosis's effect blocks (:mod:`preisach.diagnose`) both satisfy it, so code that only steps,
runs and resets a block takes either family.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Block"]


@runtime_checkable
class Block(Protocol):
    """A SISO block with named parameters and a state: ``reset``, ``step``, ``run``.

    ``step(x)`` holds ``x`` over one sample interval (zero-order hold) and returns the output
    at its end; ``run`` applies ``step`` to every sample of an array from the current state
    (which is advanced); ``reset(x0)`` puts the block in its steady state for the constant
    input ``x0`` and returns the output there.  Units are those of the signal (V in, V out for
    the actuator's blocks); parameters are in the units :attr:`units` names.
    """

    @property
    def kind(self) -> str:
        """Short identifier of the block type (``"creep"``, ``"delay"``, ...)."""
        ...

    @property
    def dt(self) -> float:
        """Sample time (s)."""
        ...

    @property
    def params(self) -> Mapping[str, Any]:
        """Parameter values by name."""
        ...

    @property
    def units(self) -> Mapping[str, str]:
        """Unit of every parameter."""
        ...

    def reset(self, x0: float) -> float:
        """Reset to the steady state for the constant input ``x0``; return the output."""
        ...

    def step(self, x: float) -> float:
        """Advance one sample with input ``x``; return the output."""
        ...

    def run(self, x: ArrayLike) -> NDArray[np.float64]:
        """Process the samples ``x`` from the current state; return the outputs."""
        ...
