"""The preisach command line, and ``preisach demo`` (README command 1) end to end."""

import contextlib
import io
import json
import re
import subprocess
import sys

import pytest
from preisach import PreisachModel, Recording
from preisach.cli import main

STAGE = re.compile(r"^\[(\d)/5\] .+ \.\.\. .*\((\d+\.\d) s\)$")


SLOW = pytest.mark.slow  # the demo runs once for these tests (about 15-40 s)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """Run the demo once with its defaults (as README command 1 does)."""
    out = tmp_path_factory.mktemp("demo") / "out"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["demo", "-o", str(out)])
    return code, out, buf.getvalue()


@SLOW
def test_demo_prints_one_line_per_stage_and_where_the_report_is(demo):
    code, out, text = demo
    assert code == 0
    stages = [m for m in (STAGE.match(ln) for ln in text.splitlines()) if m]
    assert [int(m.group(1)) for m in stages] == [1, 2, 3, 4, 5]
    assert f"wrote {out / 'report.md'}" in text


@SLOW
def test_demo_report_embeds_existing_figures(demo):
    _, out, _ = demo
    md = (out / "report.md").read_text(encoding="utf-8")
    for k, title in enumerate(
        ["Identification sweep", "Identified model", "Verification", "Neutral states", "Diagnosis"],
        1,
    ):
        assert f"## {k}. {title}" in md
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(figures) >= 9
    for name in figures:
        png = out / name
        assert png.exists(), name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert png.stat().st_size > 10_000


@SLOW
def test_demo_key_numbers(demo):
    _, out, _ = demo
    key = json.loads((out / "report.json").read_text())
    md = (out / "report.md").read_text(encoding="utf-8")
    # Table 3.1's 1 Hz column is printed beside the identified surface, which is close to it
    assert "8.81e-06" in md and "-1.94e+02" in md
    assert key["surface"]["x9"] == pytest.approx(-194.0, rel=0.1)
    assert key["surface"]["y_max"] == pytest.approx(3.49, abs=0.02)
    # identified from a noisy rig recording, other experiments predicted within 1 % of range
    assert key["fod_curves"] == 20
    assert max(key["verification_max_pct"].values()) < 1.0
    # chapters 4-5: psi_n drifts least and needs least control effort at every gain
    assert key["drift_n_smallest"] == "7/7" and key["effort_n_smallest"] == "7/7"
    assert all(p > 0 for p in key["table_5_1_percent"]["a"] + key["table_5_1_percent"]["d"])
    # the concealed effect is named, and the held-out error drops
    d = key["diagnosis"]
    assert d["verdict"] == d["truth"] == "structural_resonance"
    assert d["rmse_after_mV"] < 0.7 * d["rmse_before_mV"]
    assert f"**Verdict: `{d['verdict']}`**" in md


@SLOW
def test_demo_leaves_recordings_and_models_that_load(demo):
    _, out, _ = demo
    for name in ("fod_sweep", "wiping_out", "cml", "multisine"):
        rec = Recording.load(out / "recordings" / f"{name}.csv")
        assert rec.metadata["end_status"] == "complete" and rec.metadata["experiment"] == name
    for name in ("model_mayergoyz", "model_surface"):
        m = PreisachModel.load(out / f"{name}.npz")
        assert (m.u_min, m.u_max) == (-100.0, 100.0)
    diag = json.loads((out / "diagnosis.json").read_text())
    # the schema, plus the noise test behind none/unexplained, the refit base's
    # grid choice and the candidate table (issue 13)
    assert set(diag) == {
        "verdict",
        "effects",
        "rmse_before",
        "rmse_after",
        "noise_sigma",
        "noise_test",
        "unexplained",
        "base_grid",
        "candidates",
    }


def test_demo_rejects_bad_options(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "x"), "--seeds", "1"]) == 1
    assert "--seeds" in capsys.readouterr().err


def test_help_and_missing_command(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "demo" in capsys.readouterr().out
    assert main([]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--help"])
    assert exc.value.code == 0
    assert "virtual SS15" in capsys.readouterr().out


def test_console_script_entry_point():
    r = subprocess.run(
        [sys.executable, "-m", "preisach.cli", "--help"], capture_output=True, text=True
    )
    assert r.returncode == 0 and "demo" in r.stdout


def test_verify_with_a_bad_model_file_prints_an_error_not_a_traceback(tmp_path, capsys):
    import numpy as np

    rec = tmp_path / "rec.csv"
    Recording.from_arrays(u=np.linspace(-100.0, 100.0, 50), y=np.zeros(50), sample_time=1e-3).save(
        rec
    )
    good = tmp_path / "good.npz"
    PreisachModel.builtin(levels=11).save(good)
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "truncated.npz").write_bytes(good.read_bytes()[:300])
    d = dict(np.load(good))
    del d["version"]
    np.savez(tmp_path / "noversion.npz", **d)
    for name in ("empty.npz", "truncated.npz", "noversion.npz"):
        assert main(["verify", str(tmp_path / name), str(rec)]) == 1
        err = capsys.readouterr().err
        assert err.startswith("preisach verify: error: ") and name in err
        assert "Traceback" not in err
