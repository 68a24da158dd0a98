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
    #          (arrays of {kind = ..., params...}, see preisach.blocks)

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

Every step also takes ``name`` (used in its file name).  :func:`check_trial` validates a
file without running it and reports every problem at once: unknown keys (with a suggestion),
wrong types, missing sections and channels, limits beyond the hardware, and planned waveforms
that exceed the safety limits or the output channel's range.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from . import daq
from .calibration import SS15_CHANNEL_A, SS15_CHANNEL_B, LinearCalibration
from .errors import TrialFileError, TrialInterrupted
from .model import BUILTIN_MODELS, PreisachModel

if sys.version_info >= (3, 11):  # pragma: no cover - version dependent
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "STEP_KINDS",
    "PlannedStep",
    "StepOutcome",
    "TrialOutcome",
    "TrialPlan",
    "add_parser",
    "check_trial",
    "load_trial",
    "run_trial_file",
]

#: Actuator volts per DAQ volt of the SS15 drive (|gain| of Eq B.2), the thesis's unit of the
#: noise amplitude and the PI gains.
SS15_INPUT_GAIN = abs(SS15_CHANNEL_B.gain)
#: The SA11 amplifier's output range (thesis section 3.1).
AMPLIFIER_LIMIT = 135.0

_CALIBRATIONS: dict[str, LinearCalibration] = {
    "ss15-a": SS15_CHANNEL_A,
    "ss15-b": SS15_CHANNEL_B,
    "identity": LinearCalibration(1.0, 0.0),
}

_NUM = (int, float)

# Schema: key -> (type(s), default); "REQUIRED" marks required keys.
REQUIRED = object()
_TRIAL_KEYS: dict[str, tuple[Any, Any]] = {
    "name": (str, None),
    "description": (str, ""),
    "sample_time": (_NUM, 1e-3),
}
_DEVICE_KEYS: dict[str, tuple[Any, Any]] = {
    "kind": (str, "sim"),
    "file": (str, None),
    "calibration_file": (str, ""),
    "model": (str, "ss15-1hz"),
    "state": (str, "anhysteretic"),
    "seed": (int, 0),
    "adc_noise": (_NUM, 0.5e-3),
    "adc_bits": (int, 14),
    "dac_bits": (int, 0),
    "moving_gain": (_NUM, 0.0),
    "input_blocks": (list, []),
    "output_blocks": (list, []),
}
_CHANNEL_KEYS: dict[str, tuple[Any, Any]] = {
    "name": (str, REQUIRED),
    "channel": (int, REQUIRED),
    "range": (list, REQUIRED),
    "calibration": (str, None),
    "gain": (_NUM, None),
    "offset": (_NUM, None),
    "unit": (str, "V"),
    "subdevice": (int, -1),
    "aref": (int, 0),
}
_SAFETY_KEYS: dict[str, tuple[Any, Any]] = {
    "u_limits": (list, [-AMPLIFIER_LIMIT, AMPLIFIER_LIMIT]),
    "slew_rate": (_NUM, 1e4),
    "ramp_rate": (_NUM, 500.0),
    "approach_rate": (_NUM, 200.0),
    "y_limits": (list, [-math.inf, math.inf]),
    "max_missed_deadlines": (int, -1),
    "max_consecutive_missed": (int, 20),
}
_STEP_COMMON: dict[str, tuple[Any, Any]] = {"kind": (str, REQUIRED), "name": (str, None)}
_SHAPE = (str, "cosine")
#: Parameters of every step kind with their defaults.
STEP_KINDS: dict[str, dict[str, tuple[Any, Any]]] = {
    "initialise": {"duration": (_NUM, 12.0), "frequency": (_NUM, 1.0), "amplitude": (_NUM, 100.0)},
    "fod_sweep": {
        "frequency": (_NUM, 1.0),
        "levels": (int, 21),
        "u_min": (_NUM, -100.0),
        "u_max": (_NUM, 100.0),
        "shape": _SHAPE,
        "order": (str, "descending"),
    },
    "wiping_out": {
        "frequency": (_NUM, 1.0),
        "peaks": (list, [100.0, 72.0, 44.0]),
        "trough": (_NUM, -40.0),
        "u_min": (_NUM, -100.0),
        "shape": _SHAPE,
    },
    "cml": {
        "frequency": (_NUM, 1.0),
        "loop": (list, [0.0, 50.0]),
        "peak": (_NUM, 100.0),
        "u_min": (_NUM, -100.0),
        "shape": _SHAPE,
    },
    "drive": {
        "target": (str, REQUIRED),
        "y_d": (_NUM, None),
        "offset": (_NUM, None),
        "frequency": (_NUM, 1.0),
        "cycles": (_NUM, 10.0),
        "u_hat": (_NUM, None),
        "hold": (_NUM, 2.0),
        "model": (str, None),
        "tolerance": (_NUM, 0.03),
    },
    "noise": {
        "duration": (_NUM, 8.0),
        "amplitude": (_NUM, 0.5),
        "gain": (_NUM, 1.0),
        "input_gain": (_NUM, SS15_INPUT_GAIN),
        "cutoff": (_NUM, 15.0),
        "hold_time": (_NUM, 0.015),
        "seed": (int, 0),
        "hold_before": (_NUM, 2.0),
        "hold_after": (_NUM, 0.0),
        "offset": (_NUM, None),
    },
    "pi": {
        "setpoint": (_NUM, 1.0),
        "kp": (_NUM, 1.5),
        "ki": (_NUM, 30.0),
        "input_gain": (_NUM, SS15_INPUT_GAIN),
        "duration": (_NUM, 12.0),
        "enable_after": (_NUM, 1.0),
        "average": (_NUM, 0.025),
        "noise_gain": (_NUM, 0.0),
        "noise_from": (_NUM, 2.0),
        "noise_to": (_NUM, 10.0),
        "amplitude": (_NUM, 0.5),
        "cutoff": (_NUM, 15.0),
        "hold_time": (_NUM, 0.015),
        "seed": (int, 0),
        "offset": (_NUM, None),
    },
    "hold": {"duration": (_NUM, REQUIRED), "value": (_NUM, None)},
}
_TARGETS = {"psi_n": "n", "psi_a": "a", "psi_d": "d"}
_SECTIONS = ("trial", "device", "output", "input", "safety", "steps")


