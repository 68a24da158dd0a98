"""Every script in examples/ runs as is."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))


def test_there_are_examples():
    assert EXAMPLES


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300, env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin",
                                         "HOME": str(tmp_path)})
    assert r.returncode == 0, r.stdout + r.stderr
    assert "wrote" in r.stdout
    written = [p for p in tmp_path.iterdir() if p.is_file()]
    assert written, "an example should leave its result (figure, model, recording) on disk"
