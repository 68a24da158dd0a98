"""`preisach compensate`: reference CSV -> drive recording, through preisach.cli.main."""

from __future__ import annotations

import numpy as np
import pytest
from preisach import PreisachModel, Recording
from preisach.cli import main


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("comp") / "m.npz"
    PreisachModel.builtin("ss15-1hz", levels=41).save(path)
    return path


def write_ref(path, t, y, header="t,y", meta="# experiment: sine\n"):
    rows = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, y))
    path.write_text(meta + header + "\n" + rows)
    return path


def test_drive_reproduces_the_reference(tmp_path, model_file, capsys):
    model = PreisachModel.load(model_file)
    t = np.arange(500) * 1e-3
    y = 0.8 * model.y_max * np.sin(2 * np.pi * 2.0 * t)
    ref = write_ref(tmp_path / "ref.csv", t, y)
    out = tmp_path / "drive.csv"
    assert (
        main(["compensate", str(model_file), str(ref), "-o", str(out), "--state", "negative"]) == 0
    )
    assert "0 unreachable" in capsys.readouterr().out
    rec = Recording.load(out)
    np.testing.assert_array_equal(rec.t, t)
    np.testing.assert_allclose(rec.columns["y_ref"], y)
    sim = model.simulate(rec.u, model.negative_saturation()).output
    np.testing.assert_allclose(sim, y, atol=1e-9)
    np.testing.assert_allclose(rec.y, sim, atol=1e-12)
    assert rec.metadata["initial_state"] == "negative" and rec.metadata["unreachable"] == 0
    assert rec.metadata["reference"] == "sine"
    # a different start state gives a different drive for the same reference
    out2 = tmp_path / "drive2.csv"
    assert main(["compensate", str(model_file), str(ref), "-o", str(out2)]) == 0
    assert np.max(np.abs(Recording.load(out2).u - rec.u)) > 1.0


def test_unreachable_targets_are_reported_not_fatal(tmp_path, model_file, capsys):
    model = PreisachModel.load(model_file)
    ref = write_ref(tmp_path / "ref.csv", [0.0, 0.1, 0.2], [0.0, model.y_max + 1, 0.0])
    out = tmp_path / "d.csv"
    assert main(["compensate", str(model_file), str(ref), "-o", str(out)]) == 0
    assert "1 unreachable" in capsys.readouterr().out
    rec = Recording.load(out)
    np.testing.assert_array_equal(rec.columns["reached"], [1.0, 0.0, 1.0])
    assert rec.u[1] == model.u_max


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("t,u\n0,1\n", "needs columns 't' and 'y'"),
        ("t,y\n0,1\n0.1\n", "line 3: expected 2 fields"),
        ("t,y\n0,1\n0.1,abc\n", "line 3: not a number"),
        ("t,y\n0,1\n0,2\n", "strictly increasing"),
        ("t,y\n0,nan\n", "finite"),
        ("# only: metadata\n", "no data"),
    ],
)
def test_bad_references_exit_1_with_one_line(tmp_path, model_file, capsys, content, message):
    ref = tmp_path / "bad.csv"
    ref.write_text(content)
    out = tmp_path / "d.csv"
    assert main(["compensate", str(model_file), str(ref), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert message in err and err.startswith("preisach compensate: error:")
    assert "\n" not in err and not out.exists()


def test_bad_model_and_missing_files(tmp_path, model_file, capsys):
    ref = write_ref(tmp_path / "ref.csv", [0.0], [0.0])
    assert main(["compensate", str(tmp_path / "none.npz"), str(ref), "-o", "d.csv"]) == 1
    assert main(["compensate", str(model_file), str(tmp_path / "none.csv"), "-o", "d.csv"]) == 1
    assert main(["compensate", str(model_file), str(ref), "-o", str(tmp_path / "d.txt")]) == 1
    errs = capsys.readouterr().err.strip().splitlines()
    assert len(errs) == 3 and all(e.startswith("preisach compensate: error:") for e in errs)
