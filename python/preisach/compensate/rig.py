"""Identify a model from a device's own recorded sweep (for compensating that device).

The feedforward of a rig must come from the rig, not from the truth it simulates: this
plays the identification input of Fig 3.17 (a decaying sine to the anhysteretic state, then
a first-order-descending sweep at 1 Hz) on the device, records it, pairs ``u[k]`` with the
reading that follows it, and identifies a Mayergoyz model projected to non-negative weights.
"""

from __future__ import annotations

import os
import tempfile
from typing import Any

from ..model import PreisachModel

__all__ = ["identify_from_device"]


def identify_from_device(
    device: Any,
    *,
    sample_time: float = 1e-3,
    levels: int = 21,
    frequency: float = 1.0,
    record: str | os.PathLike[str] | None = None,
    safety: Any = None,
) -> tuple[PreisachModel, Any]:
    """Record an FOD sweep on ``device`` and identify a model from it.

    Parameters
    ----------
    device : VirtualRig or ComediDevice
        The device (input: actuator V, primary input: output V).
    sample_time : float
        Sample period (s).
    levels : int
        FOD levels of the sweep (21: the thesis's 10 V steps on +/-100 V).
    frequency : float
        One FOD curve per ``1 / frequency`` s.
    record : path, optional
        Keep the sweep's recording there (CSV); default a temporary file.
    safety : SafetyLimits, optional
        Limits of the trial.

    Returns
    -------
    (PreisachModel, IdentificationReport)
        The Mayergoyz model (``levels`` levels, projected to mu >= 0) and its report.

    """
    from ..daq import run_trial
    from ..identify import identify_fod
    from ..recording import Recording
    from ..waveforms import concatenate, decaying_sine, fod_sweep

    u = concatenate(
        decaying_sine(12.0, frequency, 100.0, sample_time=sample_time),
        fod_sweep(levels, frequency=frequency, sample_time=sample_time),
    ).u
    with tempfile.TemporaryDirectory(prefix="preisach-sweep-") as tmp:
        path = os.fspath(record) if record is not None else os.path.join(tmp, "sweep.csv")
        res = run_trial(
            device,
            u,
            path,
            sample_time=sample_time,
            safety=safety,
            metadata={"experiment": "fod_sweep"},
            overwrite=True,
            fsync=False,
        )
        if not res.complete:
            raise RuntimeError(f"{path}: the identification sweep ended early: {res.end_status}")
        rec = Recording.load(path)
    aligned = Recording.from_arrays(t=rec.t[:-1], u=rec.u[:-1], y=rec.y[1:], experiment="fod_sweep")
    report = identify_fod(aligned, project=True, name=f"Mayergoyz from the device, {levels} levels")
    return report.model, report
