"""Where the real recordings are: ``$PREISACH_DATA``, else ``../shared/data`` beside the repo.

They are never copied into the repository (see ``../shared/data/README.md`` for their licences);
tests that need them skip, naming this folder, when it does not hold them.  Also: a script of
``scripts/`` loaded as a module (:func:`script_module`), and a case of the blind generator
written to disk (:func:`blind_case`), and read with its identified model
(:func:`blind_identified`; the first generator's: :func:`blind1_identified`), and diagnosed
with some candidates as ``preisach diagnose`` would (:func:`blind_diagnosed`,
:func:`blind1_diagnosed`).
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("PREISACH_DATA") or ROOT.parent / "shared" / "data")
YAN9A = DATA_DIR / "yan9a-piezo" / "Model_Vi_Do.dat"
PMAGPY_FORC = DATA_DIR / "pmagpy-forc" / "conventional_example.forc"


def script_module(relpath: str, name: str) -> ModuleType:
    """Load ``scripts/<relpath>`` (a script, not a package module) as the module ``name``."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / relpath)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def blind_case(out: Path, seed: int, index: int) -> tuple[Path, list[str]]:
    """Write case ``index`` of the blind generator's run ``--seed seed --cases-per-kind 3
    --cml`` (``scripts/blind2``, written from physical descriptions only) into ``out``.

    Returns the case folder and the forms of its effects (empty for a null)."""
    gen = script_module("blind2/generator.py", "blind2_generator")
    job = gen.case_jobs(str(out), 3, seed, cml=True)[index]
    (out / "truth").mkdir(parents=True, exist_ok=True)
    gen.make_case(job)
    return out / f"case_{index:03d}", list(job[2])


def blind1_identified(
    out: Path, kind: str | list[str], form: str | list[str | None] | None, seed: int
) -> tuple[dict[str, Any], Any, Any, list[Any]]:
    """One case of the first blind generator (``scripts/blind``, written from physical
    descriptions only by another helper), ``make_case(kind, form, seed)``, read as a user
    would: its truth, the model identified from its ``id.csv``, that recording, and the
    experiments (every other CSV file, in order)."""
    from preisach import Recording
    from preisach.identify import identify

    gen = script_module("blind/blind_generator.py", "blind1_generator")
    (out / "truth").mkdir(parents=True, exist_ok=True)
    truth = gen.make_case(kind, form, seed, str(out), "case")
    case = out / "case"
    ident = Recording.load(case / "id.csv")
    recs = [Recording.load(p) for p in sorted(case.glob("*.csv")) if p.name != "id.csv"]
    return truth, identify([ident], progress=False).model, ident, recs


def blind_identified(out: Path, seed: int, index: int) -> tuple[list[str], Any, Any, list[Any]]:
    """:func:`blind_case`, read as a user would: the forms, the model ``preisach identify``
    makes from its ``id.csv``, that recording, and the experiments (``exp*.csv``, in order)."""
    from preisach import Recording
    from preisach.identify import identify

    case, forms = blind_case(out, seed, index)
    ident = Recording.load(case / "id.csv")
    recs = [Recording.load(p) for p in sorted(case.glob("exp*.csv"))]
    return forms, identify([ident], progress=False).model, ident, recs


def blind_diagnosed(
    out: Path, seed: int, index: int, candidates: list[str]
) -> tuple[list[str], Any]:
    """:func:`blind_identified`, diagnosed with ``candidates`` and the sweep refitted with them
    (as ``preisach diagnose`` does with the model file's stored sweep): the forms and the
    report."""
    from preisach.diagnose import diagnose

    forms, model, ident, recs = blind_identified(out, seed, index)
    rep = diagnose(model, recs, identification=[ident], candidates=candidates, progress=False)
    return forms, rep


def blind1_diagnosed(
    out: Path,
    kind: str | list[str],
    form: str | list[str | None] | None,
    seed: int,
    candidates: list[str],
) -> tuple[dict[str, Any], Any]:
    """:func:`blind1_identified`, diagnosed with ``candidates`` and the sweep refitted with
    them (as :func:`blind_diagnosed`): the truth and the report."""
    from preisach.diagnose import diagnose

    truth, model, ident, recs = blind1_identified(out, kind, form, seed)
    rep = diagnose(model, recs, identification=[ident], candidates=candidates, progress=False)
    return truth, rep
