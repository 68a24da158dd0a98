"""Sensor drift and creep named right on forms the candidates were not written for.

The data come from physical descriptions, not from the candidates' forms: a strain-gauge
offset that follows the room temperature (a random walk of the air temperature seen through
the sensor housing's thermal lag, plus the air-conditioning cycle), and the logarithmic creep
law of piezo actuators (after each move the output keeps moving by a fixed share of the move
per decade of time).  The drift candidate is a spline with a chosen roughness, the creep
candidate a bank of four lags: neither is either of these.
"""

from __future__ import annotations

import numpy as np
import pytest
from preisach import PreisachModel, Recording
from preisach.diagnose import diagnose
from preisach.diagnose.drift import bspline_basis, choose_spacing, hold_check, spacing_options

DT = 5e-3  # 200 Hz keeps the test fast; the physics is slower than 1 Hz
NOISE = 1e-3


def _session(seed: int) -> tuple[PreisachModel, list[tuple[np.ndarray, np.ndarray]]]:
    """Three recordings of a lab session: steps and holds, a slow sine sweep, steps again."""
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    rng = np.random.default_rng(seed)
    lo, hi = m.u_min, m.u_max
    span = hi - lo
    out = []
    for k in range(3):
        if k == 1:
            t = np.arange(int(10.0 / DT)) * DT
            env = np.cos(2 * np.pi * 0.07 * t)
            u = lo + span * (0.5 + 0.45 * np.sin(2 * np.pi * 0.4 * t) * env)
        else:
            levels = lo + span * rng.uniform(0.05, 0.95, 8)
            u = np.repeat(levels, int(1.25 / DT))
            t = np.arange(u.size) * DT
        out.append((t, u))
    return m, out


def _recordings(
    m: PreisachModel, runs: list[tuple[np.ndarray, np.ndarray]], extra: list[np.ndarray], seed: int
) -> list[Recording]:
    rng = np.random.default_rng(seed + 100)
    recs = []
    for k, ((t, u), e) in enumerate(zip(runs, extra)):
        y = m.simulate(u, m.negative_saturation()).output + e
        y = y + rng.normal(0.0, NOISE, t.size)
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"run{k}"))
    return recs


def _thermal_drift(n_total: int, seed: int) -> np.ndarray:
    """Sensor offset (V) following the room: a random-walk air temperature through a 3 s
    thermal lag of the housing plus a 25 s air-conditioning cycle, 2 mV/K."""
    rng = np.random.default_rng(seed)
    air = np.cumsum(rng.normal(0.0, 0.02 * np.sqrt(DT), n_total))  # K, random walk
    t = np.arange(n_total) * DT
    air = air + 1.5 * np.sin(2 * np.pi * t / 25.0 + 1.0)
    housing = np.empty_like(air)
    a = np.exp(-DT / 3.0)
    housing[0] = air[0]
    for i in range(1, n_total):
        housing[i] = a * housing[i - 1] + (1 - a) * air[i]
    return 2e-3 * (housing - housing[0])


def _log_creep(m: PreisachModel, u: np.ndarray, gamma: float) -> np.ndarray:
    """Logarithmic creep: every output increment dP at t_k goes on moving by gamma dP per
    decade of time, y_c(t) = gamma sum_k dP_k log10(1 + (t - t_k) / 0.05 s) (superposed)."""
    p = m.simulate(u, m.negative_saturation()).output
    dp = np.diff(p, prepend=p[0])
    kernel = np.log10(1.0 + np.arange(u.size) * DT / 0.05)
    return gamma * np.convolve(dp, kernel)[: u.size]


CANDIDATES = ["sensor_drift", "creep", "gain_offset"]


@pytest.fixture(scope="module")
def session():
    return _session(3)


def test_a_thermal_drift_is_named_a_drift(session):
    m, runs = session
    n = [t.size for t, _ in runs]
    d = _thermal_drift(sum(n), seed=5)  # one room, drifting on through the session
    parts = np.split(d, np.cumsum(n)[:-1])
    rep = diagnose(m, _recordings(m, runs, parts, 3), candidates=CANDIDATES, progress=False)
    assert rep.verdict == "sensor_drift", rep.summary()
    assert rep.effects[0].heldout_rmse_after < 0.7 * rep.effects[0].heldout_rmse_before


