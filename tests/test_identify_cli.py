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
    with pytest.raises(SystemExit) as exc:
        run(["identify", files["fod_sweep"]])  # -o is required: argparse usage error
    assert exc.value.code == 2
