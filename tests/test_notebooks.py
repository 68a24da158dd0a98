"""Every teaching notebook runs top to bottom (nbclient), is committed without outputs, is what
``scripts/make_notebooks.py`` generates from its jupytext source ``notebooks/NN_name.py``, and
leaves nothing behind in the folder it runs in.

Notebooks that need the real recordings (``metadata["preisach"]["requires"]``) are skipped when
the data folder - ``$PREISACH_DATA`` or ``<repo>/../shared/data`` - does not hold them.
"""

import importlib.util
import shutil

import pytest
from _paths import DATA_DIR as DATA
from _paths import ROOT

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))


def _generator():
    pytest.importorskip("jupytext")
    spec = importlib.util.spec_from_file_location(
        "make_notebooks", ROOT / "scripts" / "make_notebooks.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_there_are_notebooks_for_every_chapter():
    names = [p.name[:2] for p in NOTEBOOKS]
    assert names[:6] == ["01", "02", "03", "04", "05", "06"]
    assert names == [f"{k:02d}" for k in range(1, len(names) + 1)]


def test_notebooks_are_what_the_generator_writes():
    gen = _generator()
    sources = gen.sources()
    assert [s.with_suffix(".ipynb") for s in sources] == NOTEBOOKS, "one .py source per .ipynb"
    for source in sources:
        committed = source.with_suffix(".ipynb").read_text(encoding="utf-8")
        assert committed == gen.render(source), (
            f"{source.name} and its .ipynb differ: run python scripts/make_notebooks.py"
        )
    assert gen.main(["--check"]) == 0


def test_generator_check_reports_a_stale_notebook(tmp_path, monkeypatch, capsys):
    gen = _generator()
    source = gen.sources()[0]
    shutil.copy(source, tmp_path / source.name)
    monkeypatch.setattr(gen, "NOTEBOOKS", tmp_path)
    assert gen.main(["--check"]) == 1  # no .ipynb yet
    assert gen.main([]) == 0
    assert gen.main(["--check"]) == 0
    nb = nbformat.read(tmp_path / source.with_suffix(".ipynb").name, as_version=4)
    assert [c.id for c in nb.cells][:2] == [f"{source.name[:2]}-00", f"{source.name[:2]}-01"]
    with open(tmp_path / source.name, "a", encoding="utf-8") as f:
        f.write("\n# %%\nprint('one more cell')\n")
    assert gen.main(["--check"]) == 1
    assert "stale" in capsys.readouterr().out


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
    # run it as JupyterLab does: working directory = the notebook's folder (a copy here)
    folder = tmp_path / "notebooks"
    folder.mkdir()
    shutil.copy(path, folder / path.name)
    monkeypatch.chdir(folder)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(folder)}}
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
    # each chapter shows one of its results as Jupyter displays it (``_repr_html_``)
    html = [
        o["data"]["text/html"]
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
        if "text/html" in o.get("data", {})
    ]
    assert any("<table>" in h for h in html), f"{path.name}: no rich display of a result"
    # outputs go to a temporary folder: running a notebook leaves its folder as it was
    assert sorted(p.name for p in folder.iterdir()) == [path.name]