# ------------------------------------------------------------------------------------------
# validation
# ------------------------------------------------------------------------------------------
class _Errors:
    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, where: str, message: str) -> None:
        self.items.append(f"{where}: {message}")

    def raise_if_any(self, path: str) -> None:
        """Raise one :class:`TrialFileError` listing every error, one per line."""
        if self.items:
            raise TrialFileError(
                f"{path}: {len(self.items)} error(s)\n  " + "\n  ".join(self.items)
            )


def _suggest(key: str, known: Sequence[str]) -> str:
    close = difflib.get_close_matches(key, list(known), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _type_ok(value: Any, types: Any) -> bool:
    if isinstance(value, bool):
        return False
    if types is _NUM:
        return isinstance(value, _NUM)
    return isinstance(value, types)


def _type_name(types: Any) -> str:
    if types is _NUM:
        return "a number"
    return {str: "a string", int: "an integer", list: "an array", dict: "a table"}[types]


def _section(
    data: Mapping[str, Any], where: str, schema: Mapping[str, tuple[Any, Any]], errors: _Errors
) -> dict[str, Any]:
    """Check keys and types of one table; returns the values with defaults filled in."""
    out: dict[str, Any] = {}
    if not isinstance(data, Mapping):
        errors.add(where, f"must be a table, got {data!r}")
        data = {}
    for key in data:
        if key not in schema:
            errors.add(
                where,
                f"unknown key {key!r}{_suggest(key, list(schema))}; "
                f"allowed: {', '.join(sorted(schema))}",
            )
    for key, (types, default) in schema.items():
        if key in data:
            value = data[key]
            if not _type_ok(value, types):
                errors.add(where, f"{key} must be {_type_name(types)}, got {value!r}")
                if default is not REQUIRED:  # go on with the default: later checks still run
                    out[key] = default
                continue
            out[key] = float(value) if types is _NUM else value
        elif default is REQUIRED:
            errors.add(where, f"missing required key {key!r}")
        else:
            out[key] = default
    return out


def _pair(value: Any, where: str, key: str, errors: _Errors) -> tuple[float, float] | None:
    if not isinstance(value, list) or len(value) != 2 or not all(_type_ok(v, _NUM) for v in value):
        errors.add(where, f"{key} must be an array of two numbers [low, high], got {value!r}")
        return None
    lo, hi = float(value[0]), float(value[1])
    if not lo < hi:
        errors.add(where, f"{key} = [{lo:g}, {hi:g}] must have low < high")
        return None
    return lo, hi


def _channel(data: Any, where: str, errors: _Errors) -> daq.Channel | None:
    if not isinstance(data, Mapping):
        errors.add(where, "missing table (the channel: name, channel, range, calibration)")
        return None
    c = _section(data, where, _CHANNEL_KEYS, errors)
    rng = _pair(c.get("range"), where, "range", errors) if "range" in c else None
    cal: LinearCalibration | None
    if c.get("calibration") is not None:
        if c.get("gain") is not None or c.get("offset") is not None:
            errors.add(where, "give either calibration or gain/offset, not both")
        cal = _CALIBRATIONS.get(c["calibration"])
        if cal is None:
            errors.add(
                where,
                f"calibration {c['calibration']!r} is unknown; use one of "
                f"{sorted(_CALIBRATIONS)} or gain/offset",
            )
    else:
        gain = 1.0 if c.get("gain") is None else c["gain"]
        offset = 0.0 if c.get("offset") is None else c["offset"]
        try:
            cal = LinearCalibration(gain, offset)
        except (TypeError, ValueError) as exc:
            errors.add(where, str(exc))
            cal = None
        if cal is not None and cal.gain == 0:
            errors.add(where, "gain must not be 0")
            cal = None
    if rng is None or cal is None or "name" not in c or "channel" not in c:
        return None
    if c["channel"] < 0:
        errors.add(where, f"channel must be >= 0, got {c['channel']}")
        return None
    try:
        return daq.channel(
            c["name"],
            c["channel"],
            rng,
            cal,
            unit=c["unit"],
            subdevice=c["subdevice"],
            aref=c["aref"],
        )
    except ValueError as exc:
        errors.add(where, str(exc))
        return None


@dataclass
class PlannedStep:
    """One step of a trial with its parameters (defaults filled in).

    Attributes
    ----------
    index : int
        Position in the trial (0-based).
    kind : str
        Step kind (see :data:`STEP_KINDS`).
    name : str
        Name used in the file name.
    params : dict
        Parameters with defaults.

    """

    index: int
    kind: str
    name: str
    params: dict[str, Any]

    @property
    def file_name(self) -> str:
        """``NN_<name>.csv``."""
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in self.name)
        return f"{self.index + 1:02d}_{safe}.csv"


