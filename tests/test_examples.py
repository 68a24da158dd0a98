"""Every script in examples/ runs as is, says what it wrote, and wrote what it says."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from preisach import PreisachModel, Recording, load_model
from preisach.waveforms import fod_sweep

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))
# The examples' linear algebra is small; a threaded BLAS only spins on a busy 2-core machine
# (measured: diagnosis 3 s single-threaded vs 40 s threaded at load 4).
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
TASKS = {"identify_from_csv", "simulate", "drift_sweep", "virtual_rig_trial", "diagnose"}


def _run(script, cwd, *args):
    r = subprocess.run(
        [sys.executable, str(script), *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin", "HOME": str(cwd), **ONE_BLAS_THREAD},
    )
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def _check_identify_from_csv(out, d):
    m = PreisachModel.load(d / "identified.npz")
    assert m.levels.size == 21 and (m.u_min, m.u_max) == (-100.0, 100.0)
    rec = Recording.load(d / "fod_sweep.csv")
    assert rec.metadata["experiment"] == "fod_sweep" and rec.u.size == 20001
    pct = float(re.search(r"CML test predicted: .*\(([\d.]+) % of", out).group(1))
    assert pct < 1.0


def _check_simulate(out, d):
    assert (d / "simulate.png").stat().st_size > 10_000


def _check_drift_sweep(out, d):
    rows = (d / "drift_sweep.csv").read_text().splitlines()
    assert len(rows) == 1 + 3 * 3 * 7 * 5  # frequencies x states x gains x seeds
    assert out.count("|drift(psi_n)| smallest at 7/7 gains") == 3


def _check_virtual_rig_trial(out, d):
    summary = json.loads((d / "trial_out" / "summary.json").read_text())
    assert summary["end_status"] == "complete" and summary["steps_run"] == 2
    m = PreisachModel.load(d / "virtual_rig_model.npz")
    np.testing.assert_allclose(m.levels, np.linspace(-100, 100, 21))


def _check_diagnose(out, d):
    truth = json.loads((d / "case" / "truth.json").read_text())
    report = json.loads((d / "diagnosis.json").read_text())
    assert report["verdict"] == truth["kind"] == "delay"
    assert report["rmse_after"] < report["rmse_before"]
    assert load_model(d / "augmented.npz") is not None


def _check_compensate(out, d):
    runs = {
        (r["reference"], r["mode"]): r
        for r in json.loads((d / "tracking.json").read_text())["runs"]
    }
    ff, lin = runs[("sine-1Hz", "feedforward")], runs[("sine-1Hz", "uncompensated")]
    assert ff["max_error_pct"] <= 1.0 and 10 * ff["max_error_pct"] <= lin["max_error_pct"]


CHECKS = {
    "compensate": _check_compensate,
    "identify_from_csv": _check_identify_from_csv,
    "simulate": _check_simulate,
    "drift_sweep": _check_drift_sweep,
    "virtual_rig_trial": _check_virtual_rig_trial,
    "diagnose": _check_diagnose,
}


def test_there_is_an_example_per_task():
    assert {p.stem for p in EXAMPLES} >= TASKS
    assert set(CHECKS) >= {p.stem for p in EXAMPLES}, "add a check for the new example"


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    out = _run(script, tmp_path)
    wrote = [ln for ln in out.splitlines() if ln.startswith("wrote ")]
    assert wrote, "an example says what it wrote"
    for name in re.findall(r"[\w./-]+\.(?:png|npz|csv|json)", wrote[-1]):
        assert (tmp_path / name).is_file(), f"{script.name} says it wrote {name}"
    CHECKS[script.stem](out, tmp_path)


def test_identify_from_a_given_csv(tmp_path):
    """The CSV path given on the command line is what gets identified (here a 2 Hz device)."""
    m2 = PreisachModel.builtin("ss15-2hz")
    t, u = fod_sweep(11, frequency=2.0, sample_time=1e-3)
    y = m2.simulate(u, m2.negative_saturation()).output
    Recording.from_arrays(t=t, u=u, y=y, sample_time=1e-3, experiment="mine").save(
        tmp_path / "mine.csv"
    )
    out = _run(EXAMPLES[0].parent / "identify_from_csv.py", tmp_path, "mine.csv")
    assert "loaded mine.csv" in out and not (tmp_path / "fod_sweep.csv").exists()
    m = PreisachModel.load(tmp_path / "identified.npz")
    assert m.levels.size == 11
    assert m.y_max == pytest.approx(m2.y_max, abs=1e-9)
