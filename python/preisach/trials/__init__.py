"""Scripted rig trials: a TOML file names the device, channels, limits and steps; run it.

The same file runs on the virtual SS15 (``kind = "sim"``, as fast as it can, or paced with
``--realtime``) and on a Comedi card (``kind = "comedi"``, always paced)::

    preisach trial check examples/trials/fod_sweep.toml
    preisach trial run examples/trials/fod_sweep.toml -o out/           # virtual rig
    preisach trial run FILE --device comedi:/dev/comedi0 -o out/         # the real rig

Every step writes its own recording ``NN_<name>.csv`` (the format of
:mod:`preisach.recording`, with the step's parameters in the metadata) and the run writes
``summary.json``.  Steps run back to back on the same device: the state one step leaves is the
state the next starts from, and the recordings' time axis continues from step to step.  After
the last step, or when a step aborts, the output is ramped to 0 V.  When the run stops between
steps (Ctrl-C, an error while planning a step) the output is ramped from its last value to 0 V
at ``ramp_rate`` in a recorded run ``NN_ramp.csv`` before the exception propagates, and
``summary.json`` says ``interrupted`` or ``aborted: <ExcType: message>``.

File layout
-----------
.. code-block:: toml

    [trial]
    name = "fod-sweep-1hz"      # optional; default the file name
    description = "..."          # optional
    sample_time = 0.001          # s

    [device]
    kind = "sim"                 # "sim" (virtual SS15) or "comedi"
    # comedi:  file = "/dev/comedi0", calibration_file = "" (softcal file, optional)
    # sim:     model = "ss15-1hz" (built-in name or a saved model .npz), state = "anhysteretic"
    #          ("negative_saturation", "positive_saturation"), seed, adc_noise (V rms),
    #          adc_bits, dac_bits, moving_gain (V/V), input_blocks / output_blocks
    #          (arrays of {kind = ..., params...}, see preisach.daq.blocks)

    [output]                     # the actuator channel (DAC -> amplifier)
    name = "V_in"
    channel = 1
    range = [-10.0, 10.0]        # connector V
    calibration = "ss15-b"       # "ss15-a", "ss15-b" (Eq B.1a/b) or "identity";
                                 # or gain = -14.12 and offset = -0.02
    # subdevice = -1, aref = 0 (Comedi)

    [input]                      # the primary measured channel (column y)
    name = "V_out"
    channel = 1
    range = [-5.0, 5.0]
    calibration = "identity"

    [safety]
    u_limits = [-135.0, 135.0]   # V at the actuator (the SA11 gives +/-135 V)
    slew_rate = 10000.0          # V/s
    ramp_rate = 500.0            # V/s, ramp to 0 V on abort and at the end (<= slew_rate)
    approach_rate = 200.0        # V/s, ramp from the current output to a step's first value
    y_limits = [-4.9, 4.9]       # V, primary input; outside aborts
    max_missed_deadlines = -1    # abort beyond this many missed deadlines in total (< 0: never)
    max_consecutive_missed = 20  # ... or beyond this many in a row (a stall)

    [[steps]]                    # one table per step, run in order
    kind = "initialise"
    ...

Step kinds (all voltages at the actuator, V; times in s; frequencies in Hz):

``initialise``
    The decaying sinusoid of section 3.2 toward the anhysteretic state:
    ``duration`` (12), ``frequency`` (1), ``amplitude`` (100).
``fod_sweep``
    The identification input of Fig 3.17: ``frequency`` (1), ``levels`` (21), ``u_min``
    (-100), ``u_max`` (100), ``shape`` ("cosine" or "triangle"), ``order`` ("descending").
``wiping_out``
    The wiping-out test of Fig 3.6: ``frequency``, ``peaks`` ([100, 72, 44]), ``trough``
    (-40), ``u_min`` (-100), ``shape``.
``cml``
    The congruent-minor-loop test of Fig 3.13: ``frequency``, ``loop`` ([0, 50]), ``peak``
    (100), ``u_min`` (-100), ``shape``.
``drive``
    Drive to ``target`` = "psi_n" (Eq 4.1/4.2), "psi_a" (Eq 4.3) or "psi_d" (Eq 4.4) and hold
    the offset for ``hold`` (2) s: ``frequency`` (1), ``cycles`` (10, psi_n), ``u_hat``
    (default the model's saturation).  The offset is ``offset`` if given, else computed from
    ``y_d`` (V) on a model - ``model`` of the step, else the virtual rig's model - with
    :func:`preisach.experiments.drive_to_state` (psi_n: ``l = N_inv(y_d)``; psi_a/psi_d: the
    offset whose output lands within ``tolerance`` (0.03 V) of ``y_d``).
``noise``
    Open-loop noise injection (section 4.2): the held output plus ``gain`` times the noise of
    :func:`preisach.noise.uniform_filtered_noise` (``amplitude`` 0.5, ``cutoff`` 15 Hz,
    ``hold_time`` 0.015 s, ``seed``) scaled by ``input_gain`` (14.12 actuator V per noise
    unit: the thesis states the noise at the DAQ connector), for ``duration`` (8) s, after
    ``hold_before`` (2) s and followed by ``hold_after`` (0) s of the held value.  ``offset``:
    the held value (default the output the previous step left).
``pi``
    Closed-loop PI regulation (section 5.1): ``setpoint`` (1 V), ``kp`` (1.5), ``ki`` (30) in
    controller units scaled by ``input_gain`` (14.12), ``duration`` (12), ``enable_after`` (1),
    ``average`` (0.025 s of error averaging), noise ``noise_gain`` (0: none) from
    ``noise_from`` (2) to ``noise_to`` (10) with ``amplitude``, ``seed``, ``offset`` as above.
``hold``
    Hold ``value`` (default the current output) for ``duration`` s.
``track``
    Feedforward: ``feedforward`` (a model file or built-in name), ``reference`` (a CSV with
    ``t,y``: the desired output, V, sampled at the trial's sample time), ``state``
    ("negative" or "positive"): ramp to that saturation, hold 0.1 s, then play the model's exact
    inverse for the reference (:mod:`preisach.compensate`), under the same safety limits.

Every step also takes ``name`` (used in its file name).  :func:`check_trial` validates a
file without running it and reports every problem at once: unknown keys (with a suggestion),
wrong types, missing sections and channels, limits beyond the hardware, and planned waveforms
that exceed the safety limits or the output channel's range.

The package: :mod:`.schema` (the file format: sections, keys, defaults, parsing),
:mod:`.plan` (each step's waveform, :func:`check_trial`), :mod:`.run` (running a file on a
device, the safety ramp, ``summary.json``) and :mod:`.cli` (``preisach trial``).
"""

from __future__ import annotations

from ..daq.calibration import SS15_INPUT_GAIN
from .cli import _main as _main  # python -m preisach.trials
from .cli import _ProgressBar as _ProgressBar
from .cli import add_parser
from .plan import check_trial, step_waveform
from .run import StepOutcome, TrialOutcome, run_trial_file
from .schema import (
    AMPLIFIER_LIMIT,
    STEP_KINDS,
    PlannedStep,
    TrialPlan,
    load_trial,
)

__all__ = [
    "AMPLIFIER_LIMIT",
    "SS15_INPUT_GAIN",
    "STEP_KINDS",
    "PlannedStep",
    "StepOutcome",
    "TrialOutcome",
    "TrialPlan",
    "add_parser",
    "check_trial",
    "load_trial",
    "run_trial_file",
    "step_waveform",
]
