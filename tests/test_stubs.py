"""The hand-written stubs of preisach._core must name everything the module exports."""

import ast
from pathlib import Path

import preisach._core as core

STUB = Path(__file__).resolve().parents[1] / "python" / "preisach" / "_core.pyi"


def _stub_names():
    tree = ast.parse(STUB.read_text())
    top, members = set(), {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            top.add(node.name)
        if isinstance(node, ast.ClassDef):
            members[node.name] = {
                n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            }
    return top, members


def _public(obj):
    return {n for n in dir(obj) if not n.startswith("_")}


def test_stub_names_every_module_export():
    top, _ = _stub_names()
    exported = _public(core)
    assert exported - top == set(), f"missing from _core.pyi: {sorted(exported - top)}"
    assert top - exported == set(), f"in _core.pyi but not in _core: {sorted(top - exported)}"


def test_stub_names_every_class_member():
    _, members = _stub_names()
    for name, stubbed in members.items():
        cls = getattr(core, name)
        public = _public(cls)
        assert public - stubbed == set(), f"{name}: missing from stub: {sorted(public - stubbed)}"
        assert {m for m in stubbed if not m.startswith("_")} - public == set(), name


def test_package_is_typed():
    assert (STUB.parent / "py.typed").exists()
