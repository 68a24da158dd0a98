"""Every teaching notebook runs top to bottom (nbclient), is committed without outputs, and is
what ``scripts/make_notebooks.py`` generates.

Notebooks that need the real recordings (``metadata["preisach"]["requires"]``) are skipped when
the data folder - ``$PREISACH_DATA`` or ``<repo>/../shared/data`` - does not hold them.
"""

import importlib.util

import pytest
from _paths import DATA_DIR as DATA
from _paths import ROOT

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def _generator():
    spec = importlib.util.spec_from_file_location(
        "make_notebooks", ROOT / "scripts" / "make_notebooks.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_there_are_notebooks_for_every_chapter():
    names = [p.name[:2] for p in NOTEBOOKS]
    assert names == ["01", "02", "03", "04", "05", "06"]


def test_notebooks_are_what_the_generator_writes():
    gen = _generator()
    assert set(gen.NOTEBOOKS) == {p.name for p in NOTEBOOKS}
    for path in NOTEBOOKS:
        cells, requires = gen.NOTEBOOKS[path.name]
        nb = nbformat.read(path, as_version=4)
        assert [c.source for c in nb.cells] == [c.source for c in cells], (
            f"{path.name} differs from scripts/make_notebooks.py: edit the script and rerun it"
        )
        assert nb.metadata.get("preisach", {}).get("requires", []) == list(requires)


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs_and_is_committed_without_outputs(path, tmp_path, monkeypatch):
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.get("outputs"), f"{path.name}: commit notebooks without outputs"
            assert cell.get("execution_count") is None
    missing = [
        f for f in nb.metadata.get("preisach", {}).get("requires", []) if not (DATA / f).exists()
    ]
    if missing:
        pytest.skip(f"{path.name} needs {missing} in {DATA}")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PREISACH_DATA", str(DATA))
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.setenv(var, "1")  # small solves: threaded BLAS only spins on a busy machine
    monkeypatch.chdir(tmp_path)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    errors = [
        o
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
        if o.get("output_type") == "error"
    ]
    assert not errors
    # every code cell ran and every figure cell drew something
    assert all(c.execution_count for c in nb.cells if c.cell_type == "code")
    images = sum(
        "image/png" in o.get("data", {})
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
    )
    assert images >= 3, f"{path.name}: expected figures in the outputs, got {images}"
