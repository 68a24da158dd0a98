"""Scripted trials: checking files, running them on the virtual rig, the CLI, Ctrl-C."""

import argparse
import io
import json
import signal
from pathlib import Path

import numpy as np
import pytest
from _trial_files import ANY_MISSED, SIM_HEAD, start_realtime_run, wait_for_rows
from preisach import Recording, trials
from preisach.errors import TrialFileError
from preisach.identify import find_fod_curves
from preisach.trials import _main, add_parser, check_trial, load_trial, run_trial_file

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "trials"
KINDS = {"initialise", "fod_sweep", "wiping_out", "cml", "drive", "noise", "pi", "hold"}

HEAD = SIM_HEAD


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
ramp_rate = 20000.0
[[steps]]
kind = "fod_sweep"
frequncy = 1.0
[[steps]]
kind = "wiggle"
[[steps]]
kind = "drive"
target = "psi_x"
[[steps]]
kind = "hold"
duration = 0.1
value = 120.0
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
        "[safety]: ramp_rate = 20000 V/s exceeds slew_rate = 10000 V/s",
        # the clean step's waveform is still checked against the limits that parsed
        "steps[3] (hold): the planned input reaches 100.2 V at t = 0.5 s (from the step's "
        "start), above the output limit u_max = 100 V",  # on its approach ramp at 200 V/s
    ):
        assert part in msg, part
    assert msg.count("\n") == 10 and "10 error(s)" in msg  # one line per error
    assert "steps[0] (fod_sweep): the planned" not in msg  # steps that did not parse


def test_wrong_types_and_missing_keys_are_reported_not_crashed_on(tmp_path):
    p = write(
        tmp_path,
        HEAD
        + """
[safety]
u_limits = "wide"
slew_rate = "fast"
max_consecutive_missed = 0
[[steps]]
kind = "drive"
offset = 10.0
[[steps]]
kind = "hold"
duration = 0.1
value = 140.0
""",
    )
    with pytest.raises(TrialFileError) as info:  # was a KeyError on 'u_limits' / 'target'
        check_trial(p)
    msg = str(info.value)
    for part in (
        "[safety]: u_limits must be an array, got 'wide'",
        "[safety]: slew_rate must be a number, got 'fast'",
        "[safety]: max_consecutive_missed must be >= 1 (or < 0 for no limit), got 0",
        "steps[0] (drive): missing required key 'target'",
        # checked against the defaults in place of the invalid limits: +/-135 V
        "steps[1] (hold): the planned input reaches 135.2 V",
    ):
        assert part in msg, part
    assert "5 error(s)" in msg


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
    assert args.func(args) == 3  # EXIT_FAILED: the command ran but could not finish
    err = capsys.readouterr().err
    assert "preisach trial: error: step 2 (hold) aborted: input channel 'V_out' read" in err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["steps_run"] == 2 and summary["end_status"].startswith("aborted:")
    rec = Recording.load(tmp_path / "o" / "02_hold.csv")
    assert rec.metadata["end_status"].startswith("aborted: input channel")
    assert not (tmp_path / "o" / "03_hold.csv").exists()
    assert _main(["check", str(EXAMPLES / "cml.toml")]) == 0
    assert _main(["check", str(tmp_path / "missing.toml")]) == 1


STOP_BETWEEN_STEPS = (
    HEAD
    + """
[safety]
ramp_rate = 1000.0
[[steps]]
kind = "hold"
duration = 0.2
value = 50.0
[[steps]]
kind = "hold"
duration = 1.0
"""
)


def _planning_fails(monkeypatch, exc):
    """Make planning step 2 raise ``exc`` at run time (check_trial is skipped)."""
    real = trials.step_waveform

    def plan(plan, step, u_now):
        if step.index == 1:
            raise exc
        return real(plan, step, u_now)

    monkeypatch.setattr(trials.run, "check_trial", trials.load_trial)
    monkeypatch.setattr(trials.run, "step_waveform", plan)


