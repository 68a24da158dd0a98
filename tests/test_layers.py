"""The package face stays light: importing it loads no heavy layer."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

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
