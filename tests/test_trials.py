"""Scripted trials: checking files, running them on the virtual rig, the CLI, Ctrl-C."""

import argparse
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from preisach import Recording
from preisach.errors import TrialFileError
from preisach.identify import find_fod_curves
from preisach.trials import _main, add_parser, check_trial, load_trial, run_trial_file

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "trials"
KINDS = {"initialise", "fod_sweep", "wiping_out", "cml", "drive", "noise", "pi", "hold"}

HEAD = """
[trial]
sample_time = 0.001
[device]
kind = "sim"
[output]
name = "V_in"
channel = 1
range = [-10.0, 10.0]
calibration = "ss15-b"
[input]
name = "V_out"
channel = 1
range = [-5.0, 5.0]
"""


def write(tmp_path, text, name="t.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_every_example_checks(path):
    plan = check_trial(path)
    assert plan.steps


def test_examples_cover_every_step_kind():
    kinds = {s.kind for p in EXAMPLES.glob("*.toml") for s in load_trial(p).steps}
    assert kinds == KINDS


def test_check_names_every_error(tmp_path):
    bad = write(
        tmp_path,
        """
[trial]
sample_time = 0.001
[device]
kind = "sim"
modle = "ss15-1hz"
[output]
name = "V_in"
channel = 1
range = [-10.0, 10.0]
calibration = "ss15-c"
[safety]
u_limits = [-150.0, 100.0]
[[steps]]
kind = "fod_sweep"
frequncy = 1.0
[[steps]]
kind = "wiggle"
[[steps]]
kind = "drive"
target = "psi_x"
""",
    )
    with pytest.raises(TrialFileError) as info:
        check_trial(bad)
    msg = str(info.value)
    for part in (
        "[device]: unknown key 'modle' (did you mean 'model'?)",
        "[output]: calibration 'ss15-c' is unknown",
        "[input]: missing table",
        "[safety]: u_limits = [-150, 100] V exceed the SA11 amplifier's +/-135 V",
        "steps[0] (fod_sweep): unknown key 'frequncy' (did you mean 'frequency'?)",
        "steps[1]: kind 'wiggle' is unknown",
        "steps[2] (drive): target must be one of",
        "steps[2] (drive): give offset (V) or y_d",
    ):
        assert part in msg, part
    assert msg.count("\n") == 8  # one line per error


def test_check_planned_waveform_against_limits(tmp_path):
    p = write(
        tmp_path,
        HEAD
        + """
[safety]
u_limits = [-135.0, 90.0]
slew_rate = 500.0
[[steps]]
kind = "fod_sweep"
frequency = 4.0
[[steps]]
kind = "hold"
duration = 0.1
value = -20.0
""",
    )
    with pytest.raises(TrialFileError) as info:
        check_trial(p)
    msg = str(info.value)
    assert "steps[0] (fod_sweep): the planned input reaches" in msg
    assert "above the output limit u_max = 90 V" in msg
    assert "above the slew_rate limit 500 V/s" in msg
    assert "steps[1]" not in msg
    # a channel that cannot produce the planned input
    p2 = write(
        tmp_path,
        HEAD.replace("range = [-10.0, 10.0]", "range = [-5.0, 5.0]")
        + """
[[steps]]
kind = "hold"
duration = 1.0
value = 100.0
""",
        "t2.toml",
    )
    with pytest.raises(TrialFileError, match="what the output channel can produce"):
        check_trial(p2)


def test_fod_sweep_trial_feeds_the_fod_finder(tmp_path):
    out = run_trial_file(EXAMPLES / "fod_sweep.toml", tmp_path / "out")
    assert out.complete and [s.kind for s in out.steps] == ["initialise", "fod_sweep"]
    rec = Recording.load(out.steps[1].file)
    assert rec.metadata["experiment"] == "fod_sweep" and rec.metadata["end_status"] == "complete"
    # the time axis continues from the initialisation
    first = Recording.load(out.steps[0].file)
    assert rec.t[0] == pytest.approx(first.t[-1] + 1e-3)
    fod = find_fod_curves(rec)
    np.testing.assert_allclose(fod.levels, -100 + 10 * np.arange(21))
    assert len(fod.used_curves) == 20  # alpha = -90 ... 100
    lower = np.tril(np.ones((21, 21), bool))
    assert np.all(fod.count[lower] > 0)  # every node of all 21 FOD rows
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["end_status"] == "complete" and summary["steps_run"] == 2
    assert summary["steps"][1]["samples"] == len(rec) - rec.metadata["ramp_samples"]


def test_drive_and_pi_steps_on_the_virtual_rig(tmp_path):
    p = write(
        tmp_path,
        HEAD
        + """
[[steps]]
kind = "drive"
target = "psi_n"
y_d = 1.0
cycles = 4
hold = 0.5
[[steps]]
kind = "pi"
duration = 3.0
noise_gain = 1.6
noise_from = 1.5
noise_to = 2.5
""",
    )
    out = run_trial_file(p, tmp_path / "o")
    assert out.complete
    drive = Recording.load(out.steps[0].file)
    assert drive.y[-200:].mean() == pytest.approx(1.0, abs=0.05)
    pi = Recording.load(out.steps[1].file)
    n = pi.metadata["samples"]
    assert pi.y[n - 300 : n].mean() == pytest.approx(1.0, abs=0.01)  # regulated after the noise
    assert pi.metadata["ramp_samples"] > 0 and pi.u[-1] == 0.0  # the last step ramps to 0 V


def test_cli_exits_nonzero_with_the_reason_when_a_step_aborts(tmp_path, capsys):
    p = write(
        tmp_path,
        HEAD
        + """
[safety]
y_limits = [-5.0, 1.5]
[[steps]]
kind = "hold"
duration = 0.2
value = 0.0
[[steps]]
kind = "hold"
duration = 2.0
value = 100.0
[[steps]]
kind = "hold"
duration = 1.0
""",
    )
    parser = argparse.ArgumentParser(prog="preisach")
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["trial", "run", str(p), "-o", str(tmp_path / "o"), "-q"])
    assert args.func(args) == 1
    err = capsys.readouterr().err
    assert "preisach trial: error: step 2 (hold) aborted: input channel 'V_out' read" in err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["steps_run"] == 2 and summary["end_status"].startswith("aborted:")
    rec = Recording.load(tmp_path / "o" / "02_hold.csv")
    assert rec.metadata["end_status"].startswith("aborted: input channel")
    assert not (tmp_path / "o" / "03_hold.csv").exists()
    assert _main(["check", str(EXAMPLES / "cml.toml")]) == 0
    assert _main(["check", str(tmp_path / "missing.toml")]) == 1


