"""Trial steps as waveforms: what each step will send to the actuator, and the checks.

:func:`step_waveform` plans one step's actuator voltages; :func:`check_trial` plans every
step of a file and checks them against the safety limits and the output channel's range.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..model import BUILTIN_MODELS, PreisachModel
from .schema import _TARGETS, PlannedStep, TrialPlan, _Errors, _parse, _read


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
    from ..noise import uniform_filtered_noise

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
    from .. import waveforms as wf

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
    elif step.kind == "track":
        from ..compensate.trial import track_waveform

        u, info = track_waveform(p, ts)
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
    from ..experiments import ModelPlant, drive_to_state
    from ..experiments.initialisation import branch_input, neutral_input

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
    models = {st.params["model"] for st in plan.steps if st.params.get("model")}
    if plan.device.get("kind") == "sim":
        models.add(plan.device.get("model") or "ss15-1hz")
    for name in sorted(models):  # what run would load: a built-in name or a model file
        try:
            _load_model(name)
        except (ValueError, OSError) as exc:
            errors.add(
                "[device]" if name == plan.device.get("model") else "steps",
                f"model {name!r} is neither a built-in model ({', '.join(BUILTIN_MODELS)}) "
                f"nor a readable model file ({exc})",
            )
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
