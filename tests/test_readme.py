"""The README's Python code runs top to bottom as written.

Every fenced ``python`` block of README.md is executed in order, in one namespace, in a fresh
working folder that holds a copy of ``examples/trials`` (the one path the tour reads, relative
to the repository root). A block preceded by the line ``<!-- readme-test: skip -->`` is not run
(none is, today); it must still compile.
"""

from __future__ import annotations

import re
import shutil

import pytest
from _paths import ROOT

README = ROOT / "README.md"
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)
SKIP = "<!-- readme-test: skip -->"


def python_blocks(text: str) -> list[tuple[int, str, bool]]:
    """``(first line number, code, skip)`` of every fenced python block, in order."""
    out = []
    for m in FENCE.finditer(text):
        before = text[: m.start()].rstrip("\n").splitlines()
        skip = bool(before) and before[-1].strip() == SKIP
        out.append((text.count("\n", 0, m.start(1)) + 1, m.group(1), skip))
    return out


def test_the_readme_has_a_python_tour_and_every_block_compiles():
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 5
    for line, code, _ in blocks:
        compile("\n" * (line - 1) + code, str(README), "exec")


def test_block_extraction_sees_skips_and_line_numbers():
    text = "intro\n```python\na = 1\n```\n\n" + SKIP + "\n```python\nraise SystemExit\n```\n"
    assert python_blocks(text) == [(3, "a = 1\n", False), (8, "raise SystemExit\n", True)]


@pytest.mark.slow
def test_the_readme_python_blocks_run_top_to_bottom(tmp_path, monkeypatch):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    shutil.copytree(ROOT / "examples" / "trials", tmp_path / "examples" / "trials")
    monkeypatch.chdir(tmp_path)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.setenv(var, "1")
    namespace: dict[str, object] = {"__name__": "__readme__"}
    ran = 0
    try:
        for line, code, skip in python_blocks(README.read_text(encoding="utf-8")):
            if skip:
                continue
            # padded so that a traceback names the README's own line numbers
            exec(compile("\n" * (line - 1) + code, str(README), "exec"), namespace)
            ran += 1
    finally:
        import matplotlib.pyplot as plt

        plt.close("all")
    assert ran >= 5
    written = {p.name for p in tmp_path.iterdir()}
    assert {"ss15.npz", "fod_sweep.csv", "report.json", "augmented.npz"} <= written