def test_sigint_leaves_a_complete_contiguous_recording(tmp_path):
    # the machine is shared: no deadline budget, the test is about the interrupt
    p = write(
        tmp_path,
        HEAD
        + """
[safety]
max_consecutive_missed = -1
[[steps]]
kind = "hold"
duration = 60.0
value = 20.0
""",
    )
    out = tmp_path / "o"
    csv = out / "01_hold.csv"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "preisach.trials",
            "run",
            str(p),
            "-o",
            str(out),
            "--realtime",
            "-q",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        seen = 0
        deadline = time.monotonic() + 60
        while seen < 500 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
            if csv.exists():
                seen = sum(1 for line in csv.read_text().splitlines() if line and line[0].isdigit())
        assert seen >= 500, "the trial did not start writing"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert "interrupted" in err
    rec = Recording.load(csv)
    assert rec.metadata["end_status"] == "interrupted"
    n = rec.metadata["samples"]
    assert seen <= n < 60_000 and len(rec) == n + rec.metadata["ramp_samples"]
    np.testing.assert_allclose(rec.t, np.arange(len(rec)) * 1e-3, atol=1e-9)  # contiguous
    assert np.all(rec.u[:n][-10:] == pytest.approx(20.0)) and rec.u[-1] == 0.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["end_status"] == "interrupted"