def _check_safety_ramp(out, status):
    summary = json.loads((out / "summary.json").read_text())
    assert summary["end_status"] == status and summary["steps_run"] == 1
    step1 = Recording.load(out / "01_hold.csv")
    assert step1.metadata["end_status"] == "complete" and step1.u[-1] == pytest.approx(50.0)
    ramp = Recording.load(out / "02_ramp.csv")  # the same runner: logged and slew limited
    assert ramp.metadata["experiment"] == "safety_ramp"
    assert ramp.metadata["end_status"] == "complete"
    assert ramp.t[0] == pytest.approx(step1.t[-1] + 1e-3)  # the time axis continues
    np.testing.assert_allclose(np.diff(np.concatenate([[50.0], ramp.u])), -1.0)  # 1000 V/s
    assert ramp.u[-1] == 0.0 and ramp.metadata["final_output"] == 0.0
    assert summary["safety_ramp"]["file"] == str(out / "02_ramp.csv")
    assert summary["safety_ramp"]["from"] == pytest.approx(50.0)
    assert summary["safety_ramp"]["final_output"] == 0.0
    assert not (out / "02_hold.csv").exists()


def test_error_between_steps_ramps_down_and_writes_the_summary(tmp_path, monkeypatch):
    _planning_fails(monkeypatch, RuntimeError("planner exploded"))
    p = write(tmp_path, STOP_BETWEEN_STEPS)
    with pytest.raises(RuntimeError, match="planner exploded"):
        run_trial_file(p, tmp_path / "o")
    _check_safety_ramp(tmp_path / "o", "aborted: RuntimeError: planner exploded")


def test_ctrl_c_between_steps_exits_130_after_the_ramp(tmp_path, monkeypatch, capsys):
    _planning_fails(monkeypatch, KeyboardInterrupt())
    p = write(tmp_path, STOP_BETWEEN_STEPS)
    parser = argparse.ArgumentParser(prog="preisach")
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["trial", "run", str(p), "-o", str(tmp_path / "o"), "-q"])
    try:
        status = args.func(args)
    except KeyboardInterrupt:
        pytest.fail("the KeyboardInterrupt escaped 'preisach trial run'")
    assert status == 130
    err = capsys.readouterr().err
    assert err.startswith("preisach trial: interrupted (Ctrl-C)") and err.count("\n") == 1
    assert "Traceback" not in err
    _check_safety_ramp(tmp_path / "o", "interrupted")


def test_progress_bar_reports_every_step_up_to_100_percent(tmp_path, capsys):
    p = write(
        tmp_path,
        HEAD
        + """
[[steps]]
kind = "hold"
name = "first"
duration = 0.3
value = 10.0
[[steps]]
kind = "hold"
name = "second"
duration = 0.2
""",
    )
    assert _main(["run", str(p), "-o", str(tmp_path / "o")]) == 0
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.startswith("step ")]
    assert lines, f"no progress output on stderr: {captured.err!r}"
    firsts = [line for line in lines if line.startswith("step 1/2 first")]
    seconds = [line for line in lines if line.startswith("step 2/2 second")]
    assert firsts and seconds and lines.index(firsts[-1]) < lines.index(seconds[0])
    # off a terminal: plain lines (no carriage returns), each step's last one at 100 %
    # (0.3 s at 10 V after a 50-sample approach from 0 V at 200 V/s)
    assert "\r" not in captured.err
    assert "100%" in firsts[-1] and "350/350" in firsts[-1]
    assert lines[-1].startswith("step 2/2 second: 100%") and "200/200" in lines[-1]
    assert "summary:" in captured.out

    # on a terminal: one bar per step, redrawn with carriage returns, ended at 100 %
    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    bar = trials._ProgressBar(stream)
    step = trials.PlannedStep(0, "hold", "h", {})
    for done in (0, 50, 100):
        bar(done, 100, step, 1, 1)
    bar.close()
    text = stream.getvalue()
    assert text.startswith("\rstep 1/1 h:") and "\n" not in text[:-1]
    assert text.endswith("\n") and "100/100" in text.rsplit("\r", 1)[1]
    # a step that stops short is ended with a newline too
    stream = Tty()
    bar = trials._ProgressBar(stream)
    bar(40, 100, step, 1, 1)
    bar.close()
    assert stream.getvalue().endswith("\n") and "40/100" in stream.getvalue().rsplit("\r", 1)[1]


def test_sigint_leaves_a_complete_contiguous_recording(tmp_path):
    # the machine is shared: no deadline budget, the test is about the interrupt
    p = write(
        tmp_path,
        HEAD
        + ANY_MISSED
        + """
[[steps]]
kind = "hold"
duration = 60.0
value = 20.0
""",
    )
    out = tmp_path / "o"
    csv = out / "01_hold.csv"
    proc = start_realtime_run(p, out)
    try:
        seen = wait_for_rows(proc, csv, 500)
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