@dataclass
class TrialPlan:
    """A validated trial file.

    Attributes
    ----------
    path : str
        The file.
    name, description : str
        From ``[trial]``.
    sample_time : float
        Sample period (s).
    device : dict
        ``[device]`` with defaults.
    output, input : preisach.daq.Channel
        The actuator channel and the primary measured channel.
    safety : dict
        ``[safety]`` with defaults.
    steps : list of PlannedStep

    """

    path: str
    name: str
    description: str
    sample_time: float
    device: dict[str, Any]
    output: daq.Channel
    input: daq.Channel
    safety: dict[str, Any]
    steps: list[PlannedStep] = field(default_factory=list)

    def safety_limits(self) -> daq.SafetyLimits:
        """Return the runner's :data:`preisach.daq.SafetyLimits`."""
        s = self.safety
        return daq.SafetyLimits(
            s["u_limits"][0],
            s["u_limits"][1],
            s["slew_rate"],
            s["ramp_rate"],
            s["y_limits"][0],
            s["y_limits"][1],
            int(s["max_missed_deadlines"]),
            int(s["max_consecutive_missed"]),
        )


class _Draft(NamedTuple):
    """What parsing got, with errors or not."""

    plan: TrialPlan  # only the steps that parsed cleanly; placeholders for invalid channels
    output_ok: bool  # whether plan.output is the file's channel (not a placeholder)


def _placeholder_channel() -> daq.Channel:
    return daq.channel("(invalid)", 0, (-10.0, 10.0))


def _parse(data: Mapping[str, Any], path: str, errors: _Errors) -> _Draft:
    """Check the structure of a trial file, adding every problem found to ``errors``.

    Returns a draft plan even when there are errors, so that :func:`check_trial` can still
    plan the waveforms of the steps that parsed cleanly: it has those steps only, the
    defaults in place of invalid ``[safety]`` values and placeholder channels in place of
    invalid ones (``output_ok`` tells).  Use it as a plan only when ``errors`` is empty.
    """
    for key in data:
        if key not in _SECTIONS:
            errors.add(
                path,
                f"unknown section [{key}]{_suggest(key, _SECTIONS)}; allowed: "
                f"{', '.join('[' + s + ']' for s in _SECTIONS)}",
            )
    trial = _section(data.get("trial", {}), "[trial]", _TRIAL_KEYS, errors)
    ts = trial["sample_time"]
    if not (isinstance(ts, float) and math.isfinite(ts) and ts > 0):
        errors.add("[trial]", f"sample_time must be a positive number of seconds, got {ts!r}")
        ts = 1e-3
    dev = _section(data.get("device", {}), "[device]", _DEVICE_KEYS, errors)
    if dev["kind"] not in ("sim", "comedi"):
        errors.add("[device]", f"kind must be 'sim' or 'comedi', got {dev['kind']!r}")
    if dev["kind"] == "comedi" and not dev.get("file"):
        errors.add("[device]", "kind = 'comedi' needs file = '/dev/comediN'")
    if dev["kind"] == "sim":
        if dev["state"] not in ("anhysteretic", "negative_saturation", "positive_saturation"):
            errors.add(
                "[device]",
                f"state must be 'anhysteretic', 'negative_saturation' or "
                f"'positive_saturation', got {dev['state']!r}",
            )
        if dev["adc_noise"] < 0:
            errors.add("[device]", f"adc_noise must be >= 0 V, got {dev['adc_noise']!r}")
        from .blocks import make_block

        for side in ("input_blocks", "output_blocks"):
            for i, spec in enumerate(dev[side]):
                where = f"[device] {side}[{i}]"
                if not isinstance(spec, Mapping):
                    errors.add(where, f"must be a table {{kind = ..., ...}}, got {spec!r}")
                    continue
                try:
                    make_block(spec, ts)
                except (TypeError, ValueError) as exc:
                    errors.add(where, str(exc))
    out = _channel(data.get("output"), "[output]", errors)
    inp = _channel(data.get("input"), "[input]", errors)
    safety = _section(data.get("safety", {}), "[safety]", _SAFETY_KEYS, errors)
    u_lim = _pair(safety["u_limits"], "[safety]", "u_limits", errors)
    y_lim = _pair(safety["y_limits"], "[safety]", "y_limits", errors)
    if u_lim is not None:
        if u_lim[0] < -AMPLIFIER_LIMIT or u_lim[1] > AMPLIFIER_LIMIT:
            errors.add(
                "[safety]",
                f"u_limits = [{u_lim[0]:g}, {u_lim[1]:g}] V exceed the SA11 "
                f"amplifier's +/-{AMPLIFIER_LIMIT:g} V",
            )
        if not u_lim[0] <= 0.0 <= u_lim[1]:
            errors.add("[safety]", "u_limits must contain 0 V (the safe state)")
        safety["u_limits"] = list(u_lim)
    else:  # check the waveforms against the amplifier
        safety["u_limits"] = list(_SAFETY_KEYS["u_limits"][1])
    if y_lim is not None:
        safety["y_limits"] = list(y_lim)
    else:
        safety["y_limits"] = list(_SAFETY_KEYS["y_limits"][1])
    bad_rates: set[str] = set()
    for key in ("slew_rate", "ramp_rate", "approach_rate"):
        v = safety[key]
        if not (isinstance(v, float) and v > 0):
            errors.add("[safety]", f"{key} must be > 0 V/s, got {v!r}")
        elif key == "ramp_rate" and not math.isfinite(v):
            errors.add("[safety]", f"ramp_rate must be a finite number of V/s, got {v!r}")
        else:
            continue
        bad_rates.add(key)
        safety[key] = _SAFETY_KEYS[key][1]  # go on checking the waveforms with the default
    if not bad_rates & {"slew_rate", "ramp_rate"} and safety["ramp_rate"] > safety["slew_rate"]:
        errors.add(
            "[safety]",
            f"ramp_rate = {safety['ramp_rate']:g} V/s exceeds slew_rate = "
            f"{safety['slew_rate']:g} V/s: the ramp to 0 V after an abort must respect the "
            "slew limit (use ramp_rate <= slew_rate)",
        )
    if safety["max_consecutive_missed"] == 0:
        errors.add(
            "[safety]",
            "max_consecutive_missed must be >= 1 (or < 0 for no limit), got 0",
        )

    steps_data = data.get("steps")
    steps: list[PlannedStep] = []
    if not isinstance(steps_data, list) or not steps_data:
        errors.add(path, "no [[steps]]: a trial needs at least one step")
        steps_data = []
    for i, st in enumerate(steps_data):
        where = f"steps[{i}]"
        if not isinstance(st, Mapping):
            errors.add(where, "must be a table")
            continue
        kind = st.get("kind")
        if kind not in STEP_KINDS:
            errors.add(
                where,
                f"kind {kind!r} is unknown{_suggest(str(kind), list(STEP_KINDS))}; "
                f"choose from {', '.join(STEP_KINDS)}",
            )
            continue
        where = f"steps[{i}] ({kind})"
        n_errors = len(errors.items)
        params = _section(st, where, {**_STEP_COMMON, **STEP_KINDS[kind]}, errors)
        _check_step(kind, params, where, dev, errors)
        name = params.pop("name", None) or kind
        params.pop("kind", None)
        if len(errors.items) == n_errors:  # only clean steps are planned
            steps.append(PlannedStep(i, kind, name, params))
    if (out is None or inp is None) and not errors.items:  # pragma: no cover - defensive
        errors.add("[output]" if out is None else "[input]", "invalid channel")
    plan = TrialPlan(
        path,
        trial.get("name") or Path(path).stem,
        trial.get("description", ""),
        ts,
        dev,
        out if out is not None else _placeholder_channel(),
        inp if inp is not None else _placeholder_channel(),
        safety,
        steps,
    )
    return _Draft(plan, out is not None)


