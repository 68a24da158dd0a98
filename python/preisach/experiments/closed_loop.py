"""Closed-loop PI regulation test (thesis §5.1-5.2): the control effort spent against noise.

From an initial state the offset is held; at ``t_1 + 1`` s the discrete PI controller of
Eq 5.2 starts (the loop runs in C++, :func:`preisach._core.closed_loop`), noise scaled by
``K_n`` is added from ``t_1 + 2`` to ``t_1 + 10`` s and the trial ends at ``t_1 + 12`` s.  The
control effort ``n_c = ||u_cn - ubar_c||_2`` (Eq 5.3) counts only what the controller does
against the noise (:func:`preisach.experiments.protocol.control_effort`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .initialisation import Initialisation, paired_trials
from .plant import Plant
from .protocol import ClosedLoopProtocol, ExperimentResult, control_effort, window_mean

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["ClosedLoopResult", "closed_loop_test", "closed_loop_trials"]


@dataclass
class ClosedLoopResult(ExperimentResult):
    """One closed-loop trial.

    Attributes
    ----------
    kind, frequency, gain, seed, sample_time, offset
        As in :class:`~preisach.experiments.protocol.ExperimentResult`.
    setpoint : float
        ``y_d`` (V).
    nc : float
        Control effort ``||u_cn - ubar_c||_2`` over the samples (controller units, Eq 5.3).
    nc_l2 : float
        ``nc * sqrt(sample_time)``: the L2 norm of the signal (units * s^0.5), comparable
        across sample times.
    uc_baseline : float
        ``ubar_c`` (controller units).
    error_rms : float
        RMS of ``y_d - y`` during the effort window (V).
    error_final : float
        Mean of ``y_d - y`` over the last second (V).
    input, output, control : ndarray or None
        Applied input (V), output (V), controller output (controller units) from ``t_1``;
        ``None`` when a sweep did not keep the trace.

    """

    setpoint: float
    nc: float
    nc_l2: float
    uc_baseline: float
    error_rms: float
    error_final: float
    input: NDArray[np.float64] | None = field(default=None, repr=False)
    output: NDArray[np.float64] | None = field(default=None, repr=False)
    control: NDArray[np.float64] | None = field(default=None, repr=False)

    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Output, controller output and input against time after ``t_1``.

        Drawn by :func:`preisach.plotting.plot_closed_loop_trial`.
        """
        from ..plotting.experiments import plot_closed_loop_trial

        return plot_closed_loop_trial(self, fig=fig)


def closed_loop_trials(
    plant: Plant,
    init: Initialisation,
    gains: Sequence[float],
    seeds: Sequence[int],
    protocol: ClosedLoopProtocol | None = None,
    *,
    keep_traces: bool = True,
) -> list[ClosedLoopResult]:
    """Closed-loop trials from one initial state for paired lists of gains and seeds.

    On a plant with snapshots and ``run_closed_loop_batch`` (:class:`ModelPlant`) all trials
    run in one C++ call on every core with the GIL released; otherwise each trial resets the
    plant and runs the initialisation waveform and the test segment as **one**
    ``run_closed_loop`` (the controller's ``enable_at`` shifted by the waveform's length, so it
    still starts ``controller_on`` seconds after ``t_1``), and keeps the samples from ``t_1`` on.
    On a DAQ device (:class:`preisach.daq.DevicePlant`) that is one continuous, recorded trial:
    no pause at ``t_1`` between two device runs with the output held at the last
    initialisation sample.

    Parameters
    ----------
    plant : Plant
        Where the output comes from.
    init : Initialisation
        From :func:`drive_to_state` on the same plant; its ``y_d`` is the setpoint.
    gains, seeds : sequence
        ``K_n`` and noise seed of each trial (same length).
    protocol : ClosedLoopProtocol, optional
        Controller, timing and noise (thesis defaults: K_p = 1.5, K_i = 30).
    keep_traces : bool
        Keep the arrays in the results.

    Returns
    -------
    list of ClosedLoopResult

    """
    p = ClosedLoopProtocol() if protocol is None else protocol
    gains, seeds, ts = paired_trials(plant, init, gains, seeds)
    cfg = p.pi_config(init.y_d, ts)
    U_open = p.open_inputs(init.offset, gains, seeds, ts)
    batch = getattr(plant, "run_closed_loop_batch", None)
    if init.state is not None and batch is not None:
        U, Y, UC = (np.asarray(a) for a in batch(init.state, U_open, cfg))
    else:
        lead = np.asarray(init.waveform.input, dtype=float)
        n0 = lead.size
        cfg_run = dataclasses.replace(cfg, enable_at=cfg.enable_at + n0)
        U, Y, UC = (np.empty_like(U_open) for _ in range(3))
        for r in range(len(U_open)):
            plant.reset(None)
            u, y, uc = plant.run_closed_loop(np.concatenate([lead, U_open[r]]), cfg_run)
            U[r], Y[r], UC[r] = (np.asarray(a)[n0:] for a in (u, y, uc))
    out = []
    last = (max(0.0, p.end - 1.0), p.end)
    for r, (g, s) in enumerate(zip(gains, seeds)):
        nc, ubar = control_effort(UC[r], ts, p.effort, p.baseline)
        i0, i1 = int(round(p.effort[0] / ts)), int(round(p.effort[1] / ts))
        err = init.y_d - Y[r]
        out.append(
            ClosedLoopResult(
                init.kind,
                init.frequency,
                g,
                s,
                ts,
                init.offset,
                init.y_d,
                nc,
                nc * math.sqrt(ts),
                ubar,
                float(np.sqrt(np.mean(err[i0:i1] ** 2))),
                window_mean(err, ts, last),
                U[r] if keep_traces else None,
                Y[r] if keep_traces else None,
                UC[r] if keep_traces else None,
            )
        )
    return out


def closed_loop_test(
    plant: Plant,
    init: Initialisation,
    gain: float,
    seed: int,
    protocol: ClosedLoopProtocol | None = None,
) -> ClosedLoopResult:
    """One closed-loop PI trial (§5.1 steps 2-5) from an initial state; keeps the trace.

    Parameters
    ----------
    plant : Plant
        Where the output comes from.
    init : Initialisation
        Initial state reached on this plant; ``init.y_d`` is the setpoint.
    gain : float
        Noise gain ``K_n``.
    seed : int
        Noise seed.
    protocol : ClosedLoopProtocol, optional
        Controller, timing and noise; thesis defaults.

    Returns
    -------
    ClosedLoopResult

    """
    return closed_loop_trials(plant, init, [gain], [seed], protocol)[0]