def test_a_logarithmic_creep_is_creep_not_drift(session):
    m, runs = session
    extra = [_log_creep(m, u, 0.004) for _, u in runs]
    rep = diagnose(m, _recordings(m, runs, extra, 3), candidates=CANDIDATES, progress=False)
    assert rep.verdict == "creep", rep.summary()
    assert "sensor_drift" not in [e.name for e in rep.effects], rep.summary()


def test_roughness_is_chosen_on_held_out_time():
    """A fast wander gets finer knots than a slow ramp; no wander gets the smoothest."""
    t = np.arange(0.0, 12.0, 0.01)
    parity = (np.floor(t / 1.2).astype(np.int64)) % 2
    usable = np.ones(t.size, bool)
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 1e-3, t.size)
    opts = spacing_options(float(t[-1]))
    assert opts[0] == pytest.approx(t[-1]) and opts[-1] >= 0.5
    slow, _ = choose_spacing(t, 0.01 * t / 12 + noise, usable, parity)
    fast, _ = choose_spacing(t, 0.01 * np.sin(2 * np.pi * t / 4.0) + noise, usable, parity)
    none, _ = choose_spacing(t, noise, usable, parity)
    assert fast < slow and none == opts[0]
    assert bspline_basis(t, fast).shape[1] > bspline_basis(t, slow).shape[1]


def test_holds_tell_a_drift_from_a_smoothed_staircase():
    """During input holds a sensor drift moves the residual; a model's level errors do not."""
    dt = 0.01
    u = np.repeat([0.0, 3.0, -2.0, 5.0, 1.0, -4.0], 150)  # 1.5 s holds
    t = np.arange(u.size) * dt
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 1e-4, t.size)
    curve = 1e-2 * np.sin(2 * np.pi * t / 6.0)  # what a fitted drift says
    steps = np.repeat(rng.normal(0.0, 4e-3, 6), 150)  # level errors jumping at the steps
    y = np.repeat([0.0, 2.0, -1.5, 3.5, 0.5, -3.0], 150)  # the output's levels
    drift = hold_check([(u, curve + noise, curve, dt, y)], u_span=10.0)
    stair = hold_check([(u, steps + noise, curve, dt, y)], u_span=10.0)
    # a curve that moves on in the direction of each move into a hold follows the steps
    moves = np.repeat(np.diff(np.r_[0.0, y[::150]]), 150)
    creep_like = 1e-2 * moves * ((t % 1.5) / 1.5)
    creep = hold_check([(u, creep_like + noise, creep_like, dt, y)], u_span=10.0)
    assert creep.follows_t > 3.0 > abs(drift.follows_t)
    assert drift.n_holds == stair.n_holds == 5  # the first hold has no move into it
    assert not drift.refutes(1e-3) and stair.refutes(1e-3)
    assert not stair.refutes(stair.drift_motion)  # within twice the noise: no verdict


def _delayed(x: np.ndarray, samples: int) -> np.ndarray:
    """``x`` reaching the sensor ``samples`` samples late (the first value held before)."""
    return np.concatenate([np.full(samples, x[0]), x[:-samples]])


def test_a_drift_hidden_by_a_large_delay_is_found_after_it(session):
    """A drift curve fitted beside a large unmodelled effect can predict held-out data worse
    than none; once that effect is named, the drift must still be tried.

    Blind seed 51's case 004 (a thermal warm-up of the sensor, 9.4 x the noise, behind a
    one-sample transport delay, 5.9 x): the drift lowered the held-out error by 0.2 % beside
    the delay's 40 mV, was not tried again after it, and the verdict was `delay` alone; tried
    after the delay, it lowers the error by 36 %.
    """
    m, runs = session
    n = [t.size for t, _ in runs]
    d = _thermal_drift(sum(n), seed=5)
    parts = np.split(d, np.cumsum(n)[:-1])
    rng = np.random.default_rng(7)
    recs = []
    for k, ((t, u), e) in enumerate(zip(runs, parts)):
        y = _delayed(m.simulate(u, m.negative_saturation()).output, 2) + e
        y = y + rng.normal(0.0, NOISE, t.size)
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"run{k}"))
    rep = diagnose(m, recs, candidates=["delay", "sensor_drift"], progress=False)
    first = {c["name"]: c for c in rep.to_dict()["candidates"] if c["step"] == 1}
    assert first["sensor_drift"]["gain"] < 0.02, first  # the case the retry is for
    assert [e.name for e in rep.effects] == ["delay", "sensor_drift"], rep.summary()


