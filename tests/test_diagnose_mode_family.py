"""A structural mode seen through the reaction of a recoiling frame (issue 13).

The resonance candidate once fitted one form, ``y = x + m (G x - x)``: the sensor sees part of
its signal through the mode.  A frame or mount that recoils under the actuator's
acceleration gives another numerator, ``y = x - r s^2 / D x``, and no participation fits it
well (seed-19 blind case 008: a 247 Hz frame-reaction mode, 35 % held-out gain and
``unexplained``).  The device here is written from its differential equation, integrated in
the test, not with the package's block.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from _inputs import session, shrinking_sweep
from preisach import PreisachModel, Recording
from preisach.diagnose import diagnose

DT = 1e-3
NOISE = 1e-3  # V (the SS15 outputs span about 7 V)
F_N, ZETA, MU = 120.0, 0.08, 0.4  # Hz, 1, frame recoil per unit of the actuator's stroke
CANDIDATES = [
    "structural_resonance",
    "structural_resonance/reaction",
    "delay",
    "delay/first_order_lag",
]


@pytest.fixture(scope="module")
def model() -> PreisachModel:
    return PreisachModel.builtin("ss15-1hz", 41)


def _inputs() -> tuple[np.ndarray, list[tuple[str, np.ndarray]]]:
    ident = shrinking_sweep(DT)
    rng = np.random.default_rng(5)
    exps = []
    for name, n_levels, ramp, hold in (("steps", 14, 4, 300), ("ramps", 10, 25, 250)):
        levels = np.r_[0.0, rng.uniform(-90, 90, n_levels)]
        u = np.concatenate(
            [
                np.r_[np.linspace(a, b, ramp), np.full(hold, b)]
                for a, b in zip(levels[:-1], levels[1:])
            ]
        )
        exps.append((name, u))
    tt = np.arange(int(3 / DT)) * DT
    exps.append(("triangle 2 Hz", 80 * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * 2 * tt))))
    return ident, exps


def _frame(x: np.ndarray) -> np.ndarray:
    """``y = x + z`` with ``z'' + 2 zeta w z' + w^2 z = -mu x''`` (x held over each sample).

    Written as ``z = -mu x + mu (2 zeta w p' + w^2 p)`` with ``p'' + 2 zeta w p' + w^2 p = x``
    (no derivative of the held input), integrated by RK4 on 40 substeps per sample; the
    reading at the end of each sample interval.
    """
    w = 2 * math.pi * F_N
    h = DT / 40

    def f(s: np.ndarray, xk: float) -> np.ndarray:
        return np.array([s[1], xk - 2 * ZETA * w * s[1] - w * w * s[0]])

    s = np.array([x[0] / (w * w), 0.0])  # at rest with the first input
    y = np.empty_like(x)
    for k, xk in enumerate(x):
        for _ in range(40):
            k1 = f(s, xk)
            k2 = f(s + 0.5 * h * k1, xk)
            k3 = f(s + 0.5 * h * k2, xk)
            k4 = f(s + h * k3, xk)
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        z = -MU * xk + MU * (2 * ZETA * w * s[1] + w * w * s[0])
        y[k] = xk + z
    return y


def _recordings(model: PreisachModel) -> tuple[Recording, list[Recording]]:
    def simulate(u: np.ndarray) -> np.ndarray:
        x = model.simulate(u, model.anhysteretic_state(), sample_time=DT).output
        return _frame(x)

    ident, exps = _inputs()
    recs = session([("sweep", ident), *exps], simulate, NOISE, 13, DT)
    return recs[0], recs[1:]


def test_a_mode_in_a_recoiling_frame_is_named_with_its_frequency(model):
    ident, exps = _recordings(model)
    rep = diagnose(model, exps, identification=[ident], candidates=CANDIDATES, progress=False)
    assert rep.verdict == "structural_resonance", [e.evidence for e in rep.effects]
    eff = rep.effects[0]
    par = {k: v["value"] for k, v in eff.parameters.items()}
    assert abs(par["f_n"] / F_N - 1) < 0.03, par
    gain = 1 - eff.heldout_rmse_after / eff.heldout_rmse_before
    assert gain >= 0.5, eff.evidence
    # the ring within the holds predicted to the noise (the participation form alone left
    # 1.66 x there), and the recoil found with its size
    assert eff.holds is not None and eff.holds["ratio"] < 1.2, eff.holds
    assert abs(par["reaction"] / MU - 1) < 0.25, par
    assert "reaction to the actuator's acceleration" in eff.statement


def _blind_frame_mode(tmp_path: Path, seed: int, index: int) -> Any:
    """Blind case ``index`` of ``seed`` (a frame-reaction mode), diagnosed with the resonance
    forms from its identified model and sweep; the one effect, asserted named a resonance."""
    from _paths import blind_diagnosed

    forms, rep = blind_diagnosed(tmp_path, seed, index, ["structural_resonance"])
    assert forms == ["frame_reaction_mode"]
    assert rep.verdict == "structural_resonance", rep.summary()
    (eff,) = rep.effects
    return eff


@pytest.mark.slow
def test_a_lightly_damped_mode_between_the_scans_steps_is_found(tmp_path):
    """Blind seed 73's case 005 (scripts/blind2, written from physical descriptions only): a
    frame-reaction mode at 31.35 Hz with damping ratio 0.0063, 7.9 x the noise.  Its
    resonance is 1.3 % wide and its ring keeps its phase for about 25 cycles, so a start 3 %
    off (half the 6 % coarse step) projects it at almost nothing: from the coarse scan alone
    the best fit gained 5 % and the case was ``unexplained``.  The fine scan about the best
    coarse frequencies finds it.  Fails with ``REFINE_BEST = 0``."""
    eff = _blind_frame_mode(tmp_path, 73, 5)
    assert eff.parameters["f_n"]["value"] == pytest.approx(31.35, rel=0.005), eff.statement
    assert eff.parameters["zeta"]["value"] == pytest.approx(0.0063, rel=0.2), eff.statement
    assert eff.heldout_rmse_after < 0.5 * eff.heldout_rmse_before, eff.evidence


#: Two modes of a structure read away from its drive (the second in antiphase), and the
#: reading taken as the input is updated: Hz, damping ratio, participation.
MODES = ((90.0, 0.03, 0.25), (310.0, 0.008, -0.2))


def _two_modes_read_at_update(x: np.ndarray) -> np.ndarray:
    """``y = (1 - m1 - m2) x + m1 q1 + m2 q2``, ``q_k'' + 2 zeta_k w_k q_k' + w_k^2 q_k = w_k^2 x``.

    The input is held over each sample interval, and each reading is taken at the instant
    the input changes, before the modes have moved (a DAQ that samples as it updates).  The
    modal states are advanced exactly over an interval by the matrix exponential of the
    differential equations.
    """
    from scipy.linalg import expm

    steps = []
    for f, z, _ in MODES:
        w = 2 * math.pi * f
        aug = np.zeros((3, 3))
        aug[:2, :2] = [[0.0, 1.0], [-w * w, -2 * z * w]]
        aug[1, 2] = w * w
        e = expm(aug * DT)
        steps.append((e[:2, :2], e[:2, 2]))
    states = [np.array([x[0], 0.0]) for _ in MODES]  # at rest with the first input
    direct = 1.0 - sum(m for _, _, m in MODES)
    y = np.empty_like(x)
    for k, xk in enumerate(x):
        y[k] = direct * xk + sum(m * s[0] for (_, _, m), s in zip(MODES, states))
        states = [phi @ s + gam * xk for (phi, gam), s in zip(steps, states)]
    return y


def test_two_modes_read_as_the_input_is_updated_are_both_named(model):
    """One mode fitted to two lands on either or between them, and a mode read as its input
    is updated rings a sample later than under a zero- or first-order hold (121 degrees at
    337 Hz sampled at 1 kHz): generator-1 seed 90's case 001, two such modes, was
    ``unexplained`` (the one-mode scan's best start in one fold was 162 Hz, 337 Hz's alias
    on every fourth sample).  Fails with the hold limited to [0, 1] (one mode kept)."""

    def simulate(u: np.ndarray) -> np.ndarray:
        x = model.simulate(u, model.anhysteretic_state(), sample_time=DT).output
        return _two_modes_read_at_update(x)

    ident, exps = _inputs()
    # each recording from rest at its first input (a jump into a recording would ring from
    # before its first sample, where no model of it can start)
    parts = [("sweep", ident), *exps]
    recs = [session([p], simulate, NOISE, 17 + k, DT)[0] for k, p in enumerate(parts)]
    rep = diagnose(
        model,
        recs[1:],
        identification=[recs[0]],
        candidates=[*CANDIDATES, "structural_resonance/two_modes"],
        progress=False,
    )
    assert rep.verdict == "structural_resonance", rep.summary()
    (eff,) = rep.effects
    par = {k: v["value"] for k, v in eff.parameters.items()}
    found = sorted(
        [
            (par["f_n"], par["zeta"], par["participation"]),
            (par["f_n2"], par["zeta2"], par["participation2"]),
        ]
    )
    for (f, z, m), (f0, z0, m0) in zip(found, MODES):
        assert f == pytest.approx(f0, rel=0.005) and z == pytest.approx(z0, rel=0.2), found
        assert m == pytest.approx(m0, rel=0.1), found
    assert par["hold"] == pytest.approx(2.0, abs=0.1), par  # read as the input is updated
    assert eff.heldout_rmse_after < 0.15 * eff.heldout_rmse_before, eff.evidence
    assert "two structural modes" in eff.statement
    # one mode alone (the 90 Hz one) leaves 1.65 x the two modes' held-out RMSE (run)
    one = next(c for c in rep.candidates if c["name"] == "structural_resonance")
    assert one["heldout_rmse"] > 1.4 * eff.heldout_rmse_after, one


@pytest.mark.slow
def test_two_modes_of_the_first_blind_generator_are_both_named(tmp_path):
    """Generator-1 seed 90's case 001 (``scripts/blind``, written from physical descriptions
    only): two modes of a structure, 102.6 and 336.8 Hz (damping ratios 0.030 and 0.0062),
    participating alike, 9 x the noise, read as the input is updated.  It was
    ``unexplained`` at 14 x the noise: one mode scanned under a zero- or first-order hold on
    every fourth sample found 162 Hz in one fold (337 Hz aliased onto it) and predicted
    held-out data worse than no mode."""
    from _paths import blind1_diagnosed

    truth, rep = blind1_diagnosed(
        tmp_path,
        "structural_resonance",
        "two_mode_noncollocated",
        9000001,
        ["structural_resonance"],
    )
    (want,) = truth["effects"]
    assert rep.verdict == "structural_resonance", rep.summary()
    (eff,) = rep.effects
    par = {k: v["value"] for k, v in eff.parameters.items()}
    found = sorted([(par["f_n"], par["zeta"]), (par["f_n2"], par["zeta2"])])
    for (f, z), f0, z0 in zip(found, want["params"]["f_Hz"], want["params"]["zeta"]):
        assert f == pytest.approx(f0, rel=0.005) and z == pytest.approx(z0, rel=0.2), found
    assert rep.noise_test["ratio"] < rep.noise_test["threshold"], rep.summary()


@pytest.mark.slow
def test_a_mode_above_a_quarter_of_the_sample_rate_is_scanned_unaliased(tmp_path):
    """Blind seed 82's case 005 (scripts/blind2, written from physical descriptions only): a
    frame-reaction mode at 168 Hz (damping ratio 0.026), 9.8 x the noise, sampled at 1 kHz.
    The start scan projected trial modes on every fourth training sample (250 Hz), where
    168 Hz and 82 Hz are one signal; no start came near 168 Hz and the case was
    ``unexplained`` (12 x the noise).  Scanned on every sample the fit uses, it is found.
    Fails with the scan on the coarse rows."""
    eff = _blind_frame_mode(tmp_path, 82, 5)
    assert eff.parameters["f_n"]["value"] == pytest.approx(168.05, rel=0.01), eff.statement
