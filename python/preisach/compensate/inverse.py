r"""Exact inverse of a classical Preisach model (the C++ ``Inverter``).

For each target output the inverter searches the table cells along the monotone input
excursion from the current input (rising for a target above the current output, falling for
one below it, wiping out memory as the model does) and takes the closed-form root of the
output there: linear in the input inside a cell for staircase boundaries, quadratic for the
antidiagonal boundary pieces of neutral states.  It steps the same boundary-stack simulator as
:meth:`PreisachModel.simulate`, so ``model.simulate(r.input, state).output`` equals
``r.output`` exactly, and ``r.output`` equals the reference wherever it was reachable.

Which input, when several give the target:

* in a model with non-negative weights (class Mp) the first input reaching the target along
  the excursion (where the output is flat, the start of the flat part);
* in a model with negative cells (the 2 and 4 Hz surfaces of Table 3.1), by default
  (``nonmonotone="as_is"``) the model is inverted as it is: both excursions are searched and
  the smaller input change that reaches the target wins; with ``nonmonotone="project"`` the
  model projected to non-negative weights (least squares in the Everett values) is inverted
  instead, and the outputs reported are still those of the given model;
* a target that no excursion reaches (beyond saturation, or out of reach of a non-monotone
  model) gets the input whose output is nearest; it is flagged in ``reached`` and counted in
  ``unreachable`` -- never an exception in the middle of a run.

A model with a cubic table (:attr:`PreisachModel.interpolation`) is inverted through the
bilinear table of its interpolant on a grid :data:`CUBIC_REFINE` times finer (every original
level kept); the outputs reported are the cubic model's, so they meet the targets to within
that resampling (``reached`` tells the resampled table's), on the 21-level FOD grid of a
smooth density by microvolts.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core

if TYPE_CHECKING:  # pragma: no cover
    from ..model import PreisachModel, State

__all__ = ["InverseResult", "invert", "inverter"]

_NONMONOTONE = ("as_is", "project")
#: cells per original cell of the bilinear table a cubic model is inverted through
CUBIC_REFINE = 8


@dataclass
class InverseResult:
    """Result of :func:`invert` / :meth:`PreisachModel.inverse`.

    Unpacks like a tuple: ``t, u = model.inverse(y_ref)``.

    Attributes
    ----------
    reference : ndarray
        The target outputs (V) as given.
    input : ndarray
        The input (V) that drives the model along the reference, inside ``[u_min, u_max]``.
    output : ndarray
        The model's output (V) for ``input`` from ``initial_state``: equal to ``reference``
        (to rounding) where ``reached``, the nearest reachable output elsewhere.
    reached : ndarray of bool
        Whether each target was reachable.
    initial_state, final_state : State
        Boundary before the first and after the last sample.
    sample_time : float
        Sampling period (s) when no time array was given.

    """

    reference: NDArray[np.float64]
    input: NDArray[np.float64]
    output: NDArray[np.float64]
    reached: NDArray[np.bool_]
    initial_state: State
    final_state: State
    sample_time: float = 1e-3
    extra: dict[str, Any] = field(default_factory=dict)
    _time: NDArray[np.float64] | None = field(default=None, repr=False)

    @property
    def unreachable(self) -> int:
        """Number of targets that no input reaches (given the nearest output instead)."""
        return int(np.count_nonzero(~self.reached))

    @property
    def error(self) -> NDArray[np.float64]:
        """``output - reference`` (V): zero to rounding where reached."""
        return cast(NDArray[np.float64], self.output - self.reference)

    @property
    def max_error(self) -> float:
        """Largest ``|output - reference|`` (V) over all samples (0.0 for no samples)."""
        return float(np.max(np.abs(self.error))) if self.output.size else 0.0

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times (s)."""
        if self._time is None:
            self._time = np.arange(self.output.size, dtype=np.float64) * float(self.sample_time)
        return cast(NDArray[np.float64], self._time)

    def __iter__(self) -> Iterator[NDArray[np.float64]]:
        yield self.time
        yield self.input

    def __len__(self) -> int:
        return len(self.input)