def test_a_drift_beside_creep_is_named_with_it(session, monkeypatch):
    """A room drift twice the size of the first test's beside the logarithmic creep.

    Fitted alone, the drift curve takes up the creep too and moves on in the holds in the
    direction of each move into them, as creep does; it was refused for that, and the
    verdict was creep alone. Fitted with the creep, it no longer follows the steps, and the
    pair predicts held-out data better than either alone: both are named, the drift first
    (it gains most). The first blind generator's seed 91 had two such mixtures that ended
    ``unexplained`` (docs/diagnosis.md, section 5zj). Fails when the drift is refused for
    following the steps without being fitted beside the creep, or when the creep fitted
    beside it is fitted again in the next step (the same fit, done twice).
    """
    from preisach.diagnose.context import Context

    fits: list[tuple[str, int, int, bool]] = []
    fit = Context.fit

    def counted(self, cand, fixed, train, drift=False, starts=None):
        fits.append((cand.key, id(fixed), id(train), drift))
        return fit(self, cand, fixed, train, drift, starts)

    monkeypatch.setattr(Context, "fit", counted)
    m, runs = session
    n = [t.size for t, _ in runs]
    d = 2.0 * _thermal_drift(sum(n), seed=5)
    parts = np.split(d, np.cumsum(n)[:-1])
    extra = [p + _log_creep(m, u, 0.004) for p, (_, u) in zip(parts, runs)]
    rep = diagnose(m, _recordings(m, runs, extra, 3), candidates=CANDIDATES, progress=False)
    assert [e.name for e in rep.effects] == ["sensor_drift", "creep"], rep.summary()
    (drift,) = [c for c in rep.to_dict()["candidates"] if c["name"] == "sensor_drift"]
    assert drift["decision"].startswith("qualifies beside creep"), drift["decision"]
    assert any(k == "creep" and d for k, _, _, d in fits)
    assert len(set(fits)) == len(fits), "a fit was made twice"


@pytest.mark.slow
def test_a_drift_beside_creep_of_the_first_blind_generator_is_named(tmp_path):
    """Generator-1 seed 91's case 012 (``scripts/blind``, written from physical descriptions
    only): a random-walk sensor drift beside a creep that follows the input as a power law
    of time. Fitted alone, the drift gained 61 % of the held-out RMSE but followed the input
    steps (t = 5.5 over four holds), and the creep alone gained 9 %: ``unexplained`` at
    12 x the noise. Fails when the drift is not fitted beside the creep."""
    from _paths import blind1_diagnosed

    # a mixture's forms drawn by the generator, as its study run does
    kinds = ["sensor_drift", "creep"]
    truth, rep = blind1_diagnosed(tmp_path, kinds, [None, None], 9100012, kinds)
    assert truth["forms"] == ["random_walk", "power_law_input"], truth["forms"]
    assert [e.name for e in rep.effects] == ["sensor_drift", "creep"], rep.summary()
    assert rep.noise_test["ratio"] < 3.0, rep.summary()


@pytest.mark.slow
def test_a_drift_beside_a_kept_delay_is_measured_beyond_it(tmp_path):
    """Generator-1 seed 94's case 006 (``scripts/blind``, written from physical descriptions
    only): a sensor drift (a linear trend and a 133 s cycle) behind a 3-sample FIR delay,
    52 x the noise on the noise experiment. The delay is kept first; the drift then gains
    37 % of the held-out RMSE. Against the fine classical model alone it added 2.0 noise
    variances but at sign-flip p 0.028, the delay's residual left in the blocks compared, and
    was refused (the full run named a non-congruence instead). Measured beside the delay it
    passes. Fails when the drift's check leaves out the effects already kept."""
    from _paths import blind1_diagnosed

    kinds = ["delay", "sensor_drift"]
    truth, rep = blind1_diagnosed(tmp_path, kinds, [None, None], 9400006, kinds)
    assert truth["forms"] == ["fir_group_delay", "linear_plus_cycle"], truth["forms"]
    assert [e.name for e in rep.effects] == ["delay", "sensor_drift"], rep.summary()
