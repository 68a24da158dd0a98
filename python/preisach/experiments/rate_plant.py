"""A rate-dependent Preisach model as a plant of the regulation experiments.

:class:`RatePlant` implements the :class:`~preisach.experiments.Plant` protocol (and the
batched runs of :class:`~preisach.experiments.ModelPlant`; both are
:class:`~preisach.experiments.plant.SimulatedPlant`) for a
:class:`~preisach.rate_model.RateDependentPreisachModel`, alone or with the physics blocks the
classical model leaves out (:mod:`preisach.daq.blocks`: amplifier lag, structural mode, creep,
delay, ...) before and after it, as the virtual rig chains them::

    input blocks -> rate-dependent Preisach model -> output blocks

so rate dependence combines with the other left-out physics in one plant.  Without blocks its
snapshots are :class:`~preisach.rate_model.RateState` (boundary and filtered rate) and the
batched runs are parallel in C++; with blocks a snapshot is a copy of the whole chain (every
block's state), restored exactly, and every run is still C++ (the PI loop included).
:func:`~preisach.experiments.drive_to_state` finds ``l`` for psi_n from the neutral locus of
the model at rest (its ``table``), then corrects it on the plant, as for any plant whose output
depends on more than the boundary.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..daq.blocks import RigBlock
from ..daq.device import _as_blocks
from ..model import Slopes, State
from ..rate_model import RateDependentPreisachModel, RateState, _as_rate_state
from .plant import PIConfig, SimulatedPlant

__all__ = ["ChainSnapshot", "RatePlant"]

BlockSpec = Union[RigBlock, Mapping[str, Any]]


class ChainSnapshot(NamedTuple):
    """Exact state of a :class:`RatePlant` with blocks: a copy of its chain and its output (V)."""

    chain: _core.BlockChain
    output: float


class RatePlant(SimulatedPlant):
    """A rate-dependent model, optionally with physics blocks, as a plant simulated in C++.

    Parameters
    ----------
    model : RateDependentPreisachModel
        The model (input V, output V).
    sample_time : float, default 1e-3
        Sampling period (s); also the ``dt`` of the model's rate ``|du|/dt`` and of the blocks.
    input_blocks, output_blocks : sequence of blocks or mappings, optional
        Physics blocks before and after the model (:class:`~preisach.daq.blocks.RigBlock` made
        for ``sample_time``, or ``{"kind": ..., **params}`` as in
        :func:`~preisach.daq.blocks.make_block`).  The plant's input is clamped to the model
        range before the input blocks (the amplifier saturates), so ``out_of_range`` must be
        ``"clamp"`` with blocks.
    threads : int, default 0
        Worker threads of the batched runs; 0 uses every core.
    out_of_range : {"clamp", "raise"}, optional
        Policy for inputs outside the model range; default the model's.

    """

    _model_type = RateDependentPreisachModel
    model: RateDependentPreisachModel

    def __init__(
        self,
        model: RateDependentPreisachModel,
        sample_time: float = 1e-3,
        *,
        input_blocks: Sequence[BlockSpec] = (),
        output_blocks: Sequence[BlockSpec] = (),
        threads: int = 0,
        out_of_range: str | None = None,
    ) -> None:
        self._specs = (tuple(input_blocks), tuple(output_blocks))
        super().__init__(model, sample_time, threads=threads, out_of_range=out_of_range)
        if self.has_blocks and self.out_of_range != "clamp":
            raise ValueError(
                "out_of_range: with physics blocks the input saturates; use 'clamp', got "
                f"{self.out_of_range!r}"
            )

    def __getstate__(self) -> dict[str, Any]:
        # The C++ simulator or chain does not pickle (studies ship plants to worker
        # processes): without blocks the exact boundary and rate go instead; with blocks (given
        # as mappings) the model's boundary and rate, and the blocks restart in the steady
        # state of its input (every experiment starts with a saturating waveform anyway).
        specs = (*self._specs[0], *self._specs[1])
        if not all(isinstance(b, Mapping) for b in specs):
            raise TypeError("RatePlant: pickling needs the blocks as {'kind': ...} mappings")
        d = self.__dict__.copy()
        d["_sim"] = (
            RateState(self._sim[len(self._specs[0])].state, self.rate)
            if self.has_blocks
            else self.snapshot()
        )
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        state = d.pop("_sim")
        self.__dict__.update(d)
        self._sim = self._new_simulator()
        self.reset(state)

    @property
    def has_blocks(self) -> bool:
        """Whether physics blocks surround the model (runs go through a block chain)."""
        return bool(self._specs[0] or self._specs[1])

    def _chain(self, state: RateState) -> _core.BlockChain:
        dt = self._ts
        ins, outs = (_as_blocks(b, dt) for b in self._specs)
        stage = _core.RateStage(dt, self.model.core, state.boundary, state.rate)
        chain = _core.BlockChain([*ins, stage, *outs])
        self._y = float(chain.reset(state.input))
        return chain

    def _new_simulator(self) -> Any:
        st = self.model.anhysteretic_state()
        if self.has_blocks:
            return self._chain(st)
        return self.model.simulator(st, sample_time=self._ts)

    @property
    def output(self) -> float:
        """Current output (V)."""
        return self._y if self.has_blocks else float(self._sim.output)

    @property
    def rate(self) -> float:
        """Current filtered input rate (V/s)."""
        if self.has_blocks:
            return float(self._sim[len(self._specs[0])].rate)
        return float(self._sim.rate)

    def reset(self, state: RateState | State | ChainSnapshot | None = None) -> None:
        """Set the state: a snapshot, or a boundary and rate (default anhysteretic at rest).

        With blocks, a :class:`~preisach.rate_model.RateState` or bare
        :class:`~preisach.State` (at rest) restarts the chain from it with every block in
        the steady state of the state's input.
        """
        if isinstance(state, ChainSnapshot):
            if not self.has_blocks:
                raise TypeError("state: a chain snapshot restores a RatePlant with blocks only")
            self._sim = state.chain.copy()
            self._y = float(state.output)
            return
        st = _as_rate_state(state, self.model.anhysteretic_state())
        if self.has_blocks:
            self._sim = self._chain(st)
        else:
            self._sim.reset(st.boundary, st.rate)

    def snapshot(self) -> RateState | ChainSnapshot:
        """Return the exact current state: boundary and rate, with blocks a copy of the chain."""
        if self.has_blocks:
            return ChainSnapshot(self._sim.copy(), self._y)
        return RateState(self._sim.state, float(self._sim.rate))

    def slopes(self) -> Slopes:
        """One-sided dy/du (V/V) at the current state, the rate held (no blocks only)."""
        if self.has_blocks:
            raise ValueError("slopes: not defined for a plant with physics blocks")
        return super().slopes()

    def run_open_loop(self, u: ArrayLike) -> NDArray[np.float64]:
        """Apply ``u`` (V) from the current state; return the outputs (V)."""
        if not self.has_blocks:
            return super().run_open_loop(u)
        uu = np.ascontiguousarray(u, dtype=float)
        if uu.ndim != 1:
            raise ValueError(f"u: expected a 1-D array of input samples, got shape {uu.shape}")
        if not np.all(np.isfinite(uu)):
            raise ValueError("u: input samples must be finite")
        y = np.asarray(self._sim.run(np.clip(uu, *self.input_range)))
        if y.size:
            self._y = float(y[-1])
        return y

    def _closed_loop(
        self, u_open: NDArray[np.float64], controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        if self.has_blocks:
            lo, hi = self.input_range
            u, y, uc = _core.closed_loop_chain(
                self._sim, u_open, lo, hi, **controller.core_kwargs()
            )
            if y.size:
                self._y = float(y[-1])
            return u, y, uc
        return _core.closed_loop_rate(
            self._sim, u_open, out_of_range=self.out_of_range, **controller.core_kwargs()
        )

    def run_open_loop_batch(
        self, state: RateState | State | ChainSnapshot, u: ArrayLike
    ) -> NDArray[np.float64]:
        """Every row of ``u`` (V) from ``state``; returns the outputs (V).

        Without blocks the rows run on all cores; with blocks one after the other.
        """
        if self.has_blocks:
            U = np.atleast_2d(np.asarray(u, dtype=float))
            out = np.empty_like(U)
            for r in range(U.shape[0]):
                self.reset(state)
                out[r] = self.run_open_loop(U[r])
            return out
        y, _ = self.model.simulate_batch(
            u,
            _as_rate_state(state, self.model.anhysteretic_state()),  # type: ignore[arg-type]
            sample_time=self._ts,
            threads=self.threads,
            out_of_range=self.out_of_range,
        )
        return y

    def run_closed_loop_batch(
        self, state: RateState | State | ChainSnapshot, u_open: ArrayLike, controller: PIConfig
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Run the PI loop for every row of ``u_open`` (V) from ``state``.

        Without blocks the rows run on all cores; with blocks one after the other.
        """
        uu = self._rows(u_open, controller)
        if self.has_blocks:
            outs = []
            for r in range(uu.shape[0]):
                self.reset(state)
                outs.append(self._closed_loop(uu[r], controller))
            return tuple(np.stack([o[i] for o in outs]) for i in range(3))  # type: ignore[return-value]
        st = _as_rate_state(state, self.model.anhysteretic_state())  # type: ignore[arg-type]
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
