"""Rate dependence from a relaxing reversible response, told apart from a delay (issue 13).

A Debye-relaxing share of the reversible response (``tau`` below the sample time) widens the
loops in proportion to the input *rate*; a delay of the output lags in proportion to the
output's rate, as much as the loop is steep.  Both lower the held-out error of the classical
SS15 model; the relaxation must be named rate dependence on the first device and not on the
delayed one.  (On the seen blind set of seed 15 the delay was named for such a relaxation.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from _inputs import session, shrinking_sweep
from preisach import PreisachModel, Recording
from preisach.diagnose import AugmentedModel, ReversibleRelaxation, diagnose, load_model

DT = 1e-3
NOISE = 1e-3  # V (the SS15 outputs span about 7 V)
CANDIDATES = [
    "rate_dependence/relaxation",
    "rate_dependence/viscous",
    "delay",
    "delay/first_order_lag",
]


def _inputs() -> tuple[np.ndarray, list[tuple[str, np.ndarray]]]:
    ident = shrinking_sweep(DT)
    rng = np.random.default_rng(3)
    exps = []
    for f, amp, T in ((0.5, 90.0, 3.0), (2.0, 70.0, 3.0), (4.0, 100.0, 3.0), (6.0, 80.0, 2.0)):
        tt = np.arange(int(T / DT)) * DT
        exps.append(
            (f"triangle {f:g} Hz", amp * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * f * tt)))
        )
    levels = np.r_[0.0, rng.uniform(-90, 90, 8)]  # from where the triangles end
    steps = np.concatenate([np.linspace(a, b, 15) for a, b in zip(levels[:-1], levels[1:])])
    exps.append(("ramps", np.repeat(steps, 20)))
    return ident, exps


def _recordings(simulate) -> tuple[Recording, list[Recording]]:
    ident, exps = _inputs()
    recs = session([("sweep", ident), *exps], simulate, NOISE, 11, DT)
    return recs[0], recs[1:]


@pytest.fixture(scope="module")
def model() -> PreisachModel:
    return PreisachModel.builtin("ss15-1hz", 41)


def _classical(model: PreisachModel, u: np.ndarray) -> np.ndarray:
    return model.simulate(u, model.anhysteretic_state(), sample_time=DT).output


def test_a_relaxing_reversible_response_is_rate_dependence_not_a_delay(model, tmp_path):
    tau, k = 0.6e-3, 0.0175  # s; V/V, half the output's mean slope (7 V over 200 V)
    pole = math.exp(-DT / tau)

    def simulate(u: np.ndarray) -> np.ndarray:  # written here, not with the package's block
        z = np.empty_like(u)
        z_prev = u[0]
        for i, v in enumerate(u):
            z_prev = pole * z_prev + (1 - pole) * v
            z[i] = z_prev
        return _classical(model, u) - k * (u - z)

    ident, exps = _recordings(simulate)
    rep = diagnose(model, exps, identification=[ident], candidates=CANDIDATES, progress=False)
    assert rep.verdict == "rate_dependence", [e.evidence for e in rep.effects]
    eff = rep.effects[0]
    gain = 1 - eff.heldout_rmse_after / eff.heldout_rmse_before
    assert gain >= 0.30, eff.evidence
    assert "relaxes" in eff.statement and "whatever the hysteretic state" in eff.statement
    aug = rep.model
    assert isinstance(aug, AugmentedModel)
    assert any(isinstance(b, ReversibleRelaxation) for b in aug.blocks)
    # the augmented model follows the fastest triangle closer than its base, and round-trips
    r = exps[3]
    s0 = aug.anhysteretic_state()
    y_aug = aug.simulate(r.u, s0, sample_time=DT).output
    y_base = aug.base.simulate(r.u, s0, sample_time=DT).output
    late = slice(r.u.size // 2, None)  # after the start is wiped out
    assert np.std((r.y - y_aug)[late]) < 0.5 * np.std((r.y - y_base)[late])
    aug.save(tmp_path / "aug.npz")
    back = load_model(tmp_path / "aug.npz")
    assert back == aug
    np.testing.assert_array_equal(back.simulate(r.u, s0, sample_time=DT).output, y_aug)


def test_a_delayed_reading_stays_a_delay(model):
    def simulate(u: np.ndarray) -> np.ndarray:  # the reading two samples late
        y = _classical(model, u)
        return np.concatenate([np.full(2, y[0]), y[:-2]])

    ident, exps = _recordings(simulate)
    rep = diagnose(model, exps, identification=[ident], candidates=CANDIDATES, progress=False)
    assert rep.verdict == "delay", [e.evidence for e in rep.effects]
