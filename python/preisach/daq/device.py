"""Devices a trial runs on: the virtual SS15 rig and Comedi cards (C++ ``daq/device.hpp``).

:func:`virtual_ss15` builds the embedded default (a Preisach plant with optional physics blocks
between the Appendix B calibration and a noisy 14-bit ADC); :func:`comedi_device` opens a real
card on Linux through comedilib (:func:`comedi_available` tells whether this build has it).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Union

from .. import _core
from ..model import PreisachModel, State
from .blocks import BlockChain, RigBlock, make_block
from .calibration import SS15_CHANNEL_B, LinearCalibration
from .channel import Channel, ss15_input_channel, ss15_output_channel

__all__ = ["Device", "comedi_available", "comedi_device", "virtual_ss15"]

comedi_available = _core.comedi_available

#: Any device :func:`preisach.daq.run_trial` accepts.
Device = Union[_core.VirtualRig, _core.ComediDevice, _core.DaqDevice]


def _as_blocks(blocks: Iterable[RigBlock | Mapping[str, Any]], dt: float) -> list[RigBlock]:
    out: list[RigBlock] = []
    for i, b in enumerate(blocks):
        if isinstance(b, RigBlock):
            if not math.isclose(b.dt, dt, rel_tol=1e-12):
                raise ValueError(
                    f"block {i} ({b.kind}) has dt = {b.dt} s but the rig samples every {dt} s"
                )
            out.append(b)
        elif isinstance(b, Mapping):
            out.append(make_block(b, dt))
        else:
            raise TypeError(
                f"block {i}: expected a preisach block or a mapping, got {type(b).__name__}"
            )
    return out


def _start_state(model: PreisachModel, state: State | str | None) -> State:
    if state is None or isinstance(state, str):
        name = "anhysteretic" if state is None else state
        makers = {
            "anhysteretic": model.anhysteretic_state,
            "negative_saturation": model.negative_saturation,
            "positive_saturation": model.positive_saturation,
        }
        if name not in makers:
            raise ValueError(f"state: expected a State or one of {sorted(makers)}, got {name!r}")
        return makers[name]()
    return state


def virtual_ss15(
    model: PreisachModel | str = "ss15-1hz",
    state: State | str | None = None,
    *,
    sample_time: float = 1e-3,
    input_blocks: Sequence[RigBlock | Mapping[str, Any]] = (),
    output_blocks: Sequence[RigBlock | Mapping[str, Any]] = (),
    moving_gain: float = 0.0,
    adc_noise: float = 0.5e-3,
    adc_bits: int = 14,
    dac_bits: int = 0,
    amplifier: LinearCalibration = SS15_CHANNEL_B,
    amp_limit: float = 150.0,
    output: Channel | None = None,
    input: Channel | None = None,  # noqa: A002
    seed: int = 0,
) -> _core.VirtualRig:
    """Build the virtual SS15 rig: DAC -> SA11 amplifier -> plant -> ADC, all in C++.

    The plant is ``input_blocks -> Preisach model -> output_blocks``
    (see :mod:`preisach.daq.blocks`); with no blocks it is the classical model alone.

    Parameters
    ----------
    model : PreisachModel or str
        The Preisach model (input ``V_in`` in V, output in V), or a built-in name
        (``"ss15-1hz"``, ``"ss15-2hz"``, ``"ss15-4hz"``) or a saved model file.
    state : State or str, optional
        Starting state: a :class:`State`, ``"anhysteretic"`` (default),
        ``"negative_saturation"`` or ``"positive_saturation"``.
    sample_time : float
        The rig's sample period (s); trials must use it (the blocks are discretised for it).
    input_blocks, output_blocks : sequence
        Blocks (or ``{"kind": ..., **params}`` mappings) before and after the Preisach stage.
    moving_gain : float
        Output feedback of the Preisach stage (V/V), 0 for the classical model.
    adc_noise : float
        Measurement noise (V rms, Gaussian, seeded) added at the ADC input.
    adc_bits : int
        ADC resolution over the input channel's range (14 bits over +/-5 V = 0.61 mV).
    dac_bits : int
        DAC resolution over the output channel's range (0: ideal).
    amplifier : LinearCalibration
        The rig's *true* amplifier ``V_in = gain * V_dac + offset`` (Eq B.1b by default).  Give
        a different one than the output channel's calibration to simulate a miscalibration.
    amp_limit : float
        The amplifier's output swing (V).
    output, input : Channel, optional
        Default :func:`ss15_output_channel` and :func:`ss15_input_channel`.
    seed : int
        Seed of the ADC noise.

    Returns
    -------
    preisach._core.VirtualRig
        A device for :func:`run_trial`; ``rig.state``, ``rig.plant_output`` and
        ``rig.reset(state)`` inspect and reset it between trials.

    """
    if isinstance(model, str):
        model = (
            PreisachModel.builtin(model)
            if model.lower().startswith("ss15-")
            else PreisachModel.load(model)
        )
    if not isinstance(model, PreisachModel):
        raise TypeError(f"model: expected a PreisachModel or a name, got {type(model).__name__}")
    dt = float(sample_time)
    chain = [
        *_as_blocks(input_blocks, dt),
        _core.PreisachStage(dt, model.table, _start_state(model, state), float(moving_gain)),
        *_as_blocks(output_blocks, dt),
    ]
    return _core.VirtualRig(
        BlockChain(chain),
        ss15_output_channel() if output is None else output,
        ss15_input_channel() if input is None else input,
        sample_time=dt,
        dac_bits=int(dac_bits),
        amp_gain=amplifier.gain,
        amp_offset=amplifier.offset,
        amp_limit=float(amp_limit),
        adc_bits=int(adc_bits),
        adc_noise=float(adc_noise),
        seed=int(seed),
    )


def comedi_device(
    file: str,
    outputs: Sequence[Channel] | None = None,
    inputs: Sequence[Channel] | None = None,
    *,
    calibration_file: str = "",
) -> _core.ComediDevice:
    """Open a Comedi card (Linux) for trials.

    Parameters
    ----------
    file : str
        Device file, e.g. ``"/dev/comedi0"``.
    outputs, inputs : sequence of Channel, optional
        Default the SS15 wiring: :func:`ss15_output_channel`, :func:`ss15_input_channel`.
    calibration_file : str
        comedilib software-calibration file (from ``comedi_soft_calibrate``) for
        software-calibrated cards; default comedilib's default path.

    Raises
    ------
    preisach.errors.DeviceError
        If the file cannot be opened (the message names it), a channel or range does not
        exist, the calibration is missing, or this build has no Comedi support.

    """
    return _core.ComediDevice(
        file,
        list(outputs) if outputs is not None else [ss15_output_channel()],
        list(inputs) if inputs is not None else [ss15_input_channel()],
        calibration_file,
    )
