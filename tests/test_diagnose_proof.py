"""Proof on concealed effects: one small effect (or none) hidden in realistic recordings.

Every effect kind and a null case, on both generators of :mod:`preisach.studies.diagnosis_cases`:

* ``own`` - the different-form proof: this package's truths, in functional forms unlike the
  candidates' and with randomised shape parameters (a rate-scaled Everett function with a
  random rate smoothing, a mode driven by the first-order-hold output, the logarithmic creep
  law, a continuous first-order measurement lag, a random multi-sine offset, a moving model
  with saturating ``tanh`` feedback about a random centre);
* ``rig`` - the same-form check: the virtual SS15 rig's C++ physics blocks measured through
  its DAQ (input lag, structural mode, Prony creep, delay / moving average at 20 kHz,
  random-walk offset drift, the moving Preisach stage), largely the candidates' own forms.

Each case is an FOD identification sweep plus wiping-out, CML, minor-loop, multi-sine,
step-and-hold and filtered-noise experiments, with 1 mV noise and 14-bit quantisation; the
effect's unabsorbable part is 3.5 x the noise (invisible on a loop plot).  A model is
identified from the sweep (which carries the effect too), the experiments are diagnosed with
every candidate, and the verdict, the held-out improvement (>= 30 %) and physically
meaningful quantities of the fitted effect
(:func:`preisach.studies.diagnosis_cases.physical_checks`:
a lag, a mode, a creep movement, a loop widening, a drift's size, a feedback slope) are
checked against the truth.  Recordings are short (``scale`` 0.2) and only the first effect is
selected in 13 of the 14 fixed cases, to keep them in about a minute on two processes; the
different-form rate-dependence case runs the full selection (its first step is the one-effect
run) and must keep nothing beyond the right effect.
``scripts/diagnosis_study.py`` runs the randomised study with the full selection.
"""

from __future__ import annotations

import multiprocessing
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from preisach.studies.diagnosis_cases import EFFECT_KINDS, run_case

pytestmark = pytest.mark.slow

SCALE = 0.2
SIZE = 3.5
SEED = 31
CASES = [(g, k) for g in ("own", "rig") for k in ("none", *EFFECT_KINDS)]
# full selection (up to 3 effects) on the different-form case whose first effect explains the
# least of its residual: the place a spurious second effect would be kept.  Its first step is
# the one-effect run of the same case, so that case's checks read this run (one diagnosis
# fewer)
FULL = ("own", "rate_dependence", 3)
RUNS = [FULL, *((g, k, 1) for g, k in CASES if (g, k) != FULL[:2])]


def _run(gen: str, kind: str, max_effects: int) -> dict[str, Any]:
    """One case in a worker process, with warnings as errors as in the test session."""
    warnings.simplefilter("error")
    return run_case(
        kind, generator=gen, seed=SEED, effect_size=SIZE, scale=SCALE, max_effects=max_effects
    )


@pytest.fixture(scope="module")
def outcomes() -> dict[tuple[str, str], dict[str, Any]]:
    """All cases by (generator, kind), diagnosed on two processes (they are independent)."""
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=ctx) as ex:
        futures = {c[:2]: ex.submit(_run, *c) for c in RUNS}  # FULL, the longest, first
        return {c: f.result() for c, f in futures.items()}


def _blocks(truth: dict[str, Any]) -> dict[str, dict[str, Any]]:
    p = truth["params"]
    return {b["kind"]: b for b in p.get("input_blocks", []) + p.get("output_blocks", [])}


#: Relative tolerance of each physical quantity (fitted vs truth).  Same-form (rig) fits are
#: held tighter where the candidate is the truth's own form; the different-form (own) fits
#: measure a quantity the two forms share, so they get more room.  The rate-dependence
#: widening extrapolates a different form to a 1 Hz major loop: a factor of 2.
TOLERANCE = {
    "lag": (0.25, 0.25),
    "f_n": (0.03, 0.03),
    "zeta": (0.5, 0.5),
    "participation": (0.25, 0.25),
    "creep_50ms_1s": (0.3, 0.3),
    "peak_to_peak": (0.3, 0.3),
    "feedback_slope": (0.5, 0.2),
}


