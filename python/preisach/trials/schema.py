"""Trial files: the schema (sections, keys, types, defaults), parsing and validation.

:func:`load_trial` reads a TOML trial file into a :class:`TrialPlan`, reporting every
structural problem at once; :func:`preisach.trials.check_trial` adds the waveform checks.
"""

from __future__ import annotations

import difflib
import math
import os
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from .. import daq
from ..daq.calibration import SS15_CHANNEL_A, SS15_CHANNEL_B, SS15_INPUT_GAIN, LinearCalibration
from ..errors import TrialFileError

if sys.version_info >= (3, 11):  # pragma: no cover - version dependent
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

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
    # feedforward: the drive is the exact inverse of `feedforward` (a model file) for the output
    # reference `reference` (CSV with t,y), after a ramp to the start state (preisach.compensate)
    "track": {
        "feedforward": (str, REQUIRED),
        "reference": (str, REQUIRED),
        "state": (str, "negative"),
    },
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
        from ..daq.blocks import make_block

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
        if not isinstance(kind, str) or kind not in STEP_KINDS:  # a list is no kind (unhashable)
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
        if "target" in p and not (isinstance(p["target"], str) and p["target"] in _TARGETS):
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
    if kind == "track" and p["state"] not in ("negative", "positive"):
        errors.add(where, f"state must be 'negative' or 'positive', got {p['state']!r}")
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
