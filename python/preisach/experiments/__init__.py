"""The regulation experiments of the thesis (chapters 4-5), on a model or on a rig.

* :mod:`~preisach.experiments.plant` - the :class:`Plant` interface and the model-backed
  :class:`ModelPlant` (the DAQ layer provides a rig-backed plant with the same methods);
* :mod:`~preisach.experiments.initialisation` - inputs that drive a plant to psi_n, psi_a, psi_d
  (Eq 4.1-4.4) and :func:`drive_to_state`, which finds their offsets;
* :mod:`~preisach.experiments.protocol` - timing, noise and the metrics (drift, ``n_c``);
* :mod:`~preisach.experiments.drift` - the open-loop drift test (§4.2);
* :mod:`~preisach.experiments.closed_loop` - the closed-loop PI test (§5.1), loop in C++;
* :mod:`~preisach.experiments.sweep` - sweeps over frequencies, states, gains and seeds, with
  the thesis's tables and figures.

Example:
-------
>>> from preisach.experiments import ss15_plants, drive_to_state, drift_test
>>> plant = ss15_plants()[1.0]
>>> init = drive_to_state(plant, "a", y_d=1.0, frequency=1.0)
>>> res = drift_test(plant, init, gain=1.6, seed=0)
>>> res.drift > 0   # psi_a drifts up
True

"""

from __future__ import annotations

from .closed_loop import ClosedLoopResult, closed_loop_test, closed_loop_trials
from .drift import DriftResult, drift_test, drift_trials
from .initialisation import (
    HOLD_BAND,
    HOLD_DURATION,
    KINDS,
    SIMULATION_TOLERANCE,
    TABLE_4_1,
    HoldWindowError,
    HoldWindowWarning,
    Initialisation,
    Waveform,
    branch_input,
    default_thresholds,
    drive_to_state,
    landing_window,
    measure_locus,
    neutral_input,
)
from .plant import SS15_INPUT_GAIN, ModelPlant, PIConfig, Plant, ss15_plants, thesis_sample_time
from .protocol import (
    THESIS_GAINS,
    ClosedLoopProtocol,
    DriftProtocol,
    control_effort,
    differential_drift,
    trial_noise,
)
from .rate_plant import RatePlant
from .sweep import EXPERIMENTS, SweepResult, regulation_sweep, state_slopes

__all__ = [
    "EXPERIMENTS",
    "HOLD_BAND",
    "HOLD_DURATION",
    "KINDS",
    "SIMULATION_TOLERANCE",
    "SS15_INPUT_GAIN",
    "TABLE_4_1",
    "THESIS_GAINS",
    "ClosedLoopProtocol",
    "ClosedLoopResult",
    "DriftProtocol",
    "DriftResult",
    "HoldWindowError",
    "HoldWindowWarning",
    "Initialisation",
    "ModelPlant",
    "PIConfig",
    "Plant",
    "RatePlant",
    "SweepResult",
    "Waveform",
    "branch_input",
    "closed_loop_test",
    "closed_loop_trials",
    "control_effort",
    "default_thresholds",
    "differential_drift",
    "drift_test",
    "drift_trials",
    "drive_to_state",
    "landing_window",
    "measure_locus",
    "neutral_input",
    "regulation_sweep",
    "ss15_plants",
    "state_slopes",
    "thesis_sample_time",
    "trial_noise",
]
