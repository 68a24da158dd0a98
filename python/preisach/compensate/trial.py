"""The ``track`` step of scripted trials: a reference output through a feedforward model.

A step ``{kind = "track", feedforward = "model.npz", reference = "ref.csv", state =
"negative"}`` plays, in the C++ trial loop and under the trial's safety limits, a ramp of the
input to the saturation named by ``state`` with a 0.1 s hold (the device is then in that
state whatever came before), followed by the exact inverse of the model for the reference
computed from that state.  The reference's sample spacing must be the trial's sample time.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["track_waveform"]


def track_waveform(
    p: Mapping[str, Any], sample_time: float
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Plan the drive (V) of a ``track`` step; returns ``(u, info)``.

    ``info`` has ``unreachable`` (targets the model cannot reach), ``frame_samples`` (the
    ramp and hold before the reference) and ``reference_samples``.

    Raises
    ------
    ValueError
        If the model or the reference cannot be read, or the reference's sample spacing is
        not ``sample_time``.

    """
    from ..model import BUILTIN_MODELS, PreisachModel
    from .reference import read_reference

    name = str(p["feedforward"])
    model = (
        PreisachModel.builtin(name.lower())
        if name.lower() in BUILTIN_MODELS
        else PreisachModel.load(name)
    )
    t, y, _ = read_reference(str(p["reference"]))
    if t.size > 1 and not np.allclose(np.diff(t), sample_time, rtol=1e-6, atol=1e-12):
        raise ValueError(
            f"{p['reference']}: sample spacing {np.median(np.diff(t)):g} s differs from the "
            f"trial's sample_time {sample_time:g} s"
        )
    negative = p["state"] == "negative"
    u_sat = model.u_min if negative else model.u_max
    state = model.negative_saturation() if negative else model.positive_saturation()
    frame = np.r_[
        np.linspace(0.0, u_sat, max(int(round(0.3 / sample_time)), 2)),
        np.full(max(int(round(0.1 / sample_time)), 1), u_sat),
    ]
    r = model.inverse(y, state)
    info = {
        "unreachable": r.unreachable,
        "frame_samples": int(frame.size),
        "reference_samples": int(y.size),
    }
    return np.r_[frame, r.input], info