def _table(model: PreisachModel, nonmonotone: str) -> _core.EverettTable:
    if nonmonotone not in _NONMONOTONE:
        raise ValueError(f"nonmonotone: expected 'as_is' or 'project', got {nonmonotone!r}")
    table = model._table
    if nonmonotone == "project" and np.any(model.cell_weights() < 0):
        table = _core.project_nonnegative(table).table.with_interpolation(table.interpolation)
    if table.interpolation == "cubic":  # the closed-form roots are those of a bilinear table
        lv = np.asarray(table.levels)
        f = np.arange(CUBIC_REFINE) / CUBIC_REFINE
        fine = np.append((lv[:-1, None] + np.diff(lv)[:, None] * f).ravel(), lv[-1])
        table = table.resample(fine, "bilinear")
    return table


def inverter(
    model: PreisachModel, state: State | None = None, *, nonmonotone: str = "as_is"
) -> _core.Inverter:
    """Target-by-target inverse for a real-time loop.

    Parameters
    ----------
    model : PreisachModel
        The model to invert.
    state : State, optional
        Initial boundary; default the anhysteretic state.
    nonmonotone : {"as_is", "project"}
        How a model with negative cells is inverted (see the module docstring).

    Returns
    -------
    preisach._core.Inverter
        ``step(y)`` drives the output to ``y`` (V) and returns the input (V); ``solve(y)``
        gives ``(u, reached)`` without applying it; ``output``, ``input``, ``state``,
        ``unreachable`` (count so far), ``reset(state)``.  Non-finite targets raise
        :class:`ValueError`.

    """
    s0 = model.anhysteretic_state() if state is None else state
    return _core.Inverter(_table(model, nonmonotone), s0)


def invert(
    model: PreisachModel,
    y_ref: ArrayLike,
    state: State | None = None,
    t: ArrayLike | None = None,
    *,
    sample_time: float = 1e-3,
    nonmonotone: str = "as_is",
) -> InverseResult:
    """Input that makes the model's output follow ``y_ref`` (exact inverse).

    Parameters
    ----------
    model : PreisachModel
        The model to invert.
    y_ref : array_like, shape (n,)
        Target outputs (V), finite real numbers (a NaN or inf raises :class:`ValueError`
        naming the sample before anything runs).
    state : State, optional
        Initial boundary; default the anhysteretic state (as :meth:`PreisachModel.simulate`).
        The first target is reached from ``state``: sample ``k`` of the input gives sample
        ``k`` of the output, with no delay.
    t : array_like, optional
        Sample times (s), kept in the result.
    sample_time : float
        Sampling period (s) when ``t`` is not given.
    nonmonotone : {"as_is", "project"}
        How a model with negative cells is inverted (see the module docstring).

    Returns
    -------
    InverseResult

    """
    from ..model import _check_times, _real_array

    y = _real_array("y_ref", y_ref)
    if y.ndim != 1:
        raise ValueError(f"y_ref: expected a 1-D array of target outputs, got shape {y.shape}")
    tt = None
    if t is not None:
        tt = _real_array("t", t)
        if tt.shape != y.shape:
            raise ValueError(f"t: shape {tt.shape} does not match y_ref {y.shape}")
        _check_times(tt)
    if not sample_time > 0:
        raise ValueError(f"sample_time: must be positive, got {sample_time}")
    s0 = model.anhysteretic_state() if state is None else state
    table = _table(model, nonmonotone)
    u, y_out, reached, final, _ = _core.invert(table, y, s0)
    extra: dict[str, Any] = {"nonmonotone": nonmonotone}
    if table is not model._table:  # projected or resampled: report the given model's outputs
        y_out, final = _core.simulate(model._table, u, s0, "clamp")
        if nonmonotone == "project" and np.any(model.cell_weights() < 0):
            extra["projected"] = True
    return InverseResult(y, u, y_out, reached, s0, final, float(sample_time), extra, _time=tt)