def _check_step(
    kind: str, p: dict[str, Any], where: str, dev: Mapping[str, Any], errors: _Errors
) -> None:
    for key in ("frequency", "duration", "cutoff", "hold_time"):
        if key in p and p[key] is not None and not p[key] > 0:
            errors.add(where, f"{key} must be > 0, got {p[key]!r}")
    if "shape" in p and p["shape"] not in ("cosine", "triangle"):
        errors.add(where, f"shape must be 'cosine' or 'triangle', got {p['shape']!r}")
    for key in ("peaks", "loop"):
        if key in p and not all(_type_ok(v, _NUM) for v in p[key]):
            errors.add(where, f"{key} must be an array of numbers, got {p[key]!r}")
    if kind == "drive":
        if "target" in p and p["target"] not in _TARGETS:
            errors.add(where, f"target must be one of {sorted(_TARGETS)}, got {p['target']!r}")
        if p["offset"] is None and p["y_d"] is None:
            errors.add(where, "give offset (V) or y_d (V, the desired output)")
        if (
            p["offset"] is None
            and p["y_d"] is not None
            and p["model"] is None
            and dev.get("kind") != "sim"
        ):
            errors.add(
                where,
                "y_d on a real device needs model = '...' to compute the offset (or give offset)",
            )
    if kind == "pi" and not p["noise_from"] <= p["noise_to"]:
        errors.add(where, "noise_from must be <= noise_to")
    if kind in ("noise", "pi") and p["amplitude"] < 0:
        errors.add(where, f"amplitude must be >= 0, got {p['amplitude']!r}")


def load_trial(path: str | os.PathLike[str]) -> TrialPlan:
    """Read and validate a trial file (structure, keys, types, channels, limits).

    The planned waveforms are checked by :func:`check_trial`.

    Raises
    ------
    TrialFileError
        Listing every problem found, one per line.
    FileNotFoundError
        If the file does not exist.

    """
    p, data = _read(path)
    errors = _Errors()
    draft = _parse(data, p, errors)
    errors.raise_if_any(p)
    return draft.plan


def _read(path: str | os.PathLike[str]) -> tuple[str, dict[str, Any]]:
    p = os.fspath(path)
    with open(p, "rb") as f:
        try:
            data = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise TrialFileError(f"{p}: not valid TOML: {exc}") from None
    return p, data


# ------------------------------------------------------------------------------------------
# waveforms of the steps
# ------------------------------------------------------------------------------------------
def _model_for(plan: TrialPlan, step: PlannedStep) -> PreisachModel:
    name = step.params.get("model") or plan.device.get("model") or "ss15-1hz"
    return _load_model(name)


def _load_model(name: str) -> PreisachModel:
    if name.lower() in BUILTIN_MODELS:
        return PreisachModel.builtin(name)
    return PreisachModel.load(name)


def _approach(u_from: float, u_to: float, rate: float, ts: float) -> NDArray[np.float64]:
    """Return samples moving from u_from toward u_to at `rate` V/s (u_to not included)."""
    n = int(math.ceil(abs(u_to - u_from) / (rate * ts)))
    if n <= 1:
        return np.empty(0)
    return u_from + (u_to - u_from) * np.arange(1, n) / n


def _noise(p: Mapping[str, Any], duration: float, ts: float) -> NDArray[np.float64]:
    from .noise import uniform_filtered_noise

    if p["amplitude"] == 0:
        return np.zeros(int(round(duration / ts)))
    return uniform_filtered_noise(
        duration,
        p["amplitude"],
        sample_time=ts,
        hold_time=p["hold_time"],
        cutoff=p["cutoff"],
        seed=p["seed"],
    )


