"""The blind study's summary: for a miss, how near the truth's own fits came at step 1."""

from __future__ import annotations

from types import ModuleType
from typing import Any

from _paths import script_module


def _study() -> ModuleType:
    return script_module("blind_study.py", "blind_study")


def _report(
    verdict: str, kept: list[str], rows: list[tuple[int, str, float, float]]
) -> dict[str, Any]:
    """A diagnosis JSON report with the candidate table ``(step, form, gain, p)``."""
    effects = [
        {"name": k, "heldout_rmse_before": 2.0, "heldout_rmse_after": 1.0, "holds": None}
        for k in kept
    ]
    return {
        "verdict": verdict,
        "effects": effects,
        "rmse_before": 4.0,
        "rmse_after": 1.0,
        "noise_test": {"ratio": 1.3},
        "unexplained": None,
        "candidates": [
            {"step": s, "name": f, "gain": g, "p_value": p, "kept": f in kept}
            for s, f, g, p in rows
        ],
    }


def test_a_miss_is_listed_with_the_truths_best_fit_at_step_one() -> None:
    bs = _study()
    miss = _report(
        "none",
        [],
        [
            (1, "sensor_drift", 0.015, 0.12),
            (1, "non_congruence/output_curve", 0.014, 0.026),
            (1, "non_congruence", -0.011, 0.6),
            (2, "non_congruence", 0.2, 0.001),  # a later step does not count
        ],
    )
    hit = _report("delay", ["delay"], [(1, "delay", 0.5, 0.0002), (1, "creep", 0.01, 0.3)])
    old = _report("none", [], [])
    del old["candidates"]  # a report written before the table was in the JSON
    results = [
        {"case": "case_000", "kinds": ["non_congruence"], "passes": {"d": bs._outcome(miss)}},
        {"case": "case_001", "kinds": ["delay"], "passes": {"d": bs._outcome(hit)}},
        {"case": "case_002", "kinds": ["creep"], "passes": {"d": bs._outcome(old)}},
    ]
    assert bs._outcome(miss)["step1"]["non_congruence"] == [
        "non_congruence/output_curve",
        0.014,
        0.026,
    ]
    lines = bs.summarise(results, "d")
    text = "\n".join(lines)
    at = next(i for i, ln in enumerate(lines) if "-- case_000" in ln)
    assert "the truth's best fit: non_congruence/output_curve 1.4 % (p 0.026)" in lines[at + 1]
    assert text.count("the truth's best fit") == 1  # not for a hit, nor without a table
    assert "effect cases: right 1/3" in text


def test_the_noiseless_outputs_measure_what_the_cml_loops_carry(tmp_path) -> None:
    """``generator.py --clean`` adds the noiseless outputs and changes no CSV file; on them
    ``blind_detectability.cml_shape`` is 0 for every congruent output and well above the
    noise for seed 81's state-dependent reversible response (case 011, named from its loops).
    Fails when ``--clean`` draws from the case's random stream, or the loops are compared
    out of phase (loop B runs low -> high -> low, A and C high -> low -> high)."""
    import json

    import numpy as np

    gen = script_module("blind2/generator.py", "blind2_generator")
    bd = script_module("blind_detectability.py", "blind_detectability")
    for sub, clean in (("plain", False), ("clean", True)):
        (tmp_path / sub / "truth").mkdir(parents=True)
        gen.make_case(gen.case_jobs(str(tmp_path / sub), 3, 81, cml=True, clean=clean)[11])
    files = sorted(p.name for p in (tmp_path / "plain" / "case_011").glob("*.csv"))
    assert files and all(
        (tmp_path / "plain" / "case_011" / f).read_bytes()
        == (tmp_path / "clean" / "case_011" / f).read_bytes()
        for f in files
    ), files
    truth = json.loads((tmp_path / "clean" / "truth" / "case_011.json").read_text())
    assert truth["forms"][0]["form"] == "state_dependent_reversible", truth["forms"]
    with np.load(tmp_path / "clean" / "truth" / "case_011_clean.npz") as cl:
        assert {f"{f}:{k}" for f in files for k in ("u", "y", "y0")} == set(cl.files)
        sigma = truth["noise_rms"]
        assert bd.cml_shape(cl, truth, sigma, "y0") < 1e-9
        assert bd.cml_shape(cl, truth, sigma, "y") > bd.LOOPS_VISIBLE