def _check_parameters(gen: str, kind: str, r: dict[str, Any]) -> None:
    """Physical quantities of the fitted effect against the generator's truth."""
    checks = r["checks"]
    assert checks, "a right verdict must come with physical checks"
    for name, c in checks.items():
        f, t = c["fitted"], c["truth"]
        assert f * t > 0, f"{name}: fitted {f:.4g} has the wrong sign (truth {t:.4g})"
        if name == "widening":  # loops wider at 1 Hz than at 0.05 Hz, by about the truth's
            assert 0.5 < f / t < 2.0, f"widening {f:.4g} V vs truth {t:.4g} V"
        else:
            rel = TOLERANCE[name][0 if gen == "own" else 1]
            assert f == pytest.approx(t, rel=rel), f"{name}: fitted {f:.4g}, truth {t:.4g}"
    if gen == "rig" and kind == "rate_dependence" and "tau" in r["params"]:
        # the rig's block is an input lag: the same form, so the same time constant
        tau = _blocks(r["truth"])["input_lag"]["time_constant"]
        assert r["params"]["tau"] == pytest.approx(tau, rel=0.3)


@pytest.mark.parametrize("gen, kind", CASES, ids=[f"{g}-{k}" for g, k in CASES])
def test_concealed_effect(outcomes, gen, kind):
    r = outcomes[(gen, kind)]
    assert r["verdict"] == kind, r["summary"]
    if kind == "none":
        assert r["effects"] == [] and r["rmse_after"] <= r["rmse_before"]
        return
    assert r["size"] == pytest.approx(SIZE, rel=0.5)  # concealed: a few times the noise
    assert r["gain"] >= 0.30, r["summary"]
    _check_parameters(gen, kind, r)


def test_full_selection_keeps_no_extra_effect(outcomes):
    """With up to three effects allowed, the concealed one is kept and nothing else."""
    r = outcomes[FULL[:2]]
    assert r["effects"] == [FULL[1]], r["summary"]
    assert r["gain"] >= 0.30
    _check_parameters(FULL[0], FULL[1], r)


from _paths import YAN9A as DATA  # noqa: E402


@pytest.mark.skipif(not DATA.exists(), reason=f"real data not found at {DATA}")
def test_real_piezo_recording():
    """yan9a-piezo: 40 cycles of 1 Hz; identify from 10 cycles, diagnose the other 30."""
    import sys

    from preisach.diagnose import diagnose
    from preisach.identify import identify_lsq

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    try:
        from diagnose_real_data import load
    finally:
        sys.path.pop(0)
    ident, recs = load(DATA)
    model, _ = identify_lsq(ident, 21)
    rep = diagnose(model, recs, identification=ident)
    names = [e.name for e in rep.effects]
    # The reading drifts with time, and the loops differ from the identified ones in a way
    # that a lag of the drive (the authors assume one 5 ms sample) and a moving model both
    # explain on this single 1 Hz drive: both qualify in the first step, and which one is
    # kept is not robust (it changed with the rounding of the BLAS threads, and with how the
    # unknown initial states are chosen).  After a lag the drift is kept; after the moving
    # model, which follows the output level as it drifts, the drift's remaining gain has been
    # 10-20 %, near the bar.
    assert names[0] in ("rate_dependence", "delay", "non_congruence"), rep.summary()
    assert set(names[1:]) <= {"sensor_drift"}, rep.summary()
    first = {c["name"]: c for c in rep.candidates if c["step"] == 1}
    for name in ("rate_dependence/input_lag", "non_congruence"):
        assert first[name]["decision"] == "qualifies", rep.summary()
    # The drift alone lowers the held-out error, but a classical model with free initial
    # states leaves it only 0.08 noise variances to add on interleaved stretches (the bar is
    # 0.1), and the residual does not follow the time in the recording (p 0.6): so it may be
    # refused as implausible for its name, and when it is, it says so.
    drift = first["sensor_drift"]["decision"]
    assert drift == "qualifies" or "classical Preisach model" in drift, rep.summary()
    assert rep.rmse_after < 0.5 * rep.rmse_before
    # what is left is consistent with the noise (it was 2.6 x with the lag and the moving
    # model diverging from the chosen initial states)
    assert rep.noise_test["consistent"], rep.summary()
    if "sensor_drift" in names:
        # the final model (refitted on all samples) is sound: a drift of tens of mV/s, well
        # determined (a final fit that broke the closed loop gave 458 +- 1232 mV/s)
        rate = next(e for e in rep.effects if e.name == "sensor_drift").parameters["rate"]
        assert 0.005 < abs(rate["value"]) < 0.06 and rate["std"] < 0.5 * abs(rate["value"])
