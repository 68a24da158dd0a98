"""Generate the teaching notebooks ``notebooks/NN_name.ipynb`` from ``notebooks/NN_name.py``.

Run:  python scripts/make_notebooks.py            (rewrites every .ipynb whose source changed)
      python scripts/make_notebooks.py --check    (exit 1 if a committed .ipynb is stale)

The sources are jupytext percent-format Python files (``# %%`` starts a code cell,
``# %% [markdown]`` a markdown cell; IPython magics are commented out, ``# %matplotlib inline``):
edit them, lint them with ``ruff check notebooks``, run this script, commit both. The .ipynb are
written without outputs, with stable cell ids (``NN-kk``) so regenerating does not churn the diff.
A notebook that needs the real recordings names them in its jupytext header::

    # ---
    # jupyter:
    #   preisach:
    #     requires:
    #     - yan9a-piezo/Model_Vi_Do.dat
    # ---

(paths relative to the data folder, ``$PREISACH_DATA`` or ``<repo>/../shared/data``);
``tests/test_notebooks.py`` skips it when they are absent, executes the others, and checks that
every committed .ipynb is what this script writes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import jupytext
import nbformat
from preisach._io import write_text  # atomic: beside the target, fsync, rename

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"


def sources() -> list[Path]:
    """Return the notebook sources ``notebooks/NN_*.py`` in chapter order."""
    return sorted(NOTEBOOKS.glob("[0-9][0-9]_*.py"))


def render(source: Path) -> str:
    """Return the .ipynb text (no outputs, stable ids) generated from one percent-format source."""
    nb = jupytext.read(source, fmt="py:percent")
    requires = nb.metadata.get("preisach", {}).get("requires", [])
    nb.metadata = nbformat.NotebookNode(
        kernelspec={"name": "python3", "display_name": "Python 3", "language": "python"},
        language_info={"name": "python"},
    )
    if requires:
        nb.metadata["preisach"] = {"requires": list(requires)}
    nb.nbformat, nb.nbformat_minor = 4, 5
    for k, cell in enumerate(nb.cells):
        cell["id"] = f"{source.name[:2]}-{k:02d}"
        cell["metadata"] = nbformat.NotebookNode()
        if cell.cell_type == "code":
            cell["outputs"], cell["execution_count"] = [], None
    nbformat.validate(nb)
    return nbformat.writes(nb) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` only compare) every notebook; return the exit code."""
    check = "--check" in (sys.argv[1:] if argv is None else argv)
    stale = []
    for source in sources():
        target = source.with_suffix(".ipynb")
        text = render(source)
        if target.exists() and target.read_text(encoding="utf-8") == text:
            continue
        stale.append(target)
        if not check:
            write_text(target, text, what="notebook")
        print(("stale: " if check else "wrote: ") + str(target))
    made = {s.with_suffix(".ipynb") for s in sources()}
    orphans = sorted(set(NOTEBOOKS.glob("[0-9][0-9]_*.ipynb")) - made)
    for orphan in orphans:
        print(f"no source for {orphan} (delete it or add {orphan.with_suffix('.py').name})")
    return 1 if (check and stale) or orphans else 0


if __name__ == "__main__":
    sys.exit(main())
