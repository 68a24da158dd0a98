"""The DAQ layer: devices, controllers and the trial runner (C++ through pybind11).

A *trial* is a clocked sample loop run in C++ with the GIL released.  At every sample ``k``
(time ``t_k = k * sample_time``) the runner

1. reads every input channel (connector volts) and converts it to physical units with the
   channel's linear calibration (``physical = gain * connector + offset``, Appendix B);
2. checks the readings: NaN (a converter at the end of its range) or a primary reading outside
   ``[y_min, y_max]`` aborts the trial;
3. asks the controller for the actuator voltage (open-loop waveform, PI regulator, or a Python
   callback that gets the GIL only for the call);
4. applies the safety limits - clamp to ``[u_min, u_max]`` (default +/-135 V, what the SA11
   amplifier delivers, thesis section 3.1), slew-rate limit, then the output channel's range -
   converts to connector volts with the inverse calibration and writes it;
5. pushes the sample into a preallocated ring buffer that a writer thread streams to the
   recording file in chunks.

With ``realtime=True`` (always, for a real device) each sample starts at an absolute deadline
(``steady_clock``; sleep until shortly before, then spin); a sample whose I/O ends after the
next deadline is a *missed deadline*; every one is counted (``TrialResult.missed_deadlines``,
the first 1024 indices in ``TrialResult.missed``) and the per-sample lateness is a column of
the recording.  A simulated device otherwise runs as fast as it can.

A NaN or out-of-range reading, a controller error, a non-finite command, more deadlines missed
in a row than ``SafetyLimits.max_consecutive_missed`` (default 20: a stall of 20 ms at 1 kHz) or
in total than ``SafetyLimits.max_missed_deadlines`` (default: no limit; a lone late sample only
holds the previous output one period longer), or a stop request ends the trial early: the output
is ramped to 0 V at ``ramp_rate`` (still sampling and recording), and the file is closed with
``end_status`` ``"interrupted"`` (stop request, Ctrl-C) or ``"aborted: <reason>"``.  In every
case the file holds every sample taken and loads with :meth:`preisach.Recording.load`.

Recording columns: ``t`` (s), ``u`` (V at the actuator, after the limits), ``y`` (primary
input, physical), ``u_cmd`` (the controller's request), ``u_dac`` (connector volts written),
``y_adc`` (connector volts read), further input channels by name, ``lateness`` (s).  Note the
clocked-loop causality: ``y[k]`` is read at ``t_k`` *before* ``u[k]`` is written, so it
responds to the inputs up to ``u[k-1]``.

Devices: :func:`virtual_ss15` (the embedded default: a Preisach plant between the Appendix B
calibration and a noisy 14-bit ADC, with optional physics blocks) and :func:`comedi_device`
(real cards on Linux through comedilib; :func:`comedi_available` tells whether this build has
it).
"""

from __future__ import annotations

from .channel import Channel, SafetyLimits, channel, ss15_input_channel, ss15_output_channel
from .controller import CallbackController, PIController, WaveformController
from .device import Device, comedi_available, comedi_device, virtual_ss15
from .plant import DevicePlant
from .runner import TrialResult, run_trial

__all__ = [
    "CallbackController",
    "Channel",
    "Device",
    "DevicePlant",
    "PIController",
    "SafetyLimits",
    "TrialResult",
    "WaveformController",
    "channel",
    "comedi_available",
    "comedi_device",
    "run_trial",
    "ss15_input_channel",
    "ss15_output_channel",
    "virtual_ss15",
]
