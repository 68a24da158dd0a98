"""The package type-checks (mypy, settings in pyproject.toml) and the code is lint-clean (ruff)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from _paths import ROOT

PATHS = ["python", "tests", "scripts", "examples", "benchmarks", "notebooks"]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_mypy_finds_no_errors():
    pytest.importorskip("mypy")
    r = _run(sys.executable, "-m", "mypy")
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.parametrize("command", [["check"], ["format", "--check"]], ids=["lint", "format"])
def test_ruff_is_clean(command):
    pytest.importorskip("ruff")
    r = _run(sys.executable, "-m", "ruff", *command, *PATHS)
    assert r.returncode == 0, r.stdout + r.stderr
