"""Open-loop drift test (thesis §4.2-4.3): how far the output wanders under input noise.

From an initial state (psi_n, psi_a or psi_d, all with output ``y_d``) the offset is held for
2 s, then 8 s of zero-mean noise scaled by ``K_n`` is added to it.  The differential drift
``ybar(8, 10) - ybar(0, 2)`` measures the net output change the noise leaves behind
(:func:`preisach.experiments.protocol.differential_drift`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .initialisation import Initialisation, paired_trials
from .plant import Plant
from .protocol import DriftProtocol, ExperimentResult, differential_drift

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["DriftResult", "drift_test", "drift_trials"]


@dataclass
class DriftResult(ExperimentResult):
    """One open-loop drift trial.

    The fields of :class:`~preisach.experiments.protocol.ExperimentResult` (state, frequency, gain,
    seed, sample time, offset), and:

    Attributes
    ----------
    drift : float
        ``ybar_after - ybar_before`` (V).
    ybar_before, ybar_after : float
        Mean outputs over the protocol's windows (V).
    input, output : ndarray or None
        Test segment from ``t_1`` (V); ``None`` when a sweep did not keep the trace.

    """

    drift: float
    ybar_before: float
    ybar_after: float
    input: NDArray[np.float64] | None = field(default=None, repr=False)
    output: NDArray[np.float64] | None = field(default=None, repr=False)

    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Input and output against time after ``t_1``, averaging windows marked.

        Drawn by :func:`preisach.plotting.plot_drift_trial`.
        """
        from ..plotting.experiments import plot_drift_trial

        return plot_drift_trial(self, fig=fig)


def drift_trials(
    plant: Plant,
    init: Initialisation,
    gains: Sequence[float],
    seeds: Sequence[int],
    protocol: DriftProtocol | None = None,
    *,
    keep_traces: bool = True,
) -> list[DriftResult]:
    """Drift trials from one initial state for paired lists of gains and seeds.

    On a plant that can restore a snapshot and run batches (:class:`ModelPlant`) all trials
    run in one call from ``init.state`` on every core; otherwise each trial resets the plant and
    plays the initialisation waveform and the test segment as **one** run, whose outputs from
    ``t_1`` on are the result.  On a DAQ device (:class:`preisach.daq.DevicePlant`) that is one
    continuous, recorded trial: no pause between two device runs at ``t_1``, during which the
    output would sit at the last initialisation sample unrecorded.

    Parameters
    ----------
    plant : Plant
        Where the output comes from.
    init : Initialisation
        From :func:`drive_to_state` on the same plant.
    gains, seeds : sequence
        ``K_n`` and noise seed of each trial (same length).
    protocol : DriftProtocol, optional
        Timing and noise (thesis defaults).
    keep_traces : bool
        Keep input and output arrays in the results.

    Returns
    -------
    list of DriftResult

    """
    p = DriftProtocol() if protocol is None else protocol
    gains, seeds, ts = paired_trials(plant, init, gains, seeds)
    U = p.open_inputs(init.offset, gains, seeds, ts)
    batch = getattr(plant, "run_open_loop_batch", None)
    if init.state is not None and batch is not None:
        Y = np.asarray(batch(init.state, U))
    else:
        lead = np.asarray(init.waveform.input, dtype=float)
        n0 = lead.size
        Y = np.empty_like(U)
        for r in range(len(U)):
            plant.reset(None)
            Y[r] = np.asarray(plant.run_open_loop(np.concatenate([lead, U[r]])))[n0:]
    out = []
    for r, (g, s) in enumerate(zip(gains, seeds)):
        d, yb, ya = differential_drift(Y[r], ts, p.before, p.after)
        out.append(
            DriftResult(
                init.kind,
                init.frequency,
                g,
                s,
                ts,
                init.offset,
                d,
                yb,
                ya,
                U[r] if keep_traces else None,
                Y[r] if keep_traces else None,
            )
        )
    return out


def drift_test(
    plant: Plant,
    init: Initialisation,
    gain: float,
    seed: int,
    protocol: DriftProtocol | None = None,
) -> DriftResult:
    """One open-loop drift trial (§4.2 steps 4-6) from an initial state; keeps the trace.

    Parameters
    ----------
    plant : Plant
        Where the output comes from.
    init : Initialisation
        Initial state reached on this plant (:func:`drive_to_state`).
    gain : float
        Noise gain ``K_n`` (thesis: 0.8 i, i = 1..7).
    seed : int
        Noise seed.
    protocol : DriftProtocol, optional
        Timing and noise; thesis defaults.

    Returns
    -------
    DriftResult

    """
    return drift_trials(plant, init, [gain], [seed], protocol)[0]
