"""Analog channels and the runner's safety limits (C++ ``daq/channel.hpp``, ``daq/runner.hpp``).

A channel converts connector volts to physical units with a linear calibration
(``physical = gain * connector + offset``, thesis Appendix B); the SS15 rig's two channels are
:func:`ss15_output_channel` (the amplifier drive) and :func:`ss15_input_channel` (the strain
gauge).
"""

from __future__ import annotations

from .. import _core
from .calibration import SS15_CHANNEL_B, LinearCalibration

__all__ = ["Channel", "SafetyLimits", "channel", "ss15_input_channel", "ss15_output_channel"]

Channel = _core.DaqChannel
SafetyLimits = _core.DaqSafety


def channel(
    name: str,
    number: int,
    range: tuple[float, float],  # noqa: A002 - the DAQ term
    calibration: LinearCalibration | None = None,
    *,
    unit: str = "V",
    subdevice: int = -1,
    aref: int = 0,
) -> Channel:
    """Describe an analog channel with a :class:`~preisach.daq.calibration.LinearCalibration`.

    Parameters
    ----------
    name : str
        Channel name (the recording's column for inputs other than the primary one).
    number : int
        Channel number on the card.
    range : (float, float)
        Connector-volt range the converter is set to, e.g. ``(-10, 10)``.
    calibration : LinearCalibration, optional
        ``physical = gain * connector + offset``; default the identity.
    unit : str
        Physical unit (``"V"``).
    subdevice : int
        Comedi subdevice; -1 picks the first analog output/input subdevice.
    aref : int
        Comedi analog reference: 0 ground, 1 common, 2 differential.

    """
    cal = calibration if calibration is not None else LinearCalibration(1.0, 0.0)
    return Channel(
        name,
        int(number),
        (float(range[0]), float(range[1])),
        cal.gain,
        cal.offset,
        unit,
        int(subdevice),
        int(aref),
    )


def ss15_output_channel() -> Channel:
    """Return the SS15 drive: Quanser DAC CH 1 (+/-10 V) into SA11 channel B, Eq B.1b/B.2.

    ``V_in = -14.12 V_bin - 0.02`` (:data:`preisach.daq.calibration.SS15_CHANNEL_B`).
    """
    return channel("V_in", 1, (-10.0, 10.0), SS15_CHANNEL_B)


def ss15_input_channel() -> Channel:
    """Return the SS15 strain-gauge output: Quanser ADC Ch 1 (+/-5 V), identity calibration.

    Table B.1 shows the ADC reads the connector voltage to within 0.03 V, so the thesis
    used no ADC equation; neither do we.
    """
    return channel("V_out", 1, (-5.0, 5.0))
