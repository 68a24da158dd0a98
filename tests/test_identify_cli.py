"""`preisach identify` and `preisach verify` (preisach.identify.cli.add_parser).

The commands are registered on a parser built here exactly as preisach.cli.main does (its
subparsers, ValueError/OSError -> "preisach CMD: error: ..." and exit status 1), so these tests
do not depend on the wiring in preisach.cli.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import pytest
from preisach import PreisachModel, Recording
from preisach.identify.cli import add_parser
from preisach.waveforms import cml_input, fod_sweep, wiping_out_input


def run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    add_parser(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except (ValueError, OSError) as exc:
        print(f"preisach {args.command}: error: {exc}", file=sys.stderr)
        return 1


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    truth = PreisachModel.builtin("ss15-4hz", levels=101)
    rng = np.random.default_rng(0)
    out = {}
    for sig in (fod_sweep(frequency=4.0), wiping_out_input(4.0), cml_input(4.0)):
        y = truth.simulate(sig.u, truth.negative_saturation()).output + rng.normal(
            0, 1e-3, sig.u.size
        )
        path = d / f"{sig.name}.csv"
        Recording.from_arrays(u=sig.u, y=y, sample_time=1e-3, experiment=sig.name).save(path)
        out[sig.name] = str(path)
    out["dir"] = d
    return out


@pytest.mark.parametrize("method", ["fod", "surface", "lsq"])
def test_identify_writes_a_loadable_model_and_prints_the_report(files, capsys, method):
    model_path = files["dir"] / f"{method}.npz"
    argv = ["identify", files["fod_sweep"], "-o", str(model_path), "--method", method]
    if method == "lsq":
        argv += ["--levels", "21", "--folds", "3"]
    assert run(argv) == 0
    out = capsys.readouterr().out
    assert "identification:" in out and f"wrote {model_path}" in out and "fod_sweep" in out
    model = PreisachModel.load(model_path)
    assert model.u_min == -100.0 and model.u_max == 100.0
    assert run(["verify", str(model_path), files["wiping_out"], files["cml"]]) == 0
    table = capsys.readouterr().out
    assert "wiping_out" in table and "cml" in table
    pct = [
        float(line.split()[-2]) for line in table.splitlines() if line.startswith(("wiping", "cml"))
    ]
    assert max(pct) < 1.0


def test_identify_and_verify_write_json_and_figures(files, capsys):
    m = files["dir"] / "proj.npz"
    rj, rp = files["dir"] / "report.json", files["dir"] / "report.png"
    assert (
        run(
            [
                "identify",
                files["fod_sweep"],
                "-o",
                str(m),
                "--project",
                "--name",
                "ss15 4 Hz",
                "--json",
                str(rj),
                "--plot",
                str(rp),
            ]
        )
        == 0
    )
    report = json.loads(rj.read_text())
    assert report["method"] == "fod" and report["projection"]["kept"] == "y_min and y_max"
    assert report["negative_cells"] == 0
    assert rp.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert PreisachModel.load(m).name == "ss15 4 Hz"
    vj, vp = files["dir"] / "verify.json", files["dir"] / "verify.png"
    assert (
        run(
            [
                "verify",
                str(m),
                files["wiping_out"],
                files["cml"],
                "--properties",
                "--json",
                str(vj),
                "--plot",
                str(vp),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "wiping-out test" in out and "congruent minor loop test" in out and "PASS" in out
    v = json.loads(vj.read_text())
    assert [r["experiment"] for r in v["rows"]] == ["wiping_out", "cml"]
    assert v["properties"][0]["wiping_out"]["passed"] is True
    assert vp.exists()


def test_bad_input_exits_1_with_a_clear_message(files, tmp_path, capsys):
    assert run(["identify", str(tmp_path / "missing.csv"), "-o", str(tmp_path / "m.npz")]) == 1
    assert "preisach identify: error:" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("t,u,y\n0,1,2\n0.001,x,3\n")
    assert run(["identify", str(bad), "-o", str(tmp_path / "m.npz")]) == 1
    err = capsys.readouterr().err
    assert "bad.csv" in err and "line 3" in err
    assert (
        run(
            [
                "identify",
                files["fod_sweep"],
                "-o",
                str(tmp_path / "m.npz"),
                "--method",
                "lsq",
                "--project",
            ]
        )
        == 1
    )
    assert "--project applies to --method fod only" in capsys.readouterr().err
    assert (
        run(["identify", files["fod_sweep"], "-o", str(tmp_path / "m.npz"), "--levels", "2"]) == 1
    )
    assert "--levels" in capsys.readouterr().err
    assert run(["identify", files["fod_sweep"], "-o", str(tmp_path / "no" / "m.npz")]) == 1
    assert "does not exist" in capsys.readouterr().err
    assert run(["verify", files["cml"], files["cml"]]) == 1
    assert "not a" in capsys.readouterr().err
    # a CSV with a header and no rows
    header_only = tmp_path / "header_only.csv"
    header_only.write_text("t,u,y\n")
    assert run(["identify", str(header_only), "-o", str(tmp_path / "m.npz")]) == 1
    err = capsys.readouterr().err
    assert "header_only.csv" in err and "at least 2 samples, got 0" in err
    fod_model = tmp_path / "fod.npz"
    assert run(["identify", files["fod_sweep"], "-o", str(fod_model)]) == 0
    capsys.readouterr()
    assert run(["verify", str(fod_model), str(header_only)]) == 1
    assert "header_only.csv" in capsys.readouterr().err
    # --levels is capped for the FOD grid methods (the grid costs levels^2)
    for method in ("fod", "surface"):
        argv = ["identify", files["fod_sweep"], "-o", str(tmp_path / "m.npz"), "--method", method]
        assert run([*argv, "--levels", "202"]) == 1
        err = capsys.readouterr().err
        assert "levels: at most 201 levels for an FOD grid" in err and "got 202" in err
    assert not (tmp_path / "m.npz").exists()
    # --y-min-source belongs to the surface method
    assert run([*argv[:-2], "--method", "fod", "--y-min-source", "corner"]) == 1
    assert "--y-min-source applies to --method surface only" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        run(["identify", files["fod_sweep"]])  # -o is required: argparse usage error
    assert exc.value.code == 2


def test_identify_surface_y_min_source(files, capsys):
    models = {}
    for source in ("column_mean", "corner", None):
        path = files["dir"] / f"surface_{source}.npz"
        argv = ["identify", files["fod_sweep"], "-o", str(path), "--method", "surface"]
        if source is not None:
            argv += ["--y-min-source", source]
        assert run(argv) == 0
        capsys.readouterr()
        models[source] = PreisachModel.load(path)
    assert models[None] == models["column_mean"]  # the default
    assert models[None].metadata["y_min_source"] == "column_mean"
    assert models["corner"].metadata["y_min_source"] == "corner"
    assert models["corner"].y_min != models["column_mean"].y_min
    truth = PreisachModel.builtin("ss15-4hz", levels=101)
    for m in models.values():
        assert abs(m.y_min - truth.y_min) < 5e-3  # 1 mV noise


def test_verify_reports_inputs_outside_the_model_range(files, tmp_path, capsys):
    model_path = tmp_path / "narrow.npz"
    PreisachModel.builtin("ss15-4hz", levels=41).save(model_path)
    u = np.r_[np.linspace(-100.0, 110.0, 300), np.linspace(110.0, -100.0, 300)]
    rec = tmp_path / "overdriven.csv"
    Recording.from_arrays(u=u, y=np.sin(u / 50.0), sample_time=1e-3).save(rec)
    assert run(["verify", str(model_path), str(rec), files["cml"]]) == 0
    captured = capsys.readouterr()
    n_out = int(np.count_nonzero(u > 100.0))
    assert f"preisach verify: warning: overdriven: {n_out} of 600 input samples" in captured.err
    rows = {ln.split()[0]: ln.split() for ln in captured.out.splitlines()[3:]}
    assert rows["overdriven"][1:3] == ["600", str(n_out)] and rows["cml"][2] == "0"


def test_identify_interpolation_is_chosen_or_forced_and_stored(files, capsys):
    auto, forced = files["dir"] / "auto.npz", files["dir"] / "bilinear.npz"
    assert run(["identify", files["fod_sweep"], "-o", str(auto), "--method", "fod"]) == 0
    out = capsys.readouterr().out
    assert "interpolation between the nodes:" in out
    m = PreisachModel.load(auto)
    choice = m.metadata["interpolation"]
    assert m.interpolation == choice["interpolation"]
    best = "cubic" if choice["rms_cubic"] <= 0.9 * choice["rms_bilinear"] else "bilinear"
    assert m.interpolation == best
    argv = ["identify", files["fod_sweep"], "-o", str(forced), "--interpolation", "bilinear"]
    assert run(argv) == 0
    assert PreisachModel.load(forced).interpolation == "bilinear"
    capsys.readouterr()
    bad = ["identify", files["fod_sweep"], "-o", str(forced), "--method", "lsq"]
    assert run([*bad, "--levels", "11", "--interpolation", "cubic"]) == 1
    assert "applies to the fod method only" in capsys.readouterr().err
