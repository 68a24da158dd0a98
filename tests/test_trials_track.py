"""The ``track`` trial step: a reference output through a feedforward model, in the C++ loop."""

from __future__ import annotations

import numpy as np
import pytest
from _trial_files import sim_head
from preisach import PreisachModel, Recording
from preisach.errors import TrialFileError
from preisach.trials import check_trial, run_trial_file

TRIAL = (
    sim_head("track", model="ss15-1hz", seed=2)
    + """
[[steps]]
kind = "track"
feedforward = "{model}"
reference = "{ref}"
state = "{state}"
"""
)


@pytest.fixture
def files(tmp_path):
    model = PreisachModel.builtin("ss15-1hz")  # the rig's truth: the feedforward is exact
    model.save(tmp_path / "m.npz")
    t = np.arange(1500) * 1e-3
    y = model.y_min + 0.35 * (model.y_max - model.y_min) * (1 - np.cos(2 * np.pi * t))  # from y_min
    ref = tmp_path / "ref.csv"
    ref.write_text("t,y\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), y.tolist())))
    return tmp_path, model, y


def write_trial(d, state="negative"):
    path = d / "track.toml"
    path.write_text(TRIAL.format(model=d / "m.npz", ref=d / "ref.csv", state=state))
    return path


def test_track_step_follows_the_reference_on_the_virtual_rig(files):
    d, model, y = files
    out = run_trial_file(write_trial(d), d / "out", fsync=False)
    assert out.end_status == "complete"
    step = out.steps[0]
    assert step.info["unreachable"] == 0
    rec = Recording.load(step.file)
    k0 = step.info["approach_samples"] + step.info["frame_samples"]
    # y[k+1] is the reading after u[k] (clocked loop); ADC noise 0.5 mV, 14 bits
    got = rec.y[k0 + 1 : k0 + 1 + y.size]
    span = model.y_max - model.y_min
    assert np.max(np.abs(got - y[: got.size])) < 0.005 * span


def test_track_step_is_checked(files):
    d, _, _ = files
    with pytest.raises(TrialFileError, match="state must be"):
        check_trial(write_trial(d, state="sideways"))
    (d / "ref.csv").write_text("t,y\n0.0,0.0\n0.002,0.1\n0.004,0.2\n")
    with pytest.raises(TrialFileError, match="sample spacing"):
        check_trial(write_trial(d))
