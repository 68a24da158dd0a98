"""Controllers the trial runner asks for the actuator voltage (C++ ``daq/controller.hpp``).

:class:`WaveformController` plays a sampled open-loop input, :class:`PIController` is the
thesis's PI regulator (§4.1) and :class:`CallbackController` calls a Python function (which
gets the GIL only for the call).
"""

from __future__ import annotations

from .. import _core

__all__ = ["CallbackController", "PIController", "WaveformController"]

WaveformController = _core.DaqWaveformController
PIController = _core.DaqPIController
CallbackController = _core.DaqCallbackController
