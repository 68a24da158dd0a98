"""``preisach experiment drift|closed-loop|locus`` through its add_parser."""

from __future__ import annotations

import argparse
import csv
import json

import pytest
from preisach import PreisachModel
from preisach.experiments.cli import add_parser


def run(argv: str | list[str]) -> int:
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command")
    add_parser(sub)
    args = parser.parse_args(argv.split() if isinstance(argv, str) else argv)
    return int(args.func(args))


def test_locus_writes_json_and_figure(tmp_path, capsys):
    out, fig = tmp_path / "locus.json", tmp_path / "locus.png"
    assert run(f"experiment locus --model ss15 --points 101 --json {out} --plot {fig}") == 0
    data = json.loads(out.read_text())
    assert [m["model"] for m in data["models"]] == ["ss15-1hz", "ss15-2hz", "ss15-4hz"]
    m1 = data["models"][0]
    assert len(m1["l"]) == 101 and m1["monotone"] and m1["mp"]["in_mp"]
    assert m1["l_inverse"] == pytest.approx(25.8475, abs=1e-3)
    assert m1["method"].startswith("2.19")
    assert m1["slopes_at_neutral"]["dy_du_rising"] == pytest.approx(0.02941, abs=1e-5)
    assert not data["models"][1]["mp"]["in_mp"]
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "N_inv(1 V)" in text and "dy/du+" in text


def test_drift_writes_json_csv_and_plot(tmp_path, capsys):
    out, table, fig = tmp_path / "d.json", tmp_path / "d.csv", tmp_path / "d.png"
    argv = f"experiment drift --model ss15-1hz --seeds 2 --gains 0.8,4.0 --json {out} --csv {table}"
    assert run(argv + f" --plot {fig}") == 0
    data = json.loads(out.read_text())
    assert data["experiment"] == "drift" and len(data["rows"]) == 3 * 2 * 2
    assert data["config"]["gains"] == [0.8, 4.0] and data["models"] == {"1": "ss15-1hz"}
    comp = {(c["frequency"], c["gain"]): c for c in data["comparisons"]}
    assert comp[(1.0, 4.0)]["a_up"] and comp[(1.0, 4.0)]["d_down"]
    rows = list(csv.DictReader(table.read_text().splitlines()))
    assert len(rows) == 12 and rows[0]["state"] == "n"
    assert fig.stat().st_size > 5000
    assert "psi_n mean +/- std" in capsys.readouterr().out


def test_closed_loop_with_a_model_file(tmp_path, capsys):
    path = tmp_path / "m.npz"
    PreisachModel.builtin("ss15-2hz", 101).save(path)
    out = tmp_path / "c.json"
    argv = f"experiment closed-loop --model {path} --seeds 2 --gains 1.6 --kp 1.0 --average 0.025"
    assert run(argv + f" --json {out}") == 0
    data = json.loads(out.read_text())
    assert data["config"]["protocol"]["kp"] == 1.0
    assert data["config"]["protocol"]["average_window"] == 0.025
    assert data["config"]["sample_times"] == {"2": 0.001}
    assert len(data["percentage_table"]) == 1
    assert "Table 5.1" in capsys.readouterr().out


def test_cli_errors_and_strict_json(tmp_path):
    out = tmp_path / "x.json"
    with pytest.raises(ValueError, match="neither a built-in"):
        run(f"experiment drift --model nope --json {out}")
    bare = PreisachModel.builtin("ss15-1hz", 21)
    bare.metadata = {}
    path = tmp_path / "bare.npz"
    bare.save(path)
    with pytest.raises(ValueError, match="--frequency"):
        run(f"experiment drift --model {path} --json {out}")
    argv = f"experiment drift --model {path} --frequency 1 --seeds 1 --gains 0.8 --states a"
    assert run(argv + f" --json {out}") == 0
    text = out.read_text()
    assert "NaN" not in text and json.loads(text)["summary"][0]["std"] is None  # 1 seed: no std
    with pytest.raises(ValueError, match="own initialisation frequency"):
        run(f"experiment drift --model ss15-1hz --model ss15-2hz --frequency 1 --json {out}")
    with pytest.raises(SystemExit):
        run(f"experiment drift --model ss15-1hz --states n,x --json {out}")
    with pytest.raises(SystemExit):
        run("experiment locus --model ss15-1hz")  # --json is required
