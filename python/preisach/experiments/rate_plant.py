"""A rate-dependent Preisach model as a plant of the regulation experiments.

:class:`RatePlant` implements the :class:`~preisach.experiments.Plant` protocol (and the
batched runs of :class:`~preisach.experiments.ModelPlant`) for a
:class:`~preisach.rate_model.RateDependentPreisachModel`: its snapshots are
:class:`~preisach.rate_model.RateState` (boundary and filtered rate), restored exactly, and
its loops run in C++ with the GIL released.  :func:`~preisach.experiments.drive_to_state` finds
``l`` for psi_n from the neutral locus of the model at rest (its ``table``), then corrects it on
the plant, as for any plant whose output depends on more than the boundary.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..model import Slopes, State
from ..rate_model import RateDependentPreisachModel, RateState, _as_rate_state
from .plant import PIConfig

__all__ = ["RatePlant"]


class RatePlant:
    """A rate-dependent model as a plant: every run is simulated in C++.

    Parameters
    ----------
    model : RateDependentPreisachModel
        The model (input V, output V).
    sample_time : float, default 1e-3
        Sampling period (s); also the ``dt`` of the model's rate ``|du|/dt``.
    threads : int, default 0
        Worker threads of the batched runs; 0 uses every core.
    out_of_range : {"clamp", "raise"}, optional
        Policy for inputs outside the model range; default the model's.

    """

    def __init__(
        self,
        model: RateDependentPreisachModel,
        sample_time: float = 1e-3,
        *,
        threads: int = 0,
        out_of_range: str | None = None,
    ) -> None:
        if not isinstance(model, RateDependentPreisachModel):
            raise TypeError(
                f"model: expected a RateDependentPreisachModel, got {type(model).__name__}"
            )
        if not (math.isfinite(sample_time) and sample_time > 0):
            raise ValueError(f"sample_time: must be positive (s), got {sample_time!r}")
        if threads < 0:
            raise ValueError(f"threads: must be >= 0, got {threads}")
        self.model = model
        self._ts = float(sample_time)
        self.threads = int(threads)
        self.out_of_range = model.out_of_range if out_of_range is None else out_of_range
        if self.out_of_range not in ("clamp", "raise"):
            raise ValueError(
                f"out_of_range: expected 'clamp' or 'raise', got {self.out_of_range!r}"
            )
        self._sim = model.simulator(model.anhysteretic_state(), sample_time=self._ts)

    def __repr__(self) -> str:
        return f"RatePlant({self.model!r}, sample_time={self._ts:g})"

    @property
    def sample_time(self) -> float:
        """Sampling period (s)."""
        return self._ts

    @property
    def input_range(self) -> tuple[float, float]:
        """``(u_min, u_max)`` of the model (V)."""
        return (self.model.u_min, self.model.u_max)

    @property
    def output(self) -> float:
        """Current output (V)."""
        return float(self._sim.output)

    @property
    def rate(self) -> float:
        """Current filtered input rate (V/s)."""
        return float(self._sim.rate)

    def reset(self, state: RateState | State | None = None) -> None:
        """Set the state (default: anhysteretic at rest; a bare State is at rest)."""
        st = _as_rate_state(state, self.model.anhysteretic_state())
        self._sim.reset(st.boundary, st.rate)

    def snapshot(self) -> RateState:
        """Return the current boundary and filtered rate (exact)."""
        return RateState(self._sim.state, float(self._sim.rate))

    def slopes(self) -> Slopes:
        """One-sided dy/du (V/V) at the current state, the rate held."""
        return Slopes(*self._sim.slopes())

    def run_open_loop(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply ``u`` (V) from the current state; return the outputs (V)."""
        uu = np.ascontiguousarray(u, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u: expected a 1-D array of input samples, got shape {uu.shape}")
        return self._sim.run(uu, self.out_of_range)

    def _check(self, controller: PIConfig) -> None:
        if not isinstance(controller, PIConfig):
            raise TypeError(f"controller: expected a PIConfig, got {type(controller).__name__}")
        if not math.isclose(controller.sample_time, self._ts, rel_tol=1e-9):
            raise ValueError(
                f"controller.sample_time = {controller.sample_time:g} s differs from the "
                f"plant's sample_time {self._ts:g} s"
            )

    def run_closed_loop(
        self, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop (in C++, GIL released) from the current state; see :class:`PIConfig`."""
        self._check(controller)
        uu = np.ascontiguousarray(u_open, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u_open: expected a 1-D array, got shape {uu.shape}")
        u, y, uc = _core.closed_loop_rate(
            self._sim, uu, out_of_range=self.out_of_range, **controller.core_kwargs()
        )
        return u, y, uc

    def run_open_loop_batch(self, state: RateState | State, u: ArrayLike) -> NDArray[np.float64]:
        """Every row of ``u`` (V) from ``state`` on all cores; returns the outputs (V)."""
        y, _ = self.model.simulate_batch(
            u, state, sample_time=self._ts, threads=self.threads, out_of_range=self.out_of_range
        )
        return y

    def run_closed_loop_batch(
        self, state: RateState | State, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop for every row of ``u_open`` (V) from ``state``, on all cores."""
        self._check(controller)
        st = _as_rate_state(state, self.model.anhysteretic_state())
        uu = np.ascontiguousarray(u_open, dtype=float)
        if uu.ndim != 2:
            raise ValueError(f"u_open: expected a 2-D array (runs, samples), got shape {uu.shape}")
        u, y, uc, _, _ = _core.closed_loop_rate_batch(
            self.model.core,
            [st.boundary],
            [st.rate],
            uu,
            out_of_range=self.out_of_range,
            threads=self.threads,
            **controller.core_kwargs(),
        )
        return u, y, uc
