"""The hand-written stubs of preisach._core: every export, member and signature of the module."""

import ast
import re
from pathlib import Path

import preisach._core as core

STUB = Path(__file__).resolve().parents[1] / "python" / "preisach" / "_core.pyi"


def _stub_names():
    """Top-level names, and each class's members counting those its stub bases declare.

    A member a class inherits at runtime is written once, in its base (``Block``,
    ``DaqDevice``, ...): :func:`test_stub_bases_are_the_runtime_bases` keeps that inheritance
    the binding's own.
    """
    tree = ast.parse(STUB.read_text())
    top, own, bases = set(), {}, {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            top.add(node.name)
        if isinstance(node, ast.ClassDef):
            own[node.name] = {
                n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            }
            bases[node.name] = [b.id for b in node.bases if isinstance(b, ast.Name)]

    def members(name):
        return own[name].union(*(members(b) for b in bases[name] if b in own))

    return top, {name: members(name) for name in own}, bases


def _public(obj):
    return {n for n in dir(obj) if not n.startswith("_")}


def test_stub_names_every_module_export():
    top, _, _ = _stub_names()
    exported = _public(core)
    assert exported - top == set(), f"missing from _core.pyi: {sorted(exported - top)}"
    assert top - exported == set(), f"in _core.pyi but not in _core: {sorted(top - exported)}"


def test_stub_bases_are_the_runtime_bases():
    _, _, bases = _stub_names()
    for name, stubbed in bases.items():
        runtime = [
            b.__name__ for b in getattr(core, name).__bases__ if b.__module__ == core.__name__
        ]
        assert stubbed == runtime, f"{name}: stub bases {stubbed} != runtime bases {runtime}"


def test_stub_names_every_class_member():
    _, members, _ = _stub_names()
    for name, stubbed in members.items():
        cls = getattr(core, name)
        public = _public(cls)
        assert public - stubbed == set(), f"{name}: missing from stub: {sorted(public - stubbed)}"
        assert {m for m in stubbed if not m.startswith("_")} - public == set(), name


def test_package_is_typed():
    assert (STUB.parent / "py.typed").exists()


# ---------------------------------------------------------------- signatures
# mypy's stubtest compares the stub with the runtime module: names, kinds (class, function,
# property, staticmethod), and signatures where the runtime has them.  pybind11 adds noise that
# is allowed here: every class has pybind11's metaclass, and classes without a constructor
# expose ``__init__(self, *args, **kwargs)`` (which raises).
NO_CONSTRUCTOR = ("Block", "DaqController", "DaqDevice", "DaqTrialResult", "ProjectionResult")


def test_stubtest_finds_no_drift(tmp_path):
    import subprocess
    import sys

    allowlist = tmp_path / "allowlist.txt"
    allowlist.write_text("".join(f"preisach._core.{c}.__init__\n" for c in NO_CONSTRUCTOR))
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "mypy.stubtest",
            "preisach._core",
            "--concise",
            "--allowlist",
            str(allowlist),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,  # not the project's mypy configuration (files = ...)
    )
    errors = [
        ln
        for ln in r.stdout.splitlines()
        if ln.strip() and not ln.endswith("is inconsistent, metaclass differs")
    ]
    assert r.returncode in (0, 1), r.stderr
    assert errors == [], "\n".join(errors)


def _split_params(text):
    """Split a parameter list at the commas outside brackets and quotes."""
    out, depth, cur, quote = [], 0, "", None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
            continue
        cur += ch
    return [p for p in [*out, cur.strip()] if p]


def _runtime_signatures(obj, name):
    """Parameter (name, has_default) tuples of every overload in a pybind11 docstring.

    pybind11 names unnamed arguments ``arg0``, ``arg1``, ...: they are positional-only and
    match any name in the stub (``"<positional>"``).
    """
    sigs = set()
    for line in (obj.__doc__ or "").splitlines():
        m = re.match(r"^(?:\d+\. )?" + re.escape(name) + r"\((.*)\) -> ", line)
        if not m:
            continue
        params = []
        for p in _split_params(m.group(1)):
            if p in ("*", "/"):
                params.append((p, False))
                continue
            pname = re.match(r"^\**\w+", p).group(0)
            annotation_and_default = p.split(":", 1)[1] if ":" in p else p
            has_default = re.search(r"=(?![^\[]*\])", annotation_and_default) is not None
            params.append(
                ("<positional>" if re.fullmatch(r"arg\d+", pname) else pname, has_default)
            )
        sigs.add(tuple(params))
    return sigs


def _stub_signature(fn):
    a = fn.args
    positional = a.posonlyargs + a.args
    n_defaults = len(a.defaults)
    params = []
    for i, x in enumerate(positional):
        name = x.arg
        if i < len(a.posonlyargs) and name != "self":
            name = "<positional>"
        params.append((name, i >= len(positional) - n_defaults))
    if a.vararg:
        params.append(("*" + a.vararg.arg, False))
    elif a.kwonlyargs:
        params.append(("*", False))
    params += [(x.arg, d is not None) for x, d in zip(a.kwonlyargs, a.kw_defaults)]
    if a.kwarg:
        params.append(("**" + a.kwarg.arg, False))
    return tuple(params)


def _stub_functions():
    """(qualified name, runtime object, stub FunctionDef) for every stubbed callable."""
    tree = ast.parse(STUB.read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            yield node.name, getattr(core, node.name), node
        elif isinstance(node, ast.ClassDef):
            cls = getattr(core, node.name)
            for fn in node.body:
                decorators = {d.id for d in fn.decorator_list if isinstance(d, ast.Name)}
                if isinstance(fn, ast.FunctionDef) and "property" not in decorators:
                    yield f"{node.name}.{fn.name}", getattr(cls, fn.name), fn


def test_stub_parameters_match_the_pybind_signatures():
    # stubtest cannot see these: pybind11 functions have no inspect.signature, only the
    # signature lines of their docstrings
    stubbed = {}
    for qualname, obj, fn in _stub_functions():
        stubbed.setdefault(qualname, (obj, set()))[1].add(_stub_signature(fn))
    assert len(stubbed) > 100
    problems = []
    for qualname, (obj, stub_sigs) in sorted(stubbed.items()):
        runtime = _runtime_signatures(obj, qualname.rsplit(".", 1)[-1])
        if not runtime:
            problems.append(f"{qualname}: no signature in the runtime docstring")
        elif runtime != stub_sigs:
            problems.append(f"{qualname}: runtime {sorted(runtime)} != stub {sorted(stub_sigs)}")
    assert problems == [], "\n".join(problems)


def test_signature_check_catches_a_drift():
    # the check above must fail on a renamed, a missing and a default-less parameter
    (fn,) = [f for q, _, f in _stub_functions() if q == "simulate"]
    runtime = _runtime_signatures(core.simulate, "simulate")
    assert runtime == {_stub_signature(fn)}
    for mutate in (
        "def simulate(table, u, state, policy='clamp'): ...",
        "def simulate(table, u, state): ...",
        "def simulate(table, u, state, out_of_range): ...",
    ):
        assert runtime != {_stub_signature(ast.parse(mutate).body[0])}