def step_waveform(
    plan: TrialPlan, step: PlannedStep, u_now: float
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Plan the actuator voltages of a step (V), starting from the output ``u_now``.

    For a ``pi`` step this is the feed-forward (held offset plus noise); the controller adds
    to it.  The waveform starts with a ramp from ``u_now`` at the safety's ``approach_rate``
    when its first value differs.

    Returns
    -------
    u : ndarray
        One value per sample (V).
    info : dict
        What was computed on the way (e.g. the drive offset), for the metadata.

    """
    from . import waveforms as wf

    p = step.params
    ts = plan.sample_time
    info: dict[str, Any] = {}
    if step.kind == "initialise":
        u = wf.decaying_sine(p["duration"], p["frequency"], p["amplitude"], sample_time=ts).u
    elif step.kind == "fod_sweep":
        u = wf.fod_sweep(
            p["levels"],
            u_min=p["u_min"],
            u_max=p["u_max"],
            frequency=p["frequency"],
            sample_time=ts,
            shape=p["shape"],
            order=p["order"],
        ).u
    elif step.kind == "wiping_out":
        u = wf.wiping_out_input(
            p["frequency"],
            peaks=[float(v) for v in p["peaks"]],
            trough=p["trough"],
            u_min=p["u_min"],
            sample_time=ts,
            shape=p["shape"],
        ).u
    elif step.kind == "cml":
        lo, hi = (float(v) for v in p["loop"])
        u = wf.cml_input(
            p["frequency"],
            loop=(lo, hi),
            peak=p["peak"],
            u_min=p["u_min"],
            sample_time=ts,
            shape=p["shape"],
        ).u
    elif step.kind == "drive":
        u, info = _drive_waveform(plan, step)
    elif step.kind in ("noise", "pi"):
        off = u_now if p["offset"] is None else p["offset"]
        info["offset"] = off
        if step.kind == "noise":
            n_before = int(round(p["hold_before"] / ts))
            n_after = int(round(p["hold_after"] / ts))
            eta = _noise(p, p["duration"], ts) * p["gain"] * p["input_gain"]
            u = np.concatenate([np.full(n_before, off), off + eta, np.full(n_after, off)])
        else:
            n = int(round(p["duration"] / ts))
            u = np.full(n, off)
            if p["noise_gain"]:
                i0, i1 = int(round(p["noise_from"] / ts)), min(n, int(round(p["noise_to"] / ts)))
                eta = _noise(p, (i1 - i0) * ts, ts)[: i1 - i0]
                u[i0 : i0 + eta.size] += eta * p["noise_gain"] * p["input_gain"]
    elif step.kind == "hold":
        value = u_now if p["value"] is None else p["value"]
        u = np.full(max(1, int(round(p["duration"] / ts))), value)
    else:  # pragma: no cover - validated before
        raise ValueError(f"unknown step kind {step.kind!r}")
    u = np.asarray(u, dtype=float)
    lead = _approach(u_now, float(u[0]), plan.safety["approach_rate"], ts)
    info["approach_samples"] = int(lead.size)
    return np.concatenate([lead, u]), info


def _drive_waveform(
    plan: TrialPlan, step: PlannedStep
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    from .experiments import ModelPlant, drive_to_state
    from .experiments.waveforms import branch_input, neutral_input

    p = step.params
    ts = plan.sample_time
    kind = _TARGETS[p["target"]]
    info: dict[str, Any] = {"target": p["target"]}
    model = _model_for(plan, step)
    u_range = (model.u_min, model.u_max)
    if p["offset"] is not None:
        off = p["offset"]
        if kind == "n":
            wave = neutral_input(
                off,
                p["frequency"],
                u_range=u_range,
                cycles=p["cycles"],
                sample_time=ts,
                u_hat=p["u_hat"],
            )
        else:
            wave = branch_input(
                kind, off, p["frequency"], u_range=u_range, sample_time=ts, u_hat=p["u_hat"]
            )
    else:
        init = drive_to_state(
            ModelPlant(model, ts),
            kind,
            p["y_d"],
            p["frequency"],
            tolerance=p["tolerance"],
            cycles=p["cycles"],
            u_hat=p["u_hat"],
        )
        wave = init.waveform
        info.update(y_d=p["y_d"], model_output=init.y_end, model=model.name)
    info["offset"] = wave.offset
    hold = np.full(int(round(p["hold"] / ts)), wave.offset)
    return np.concatenate([wave.input, hold]), info


# ------------------------------------------------------------------------------------------
# check
# ------------------------------------------------------------------------------------------
def check_trial(path: str | os.PathLike[str]) -> TrialPlan:
    """Validate a trial file without running it.

    Besides :func:`load_trial`'s checks, every step's planned waveform is generated (starting
    from 0 V, each step from where the previous one ends) and checked against the safety
    limits ``u_limits`` and ``slew_rate`` and against the output channel's connector range.
    The waveforms are checked even when the file has other errors: those of the steps that
    parsed cleanly, against the limits that did (the defaults in place of invalid ones; no
    channel-range check when the output channel is invalid; a step after one that did not
    parse starts from where the last planned step ended), and every problem is reported in
    one :class:`TrialFileError`.

    Returns
    -------
    TrialPlan

    Raises
    ------
    TrialFileError
        Listing every problem, one per line.

    """
    p, data = _read(path)
    errors = _Errors()
    plan, output_ok = _parse(data, p, errors)
    lo, hi = plan.safety["u_limits"]
    slew = plan.safety["slew_rate"]
    ch_lo, ch_hi = sorted(
        (plan.output.physical(plan.output.range[0]), plan.output.physical(plan.output.range[1]))
    )
    ts = plan.sample_time
    u_now = 0.0
    for step in plan.steps:
        where = f"steps[{step.index}] ({step.kind})"
        try:
            u, _ = step_waveform(plan, step, u_now)
        except (ValueError, TypeError, ArithmeticError, OSError) as exc:
            errors.add(where, f"cannot plan the waveform: {exc}")
            continue
        if u.size == 0:
            errors.add(where, "the planned waveform is empty")
            continue
        for bound, ok, what in (
            (lo, u >= lo, "below the output limit u_min"),
            (hi, u <= hi, "above the output limit u_max"),
        ):
            if not ok.all():
                k = int(np.argmin(ok))
                errors.add(
                    where,
                    f"the planned input reaches {u[k]:.6g} V at t = {k * ts:.6g} s "
                    f"(from the step's start), {what} = {bound:g} V",
                )
        for bound, ok, what in ((ch_lo, u >= ch_lo, "below"), (ch_hi, u <= ch_hi, "above")):
            if output_ok and not ok.all():
                k = int(np.argmin(ok))
                errors.add(
                    where,
                    f"the planned input {u[k]:.6g} V at t = {k * ts:.6g} s is "
                    f"{what} what the output channel can produce ({bound:.6g} V at "
                    f"the end of its connector range)",
                )
        rate = np.abs(np.diff(np.concatenate([[u_now], u]))) / ts
        if rate.size and rate.max() > slew * (1 + 1e-9):
            k = int(np.argmax(rate))
            errors.add(
                where,
                f"the planned input changes at {rate[k]:.6g} V/s at "
                f"t = {k * ts:.6g} s,"
                f" above the slew_rate limit {slew:g} V/s",
            )
        u_now = float(u[-1])
    errors.raise_if_any(p)
    return plan


# ------------------------------------------------------------------------------------------
# run
# ------------------------------------------------------------------------------------------
@dataclass
class StepOutcome:
    """What one step did.

    Attributes
    ----------
    index, kind, name : int, str, str
        The step.
    file : str
        Its recording.
    result : preisach.daq.TrialResult
        The runner's result.
    info : dict
        Planning details (drive offset, approach samples, ...).

    """

    index: int
    kind: str
    name: str
    file: str
    result: daq.TrialResult
    info: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        d = {
            "index": self.index,
            "kind": self.kind,
            "name": self.name,
            "file": self.file,
            "info": self.info,
        }
        d.update({k: v for k, v in self.result.to_dict().items() if k not in ("path", "missed")})
        d["missed"] = self.result.missed[:100]
        return d


@dataclass
class TrialOutcome:
    """The result of :func:`run_trial_file`.

    Attributes
    ----------
    plan : TrialPlan
    device : str
        Device description.
    end_status : str
        ``"complete"``, or the ``end_status`` of the step that ended the trial.
    steps : list of StepOutcome
    summary_file : str
        The ``summary.json`` written.

    """

    plan: TrialPlan
    device: str
    end_status: str
    steps: list[StepOutcome]
    summary_file: str

    @property
    def complete(self) -> bool:
        """Whether every step completed."""
        return self.end_status == "complete"


def _make_device(plan: TrialPlan, device: str | None) -> Any:
    spec = device or plan.device["kind"]
    if spec == "sim":
        d = plan.device
        return daq.virtual_ss15(
            _load_model(d["model"]),
            d["state"],
            sample_time=plan.sample_time,
            input_blocks=d["input_blocks"],
            output_blocks=d["output_blocks"],
            moving_gain=d["moving_gain"],
            adc_noise=d["adc_noise"],
            adc_bits=d["adc_bits"],
            dac_bits=d["dac_bits"],
            output=plan.output,
            input=plan.input,
            seed=d["seed"],
        )
    if spec.startswith("comedi"):
        file = spec.partition(":")[2] or plan.device.get("file")
        if not file:
            raise ValueError("--device comedi needs a device file: comedi:/dev/comediN")
        return daq.comedi_device(
            file, [plan.output], [plan.input], calibration_file=plan.device["calibration_file"]
        )
    raise ValueError(f"device {spec!r}: expected 'sim' or 'comedi:/dev/comediN'")


def _ramp_file(out: Path, number: int, written: set[Path], overwrite: bool) -> Path:
    """``NN_ramp.csv`` in ``out``, or ``NN_ramp-2.csv``, ... when that name is taken."""
    file = out / f"{number:02d}_ramp.csv"
    k = 1
    while file in written or (file.exists() and not overwrite):
        k += 1
        file = out / f"{number:02d}_ramp-{k}.csv"
    return file


def _ramp_to_zero(
    dev: Any,
    plan: TrialPlan,
    safety: daq.SafetyLimits,
    file: Path,
    *,
    t0: float,
    realtime: bool,
    fsync: bool,
    priority: int,
) -> dict[str, Any] | None:
    """Ramp the actuator from its last output to 0 V at ``safety.ramp_rate``, recorded.

    Used when a trial stops between steps (or a step raises): the runner's own ramp only
    runs inside a trial.  Returns what happened, for the summary (``None`` when the output
    is already at 0 V); never raises, so the caller can re-raise what stopped the trial.
    """
    try:
        u = float(dev.outputs[0].physical(dev.last_output(0)))
    except Exception as exc:  # noqa: BLE001 - reported in the summary
        return {"error": f"cannot read the output: {type(exc).__name__}: {exc}"}
    if abs(u) < 1e-9:
        return None
    ts = plan.sample_time
    wave = np.append(_approach(u, 0.0, safety.ramp_rate, ts), 0.0)
    doc: dict[str, Any] = {"file": str(file), "from": u, "ramp_rate": safety.ramp_rate}
    try:
        res = daq.run_trial(
            dev,
            wave,
            file,
            sample_time=ts,
            realtime=realtime,
            safety=safety,
            metadata={"experiment": "safety_ramp", "trial": plan.name, "ramp_from": u},
            overwrite=True,
            fsync=fsync,
            t0=t0,
            priority=priority,
            ramp_at_end=True,
        )
    except TrialInterrupted as exc:  # Ctrl-C during the ramp: the runner still ramped down
        if not isinstance(exc.result, daq.TrialResult):  # pragma: no cover
            doc["error"] = f"TrialInterrupted: {exc}"
            return doc
        res = exc.result
    except BaseException as exc:  # noqa: BLE001 - reported; the caller re-raises its own
        doc["error"] = f"{type(exc).__name__}: {exc}"
        return doc
    doc.update(
        end_status=res.end_status,
        samples=res.samples,
        ramp_samples=res.ramp_samples,
        final_output=res.final_output,
    )
    return doc


def run_trial_file(
    path: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    *,
    device: str | None = None,
    realtime: bool = False,
    overwrite: bool = False,
    fsync: bool = True,
    priority: int = 0,
    progress: Callable[[int, int, PlannedStep, int, int], None] | None = None,
) -> TrialOutcome:
    """Check and run a trial file; one recording per step plus ``summary.json`` in ``outdir``.

    Parameters
    ----------
    path : str or path-like
        The trial file.
    outdir : str or path-like
        Output folder (created).
    device : str, optional
        ``"sim"`` or ``"comedi:/dev/comediN"`` to override the file's ``[device] kind``.
    realtime : bool
        Pace a simulated device in real time (a real one always is).
    overwrite : bool
        Replace existing recordings.
    fsync : bool
        fsync the recordings as they are written.
    priority : int
        SCHED_FIFO priority to request for the sample loop (0: none).
    progress : callable, optional
        ``progress(done, planned, step, step_number, n_steps)`` during each step.

    Returns
    -------
    TrialOutcome
        Its ``end_status`` is not ``"complete"`` when a step aborted (later steps are skipped).

    Raises
    ------
    TrialFileError
        If the file does not pass :func:`check_trial`.
    preisach.errors.TrialInterrupted
        On Ctrl-C during a step, after the current recording and the summary were written.
    BaseException
        Anything else raised once the device is open - a Ctrl-C between steps, an error while
        planning a step, a device error - is re-raised after the output was ramped from its
        last value to 0 V at the safety ``ramp_rate`` (a recorded run of the same runner,
        ``NN_ramp.csv``, ``NN`` the number of the step in progress, listed as
        ``safety_ramp`` in the summary) and ``summary.json`` was written with ``end_status``
        ``"interrupted"`` (:class:`KeyboardInterrupt`) or ``"aborted: <ExcType: message>"``.

    """
    plan = check_trial(path)
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    dev = _make_device(plan, device)
    safety = plan.safety_limits()
    outcomes: list[StepOutcome] = []
    end_status = "complete"
    u_now = float(dev.outputs[0].physical(dev.last_output(0)))
    t0 = 0.0
    started = time.time()
    summary = out / "summary.json"
    interrupted: TrialInterrupted | None = None
    number = 1  # of the step in progress
    written: set[Path] = set()  # recordings of this run, never overwritten by the safety ramp
    safety_ramp: dict[str, Any] | None = None
    try:
        for i, step in enumerate(plan.steps):
            number = i + 1
            u, info = step_waveform(plan, step, u_now)
            last = i == len(plan.steps) - 1
            meta: dict[str, Any] = {
                "experiment": step.kind,
                "trial": plan.name,
                "step": step.index,
                "step_name": step.name,
                "step_params": json.dumps(step.params, sort_keys=True),
            }
            meta.update(
                {
                    f"plan_{k}": v
                    for k, v in info.items()
                    if isinstance(v, (int, float, str)) and not isinstance(v, bool)
                }
            )
            if step.kind == "pi":
                p = step.params
                g = p["input_gain"]
                controller: Any = daq.PIController(
                    p["kp"] * g,
                    p["ki"] * g,
                    p["setpoint"],
                    plan.sample_time,
                    u,
                    enable_at=info["approach_samples"]
                    + int(round(p["enable_after"] / plan.sample_time)),
                    average=max(1, int(round(p["average"] / plan.sample_time))),
                )
            else:
                controller = daq.WaveformController(u)
            file = out / step.file_name

            def report(done: int, planned: int, _s: PlannedStep = step, _i: int = i) -> None:
                if progress is not None:
                    progress(done, planned, _s, _i + 1, len(plan.steps))

            written.add(file)
            try:
                res = daq.run_trial(
                    dev,
                    controller,
                    file,
                    sample_time=plan.sample_time,
                    realtime=realtime,
                    safety=safety,
                    metadata=meta,
                    overwrite=overwrite,
                    fsync=fsync,
                    t0=t0,
                    priority=priority,
                    ramp_at_end=last,
                    progress=report,
                )
            except TrialInterrupted as exc:
                interrupted = exc
                if not isinstance(exc.result, daq.TrialResult):  # pragma: no cover
                    raise
                res = exc.result
            outcomes.append(StepOutcome(step.index, step.kind, step.name, str(file), res, info))
            u_now = res.final_output
            t0 += (res.samples + res.ramp_samples) * plan.sample_time
            if interrupted is not None or not res.complete:
                end_status = res.end_status
                break
    except BaseException as exc:
        end_status = (
            "interrupted"
            if isinstance(exc, KeyboardInterrupt)
            else f"aborted: {type(exc).__name__}: {exc}"
        )
        safety_ramp = _ramp_to_zero(
            dev,
            plan,
            safety,
            _ramp_file(out, number, written, overwrite),
            t0=t0,
            realtime=realtime,
            fsync=fsync,
            priority=priority,
        )
        raise
    finally:
        doc = {
            "trial": plan.name,
            "file": plan.path,
            "description": plan.description,
            "device": dev.description,
            "realtime": bool(realtime or not dev.simulated),
            "sample_time": plan.sample_time,
            "end_status": end_status,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(started)),
            "elapsed": time.time() - started,
            "steps_planned": len(plan.steps),
            "steps_run": len(outcomes),
            "steps": [o.to_dict() for o in outcomes],
        }
        if safety_ramp is not None:
            doc["safety_ramp"] = safety_ramp
        tmp = summary.with_name(summary.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=2) + "\n")
        os.replace(tmp, summary)
    outcome = TrialOutcome(plan, dev.description, end_status, outcomes, str(summary))
    if interrupted is not None:
        raise TrialInterrupted(str(interrupted), outcome)
    return outcome


# ------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------
class _ProgressBar:
    """A text progress bar on stderr (carriage returns on a terminal, lines otherwise)."""

    def __init__(self, stream: Any = None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.last: tuple[int, int] = (-1, -1)
        self._open = False  # a terminal line without its newline yet

    def close(self) -> None:
        """End a pending terminal line (a step that stopped before 100 %)."""
        if self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False

    def __call__(self, done: int, planned: int, step: PlannedStep, number: int, total: int) -> None:
        frac = done / planned if planned else 1.0
        width = 30
        bar = "#" * int(frac * width) + "-" * (width - int(frac * width))
        text = (
            f"step {number}/{total} {step.name:<12} [{bar}] {100 * frac:5.1f}% "
            f"{done}/{planned} samples"
        )
        if self.tty:
            if self._open and number != self.last[0]:
                self.stream.write("\n")  # the previous step stopped short of 100 %
            self.last = (number, -1)
            self._open = done < planned
            self.stream.write("\r" + text + ("" if self._open else "\n"))
            self.stream.flush()
        else:
            quarter = int(frac * 4)
            if (number, quarter) != self.last:
                self.last = (number, quarter)
                self.stream.write(text + "\n")
                self.stream.flush()


def _cmd_check(args: argparse.Namespace) -> int:
    plan = check_trial(args.file)
    print(
        f"{plan.path}: OK - {plan.name!r}, {len(plan.steps)} step(s) on "
        f"{plan.device['kind']}, sample time {plan.sample_time:g} s"
    )
    u_now = 0.0
    for step in plan.steps:
        u, _ = step_waveform(plan, step, u_now)
        u_now = float(u[-1])
        print(
            f"  {step.index + 1:2d}. {step.kind:<11} {step.name:<16} "
            f"{u.size * plan.sample_time:8.3f} s "
            f"input {u.min():8.2f} .. {u.max():7.2f} V"
        )
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    bar = None if args.quiet else _ProgressBar()
    try:
        outcome = run_trial_file(
            args.file,
            args.output,
            device=args.device,
            realtime=args.realtime,
            overwrite=args.overwrite,
            priority=args.priority,
            progress=bar,
        )
    except TrialInterrupted as exc:
        if bar is not None:
            bar.close()
        out = exc.result
        if isinstance(out, TrialOutcome):
            print(
                f"preisach trial: interrupted; recordings and {out.summary_file} are complete "
                "up to the interrupt",
                file=sys.stderr,
            )
        return 130
    except KeyboardInterrupt:  # between steps, or before the device was opened
        if bar is not None:
            bar.close()
        print(
            f"preisach trial: interrupted (Ctrl-C); the recordings and summary.json written "
            f"to {args.output} are complete up to the interrupt",
            file=sys.stderr,
        )
        return 130
    if bar is not None:
        bar.close()
    for s in outcome.steps:
        r = s.result
        print(
            f"{s.file}: {r.end_status}, {r.samples} samples"
            + (f" (+{r.ramp_samples} ramp)" if r.ramp_samples else "")
            + (
                f", {r.missed_deadlines} missed deadlines, max lateness "
                f"{r.max_lateness * 1e6:.0f} us"
                if r.realtime
                else ""
            )
        )
    print(f"summary: {outcome.summary_file}")
    if not outcome.complete:
        last = outcome.steps[-1]
        print(
            f"preisach trial: error: step {last.index + 1} ({last.name}) {outcome.end_status}",
            file=sys.stderr,
        )
        return 1
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``preisach trial run|check`` on an argparse subparsers object."""
    p = subparsers.add_parser(
        "trial",
        help="run or check a scripted rig trial (TOML)",
        description="Scripted rig trials on the virtual SS15 or a Comedi card: one recording "
        "per step plus summary.json.",
    )
    sub = p.add_subparsers(dest="trial_command", metavar="ACTION", required=True)
    r = sub.add_parser(
        "run",
        help="run a trial file",
        description="Run a trial file; exits 1 with the reason when a step "
        "aborts, 130 when interrupted (the files are complete either way).",
    )
    r.add_argument("file", help="trial file (TOML)")
    r.add_argument("-o", "--output", required=True, help="output folder")
    r.add_argument(
        "--device",
        default=None,
        help="'sim' or 'comedi:/dev/comediN' (default: the file's [device] kind)",
    )
    r.add_argument(
        "--realtime",
        action="store_true",
        help="pace a simulated device in real time (a real one always is)",
    )
    r.add_argument("--overwrite", action="store_true", help="replace existing recordings")
    r.add_argument(
        "--priority",
        type=int,
        default=0,
        help="request SCHED_FIFO at this priority for the sample loop (default: no)",
    )
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_run)
    c = sub.add_parser(
        "check",
        help="validate a trial file without running it",
        description="Validate a trial file and its planned waveforms; names every error.",
    )
    c.add_argument("file", help="trial file (TOML)")
    c.set_defaults(func=_cmd_check)
    return p


def _main(argv: Sequence[str] | None = None) -> int:
    """``python -m preisach.trials run|check ...`` (the same as ``preisach trial``)."""
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_parser(sub)
    args = parser.parse_args(["trial", *(argv if argv is not None else sys.argv[1:])])
    try:
        return int(args.func(args))
    except (ValueError, OSError) as exc:
        print(f"preisach trial: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(_main())
