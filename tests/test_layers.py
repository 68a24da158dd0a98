"""Layers point one way, and the package face stays light.

The layer map (docs/ARCHITECTURE.md draws it): a module may import its own layer and the layers
below it, never one above.  Every module under ``python/preisach`` is parsed with :mod:`ast`
(nothing is imported); imports under ``if TYPE_CHECKING:`` count like runtime ones.  The only
upward imports allowed are :mod:`preisach.plotting` inside a function (a ``.plot()`` method
delegating to its figure), and the package face ``preisach/__init__.py``, which names public
objects of every layer but loads them lazily (PEP 562).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest
from _paths import ROOT

HEAVY = ("preisach.diagnose", "matplotlib", "scipy.signal")


def _modules_after(statement: str) -> set[str]:
    code = f"import sys, json\n{statement}\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    ).stdout
    return set(json.loads(out))


@pytest.mark.parametrize("statement", ["import preisach", "import preisach.model"])
def test_face_and_model_load_no_heavy_layer(statement):
    loaded = _modules_after(statement)
    heavy = sorted(m for m in loaded if m.startswith(HEAVY))
    assert heavy == [], f"{statement} loaded {heavy}"


def test_lazy_names_resolve_and_diagnose_stays_the_function():
    code = (
        "import preisach, sys\n"
        "from preisach.diagnose import diagnose, DiagnosisReport\n"
        "assert preisach.diagnose is diagnose, preisach.diagnose\n"
        "assert preisach.DiagnosisReport is DiagnosisReport\n"
        "from preisach.model import PreisachModel\n"
        "assert preisach.PreisachModel is PreisachModel\n"
        "assert isinstance(preisach.__version__, str) and preisach.__version__\n"
        "assert 'diagnose' in dir(preisach)\n"
        "print('ok')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr


def test_unknown_attribute_is_an_attribute_error():
    import preisach

    with pytest.raises(AttributeError, match="no_such_name"):
        _ = preisach.no_such_name


def test_rig_blocks_and_diagnosis_blocks_satisfy_the_one_block_interface():
    import numpy as np
    from preisach.daq.blocks import BLOCK_KINDS, make_block
    from preisach.diagnose import FirstOrderInputLag
    from preisach.types import Block

    rig = [make_block({"kind": kind}, 1e-3) for kind in BLOCK_KINDS]
    effect = FirstOrderInputLag(1e-3, tau=2e-3)
    for block in [*rig, effect]:
        assert isinstance(block, Block), type(block).__name__
        y0 = block.reset(0.0)
        assert block.step(0.0) == pytest.approx(y0)  # the steady state for a constant input
        assert block.run(np.zeros(3)).shape == (3,)
    assert not isinstance(object(), Block)


# ------------------------------------------------------------------------------ layer map

PACKAGE = ROOT / "python" / "preisach"

#: Layer of each module or package (the longest matching prefix wins), lowest first:
#: 0 core and utilities, 1 model level (data types, simulation, rig), 2 what uses models
#: (identification, verification, experiments, compensation), 3 diagnosis, 4 the faces
#: (command line, demo, figures, trial files, studies).  Any ``*.cli`` module is layer 4;
#: a private top-level module (``preisach._io``, ``preisach._figures``...) is a core utility.
LAYERS: dict[str, int] = {
    "preisach._core": 0,
    "preisach.errors": 0,
    "preisach.types": 0,
    "preisach.execution": 0,
    "preisach.model": 1,
    "preisach.rate_model": 1,
    "preisach.recording": 1,
    "preisach.surface": 1,
    "preisach.waveforms": 1,
    "preisach.noise": 1,
    "preisach.reference": 1,
    "preisach.initial_state": 1,
    "preisach.forc": 1,
    "preisach.daq": 1,
    "preisach.identify": 2,
    "preisach.verify": 2,
    "preisach.neutral": 2,
    "preisach.experiments": 2,
    "preisach.compensate": 2,
    "preisach.diagnose": 3,
    "preisach.cli": 4,
    "preisach.demo": 4,
    "preisach.plotting": 4,
    "preisach.trials": 4,
    "preisach.studies": 4,
}
LAYER_NAMES = ["core", "model", "identify/experiments", "diagnose", "faces"]

#: Known upward imports (module, target) with the reason each is tolerated; remove an entry
#: with its cause.
ALLOWED: dict[tuple[str, str], str] = {
    ("preisach.model", "preisach.compensate"): (
        "PreisachModel.inverse/inverter delegate lazily to compensate.inverse (as .plot() does "
        "to plotting) and name its InverseResult for typing; compensate.inverse itself needs "
        "only the model layer, so moving it down (or the methods out of model.py) ends this"
    ),
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def layer_of(module: str) -> int:
    parts = module.split(".")
    if parts[-1] == "cli":
        return 4
    if len(parts) == 2 and parts[1].startswith("_"):
        return 0
    for k in range(len(parts), 0, -1):
        prefix = ".".join(parts[:k])
        if prefix in LAYERS:
            return LAYERS[prefix]
    raise KeyError(f"{module} has no layer: add it (or its package) to LAYERS")


def _targets(module: str, is_package: bool, node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name.split(".")[0] == "preisach"]
    if node.level == 0:
        if (node.module or "").split(".")[0] != "preisach":
            return []
        base = node.module or ""
    else:
        parts = module.split(".") if is_package else module.split(".")[:-1]
        parts = parts[: len(parts) - (node.level - 1)]
        base = ".".join(parts + ([node.module] if node.module else []))
    out = []
    for alias in node.names:
        sub = f"{base}.{alias.name}"
        out.append(sub if sub in MODULES or alias.name == "_core" else base)
    return out


_PARSED: dict[str, list[tuple[str, str, int]]] = {}


def package_imports(module: str, source: str | None = None) -> list[tuple[str, str, int]]:
    """``(target, kind, line)`` of every import of the package in ``module``.

    ``kind`` is ``"module"`` (runs at import), ``"typing"`` (under ``if TYPE_CHECKING:``) or
    ``"lazy"`` (inside a function).  The package's own files are parsed once per session (the
    layer and the cycle checks read the same imports); a given ``source`` is always parsed.
    """
    if source is None and module in _PARSED:
        return _PARSED[module]
    path = MODULES[module]
    is_package = path.name == "__init__.py"
    found: list[tuple[str, str, int]] = []

    def visit(node: ast.AST, kind: str) -> None:
        for child in ast.iter_child_nodes(node):
            k = kind
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                k = "typing"
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) and kind == "module":
                k = "lazy"
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                found.extend((t, k, child.lineno) for t in _targets(module, is_package, child))
            else:
                visit(child, k)

    visit(ast.parse(path.read_text(encoding="utf-8") if source is None else source), "module")
    if source is None:
        _PARSED[module] = found
    return found


def upward_imports(module: str, found: list[tuple[str, str, int]]) -> list[str]:
    """The imports in ``found`` (of ``module``) that reach a higher layer without leave."""
    here = layer_of(module)
    upward = []
    for target, kind, line in found:
        if target == "preisach" or layer_of(target) <= here:
            continue
        if kind == "lazy" and target.startswith("preisach.plotting"):
            continue  # a .plot() method delegating to its figure
        if (module, target) in ALLOWED:
            continue
        upward.append(
            f"{module}:{line} ({LAYER_NAMES[here]}) imports {target} "
            f"({LAYER_NAMES[layer_of(target)]}, {kind})"
        )
    return upward


def test_every_module_has_a_layer():
    assert len(MODULES) > 40
    missing = []
    for m in MODULES:
        if m == "preisach":
            continue  # the face: see test_face_and_model_load_no_heavy_layer
        try:
            layer_of(m)
        except KeyError as exc:
            missing.append(str(exc))
    assert missing == []


def test_no_layer_imports_a_higher_one():
    upward = []
    for module in MODULES:
        if module != "preisach":  # the lazy face names every layer's public objects
            upward += upward_imports(module, package_imports(module))
    assert upward == []


def test_module_level_imports_form_no_cycle():
    graph = {m: set() for m in MODULES}
    for module in MODULES:
        for target, kind, _ in package_imports(module):
            if kind == "module" and target in MODULES and target not in (module, "preisach"):
                graph[module].add(target)
    # a cycle exists iff a depth-first search meets a node on its own stack
    state: dict[str, int] = {}
    cycles = []

    def dfs(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append(" -> ".join([*stack[stack.index(nxt) :], nxt]))
            elif nxt not in state:
                dfs(nxt, stack)
        stack.pop()
        state[node] = 2

    for m in sorted(graph):
        if m not in state:
            dfs(m, [])
    assert cycles == []


def test_the_checker_sees_an_upward_import():
    source = (
        "from __future__ import annotations\n"
        "from typing import TYPE_CHECKING\n"
        "from .diagnose import diagnose\n"
        "if TYPE_CHECKING:\n"
        "    from .identify import Report\n"
        "def plot(self):\n"
        "    from .plotting.model import plot_simulation\n"
        "def fit(self):\n"
        "    from .experiments import drift_test\n"
    )
    found = package_imports("preisach.model", source)
    assert found == [
        ("preisach.diagnose", "module", 3),
        ("preisach.identify", "typing", 5),
        ("preisach.plotting.model", "lazy", 7),
        ("preisach.experiments", "lazy", 9),
    ]
    flagged = upward_imports("preisach.model", found)
    assert [f.split(" imports ")[1].split(" ")[0] for f in flagged] == [
        "preisach.diagnose",
        "preisach.identify",
        "preisach.experiments",
    ]
