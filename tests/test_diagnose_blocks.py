"""Physics blocks of diagnosis: conventions, steady states, exactness, persistence."""

from __future__ import annotations

import math

import numpy as np
import preisach._core as core
import pytest
from preisach import PreisachModel
from preisach.daq.blocks import make_block
from preisach.diagnose import (
    EFFECT_TYPES,
    AugmentedModel,
    FirstOrderInputLag,
    FractionalDelay,
    GainOffset,
    LagrangeDelay,
    LevelDependentGain,
    OutputFeedback,
    PronyCreep,
    RateDependentPlay,
    RateDependentWidth,
    ReversibleRelaxation,
    SecondOrderMode,
    SensorDrift,
    TwoModes,
)
from preisach.diagnose.effects import effect_from_dict

DT = 1e-3
#: Two modes, the second in antiphase (Hz, 1, 1).
TWO_MODES = dict(
    f_n=90.0, zeta=0.03, participation=0.25, f_n2=310.0, zeta2=0.008, participation2=-0.2
)


def _examples():
    return [
        SecondOrderMode(DT, f_n=37.62, zeta=0.02, participation=0.5),
        SecondOrderMode(DT, f_n=264.0, zeta=0.01, participation=0.3, hold=1.6),
        TwoModes(DT, **TWO_MODES, hold=2.0),
        PronyCreep(DT, taus=[0.02, 0.2, 2.0], weights=[0.01, 0.02, 0.005], gain=1.01),
        FractionalDelay(DT, tau=2.3e-3),
        LagrangeDelay(DT, tau=2.3e-3),
        LagrangeDelay(DT, tau=0.4e-3),
        FirstOrderInputLag(DT, tau=1.5e-3),
        RateDependentPlay(DT, w_ref=0.5, exponent=0.5, v_ref=200.0, tau_v=5e-3),
        SensorDrift(DT, offset=1e-3, rate=2e-4),
        LevelDependentGain(DT, c2=0.01, c3=-0.02, x_c=0.0, span=3.5),
        GainOffset(DT, gain=1.02, offset=-3e-3),
    ]


@pytest.mark.parametrize("blk", _examples(), ids=lambda b: type(b).__name__)
def test_run_in_pieces_equals_one_run_and_step(blk):
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(0, 0.05, 1500))
    blk.reset(float(x[0]))
    whole = blk.run(x)
    blk.reset(float(x[0]))
    parts = np.concatenate([blk.run(x[:700]), blk.run(x[700:1201]), blk.run(x[1201:])])
    np.testing.assert_allclose(parts, whole, rtol=0, atol=1e-12)
    blk.reset(float(x[0]))
    steps = np.array([blk.step(v) for v in x[:50]])
    np.testing.assert_allclose(steps, whole[:50], rtol=0, atol=1e-12)


@pytest.mark.parametrize("blk", _examples(), ids=lambda b: type(b).__name__)
def test_reset_is_a_steady_state(blk):
    y0 = blk.reset(0.7)
    y = blk.run(np.full(300, 0.7))
    if isinstance(blk, SensorDrift):  # drifts with time by design
        np.testing.assert_allclose(y, 0.7 + 1e-3 + 2e-4 * DT * np.arange(1, 301), atol=1e-15)
    else:
        np.testing.assert_allclose(y, y0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("blk", _examples(), ids=lambda b: type(b).__name__)
def test_dict_round_trip_and_units(blk):
    d = blk.to_dict()
    back = effect_from_dict(d)
    assert type(back) is type(blk) and back.params == blk.params and back.dt == blk.dt
    assert set(blk.units) == set(blk.params)
    assert type(blk).__name__ in EFFECT_TYPES
    assert blk.kind in blk.describe()


def test_structural_mode_equals_the_rigs_block():
    x = np.concatenate([np.zeros(5), np.ones(300)]) + 0.3 * np.sin(0.3 * np.arange(305))
    for f, z in ((37.62, 0.02), (120.0, 0.3), (5.0, 1.0), (20.0, 2.0)):
        rig = make_block({"kind": "structural_mode", "frequency": f, "damping": z}, DT)
        rig.reset(0.0)
        mine = SecondOrderMode(DT, f_n=f, zeta=z, participation=1.0)
        mine.reset(0.0)
        np.testing.assert_allclose(mine.run(x), rig.run(x), rtol=0, atol=1e-9)


def test_a_mode_with_a_reaction_is_the_zoh_of_its_transfer_function():
    # y = x + m (G x - x) - r s^2/D x: the ZOH discretisation of the whole transfer function
    # (scipy), read at the end of each held interval (direct feedthrough of the held sample)
    from scipy import signal

    x = np.random.default_rng(2).standard_normal(400).cumsum()
    for f, z, m, r in ((120.0, 0.1, 0.3, 0.5), (247.0, 0.14, 0.0, 0.5), (40.0, 0.02, 1.2, -0.7)):
        w = 2 * math.pi * f
        den = np.array([1.0, 2 * z * w, w * w])
        num = den + m * (np.array([0.0, 0.0, w * w]) - den) - r * np.array([1.0, 0.0, 0.0])
        bd, ad, _ = signal.cont2discrete((num, den), DT, method="zoh")
        ys = signal.lfilter(bd.ravel(), ad, np.r_[x, x[-1]])
        d = num[0] / den[0]
        want = ys[1:] - d * np.r_[x[1:], x[-1]] + d * x
        blk = SecondOrderMode(DT, f_n=f, zeta=z, participation=m, reaction=r)
        blk.reset(0.0)
        np.testing.assert_allclose(blk.run(x), want, rtol=0, atol=1e-9)
        assert blk.reset(1.7) == 1.7 and blk.run(np.full(50, 1.7)) == pytest.approx(1.7)
    # files written before the reaction existed load with none
    old = SecondOrderMode(DT, f_n=50.0, zeta=0.1, participation=0.4).to_dict()
    del old["params"]["reaction"]
    back = effect_from_dict(old)
    assert back.params["reaction"] == 0.0
    assert back.to_dict() == SecondOrderMode(DT, f_n=50.0, zeta=0.1, participation=0.4).to_dict()


def test_a_mode_under_a_first_order_hold_is_its_response_to_the_input_linear_between_samples():
    # hold 1: the continuous system driven by the samples joined by straight lines (scipy's
    # lsim interpolates so); hold h: the mix (1 - h) zero-order + h first-order, unit DC gain
    from scipy import signal

    x = np.r_[0.0, np.random.default_rng(3).standard_normal(399).cumsum()]
    t = np.arange(x.size) * DT
    for f, z, m, r in ((120.0, 0.1, 0.3, 0.5), (264.0, 0.03, 0.9, 0.0), (40.0, 0.02, 1.2, -0.7)):
        w = 2 * math.pi * f
        den = np.array([1.0, 2 * z * w, w * w])
        num = den + m * (np.array([0.0, 0.0, w * w]) - den) - r * np.array([1.0, 0.0, 0.0])
        _, want, _ = signal.lsim((num, den), x, t, interp=True)
        blocks = [
            SecondOrderMode(DT, f_n=f, zeta=z, participation=m, reaction=r, hold=h)
            for h in (0.0, 1.0, 0.3)
        ]
        runs = []
        for b in blocks:
            b.reset(0.0)
            runs.append(b.run(x))
        zoh, foh, mix = runs
        np.testing.assert_allclose(foh, want, rtol=0, atol=1e-9)
        np.testing.assert_allclose(mix, 0.7 * zoh + 0.3 * foh, rtol=0, atol=1e-9)
        assert np.abs(foh - zoh).max() > 0.05 * np.abs(np.diff(x)).max()
        assert blocks[2].reset(1.7) == 1.7 and blocks[2].run(np.full(50, 1.7)) == pytest.approx(1.7)
    # files written before the hold existed load with a zero-order hold
    old = SecondOrderMode(DT, f_n=50.0, zeta=0.1, participation=0.4).to_dict()
    del old["params"]["hold"]
    assert effect_from_dict(old).params["hold"] == 0.0


def test_a_mode_read_as_its_input_is_updated_is_the_zero_order_response_a_sample_later():
    # hold 2: the reading taken as the input changes, before the mode has moved: the part
    # through the mode is the zero-order-hold response one sample later, the rest is at once;
    # between 1 and 2 the mix of the first-order and that response
    x = np.r_[0.0, np.random.default_rng(4).standard_normal(399).cumsum()]
    for f, z, m, r in ((120.0, 0.1, 0.3, 0.5), (337.0, 0.006, 0.2, 0.0)):
        runs = []
        for h in (0.0, 1.0, 2.0, 1.25):
            b = SecondOrderMode(DT, f_n=f, zeta=z, participation=m, reaction=r, hold=h)
            b.reset(0.0)
            runs.append(b.run(x))
        zoh, foh, late, mix = runs
        through = 1.0 - m - r  # the part that passes at once: y = through x + (the mode's)
        np.testing.assert_allclose(
            late[1:] - through * x[1:], zoh[:-1] - through * x[:-1], rtol=0, atol=1e-9
        )
        np.testing.assert_allclose(mix, 0.75 * foh + 0.25 * late, rtol=0, atol=1e-9)
        b = SecondOrderMode(DT, f_n=f, zeta=z, participation=m, reaction=r, hold=2.0)
        assert b.reset(-0.4) == -0.4 and b.run(np.full(30, -0.4)) == pytest.approx(-0.4)


@pytest.mark.parametrize("hold", [0.0, 0.5, 1.0, 2.0])
def test_two_modes_are_the_sum_of_their_modes(hold):
    # y = x + m1 (G1 x - x) + m2 (G2 x - x): the modal sum, participations of either sign
    x = np.r_[np.zeros(5), np.random.default_rng(6).standard_normal(500).cumsum()]
    both = TwoModes(DT, **TWO_MODES, hold=hold)
    one = SecondOrderMode(DT, f_n=90.0, zeta=0.03, participation=0.25, hold=hold)
    two = SecondOrderMode(DT, f_n=310.0, zeta=0.008, participation=-0.2, hold=hold)
    for b in (both, one, two):
        b.reset(0.0)
    np.testing.assert_allclose(both.run(x), one.run(x) + two.run(x) - x, rtol=0, atol=1e-9)


def test_structural_mode_rings_at_its_frequency():
    m = SecondOrderMode(DT, f_n=40.0, zeta=0.01, participation=1.0)
    m.reset(0.0)
    y = m.run(np.ones(4000)) - 1.0
    zc = np.flatnonzero(np.diff(np.sign(y[100:])) != 0)
    f = 1.0 / (2 * np.mean(np.diff(zc)) * DT)
    assert f == pytest.approx(40.0 * math.sqrt(1 - 0.01**2), rel=5e-3)


def test_creep_step_response_is_the_sum_of_lags():
    c = PronyCreep(DT, taus=[0.02, 0.2, 2.0], weights=[0.01, 0.02, 0.03], gain=1.05)
    c.reset(0.0)
    y = c.run(np.ones(5000))
    t = (np.arange(5000) + 1) * DT
    ref = 1.05 - sum(w * np.exp(-t / tau) for w, tau in zip([0.01, 0.02, 0.03], [0.02, 0.2, 2.0]))
    np.testing.assert_allclose(y, ref, atol=1e-12)


def test_fractional_delay_shifts_a_ramp():
    d = FractionalDelay(DT, tau=2.5e-3)
    d.reset(0.0)
    y = d.run(np.arange(100.0))
    np.testing.assert_allclose(y[10:], np.arange(100.0)[10:] - 2.5)


def test_lagrange_delay_is_a_delay_up_to_a_tenth_of_the_sample_rate():
    """Whole samples shift exactly; a fraction of a sample delays a sine at 0.1 fs to within
    1 % of its amplitude, where linear interpolation (a two-tap average) is off by 4 %."""
    x = np.random.default_rng(3).normal(size=200)
    d = LagrangeDelay(DT, tau=3 * DT)
    d.reset(0.0)
    np.testing.assert_allclose(d.run(x)[3:], x[:-3], rtol=0, atol=1e-12)
    t = np.arange(400) * DT
    w = 2 * math.pi * 0.1 / DT
    for tau in (0.25, 0.5, 0.8, 1.5, 2.7):
        exact = np.sin(w * (t - tau * DT))[20:]
        lag = LagrangeDelay(DT, tau=tau * DT)
        lag.reset(0.0)
        assert np.max(np.abs(lag.run(np.sin(w * t))[20:] - exact)) < 0.01, tau
    lin = FractionalDelay(DT, tau=0.5 * DT)
    lin.reset(0.0)
    exact = np.sin(w * (t - 0.5 * DT))[20:]
    assert np.max(np.abs(lin.run(np.sin(w * t))[20:] - exact)) > 0.04


def test_input_lag_delays_a_slow_ramp_by_tau():
    lag = FirstOrderInputLag(DT, tau=3e-3)
    lag.reset(0.0)
    y = lag.run(np.arange(2000.0))
    e = math.exp(-1.0 / 3.0)  # exact ZOH lag of a ramp: e / (1 - e) samples, about tau - dt / 2
    assert np.arange(2000.0)[-1] - y[-1] == pytest.approx(e / (1 - e), rel=1e-9)


def test_play_width_follows_the_rate_and_is_a_relay_dilation():
    p = RateDependentPlay(DT, w_ref=1.0, exponent=1.0, v_ref=100.0, tau_v=1e-3)
    p.reset(0.0)
    up = np.linspace(0, 10, 101)  # 100 V/s
    z = p.run(up)
    assert up[-1] - z[-1] == pytest.approx(1.0, rel=0.02)  # lags by w_ref at v_ref
    z2 = p.run(np.full(50, 10.0))  # at rest the width shrinks and the play catches up
    assert z2[-1] == pytest.approx(10.0, abs=1e-6)


def test_level_dependent_gain_inverse_and_slope():
    b = LevelDependentGain(DT, c2=0.03, c3=-0.05, x_c=0.2, span=3.0)
    x = np.linspace(-3, 3, 101)
    np.testing.assert_allclose(b.inverse(b.run(x)), x, atol=1e-10)
    h = 1e-6
    np.testing.assert_allclose(b.slope(x), (b.run(x + h) - b.run(x - h)) / (2 * h), rtol=1e-6)


def test_output_feedback_matches_the_rigs_moving_stage():
    from preisach.daq.blocks import BlockChain, preisach_stage

    m = PreisachModel.builtin("ss15-1hz", levels=41)
    u = 90 * np.sin(np.linspace(0, 12, 3000)) - 5
    fb = OutputFeedback(DT, a=0.8, b=0.0, c=0.0, y_c=0.0, span=3.5)
    y, ue, _ = fb.simulate(m.table, u, m.negative_saturation())
    chain = BlockChain([preisach_stage(m, m.negative_saturation(), DT, 0.8)])
    chain.reset(float(u[0]))
    np.testing.assert_allclose(y, chain.run(u), atol=1e-12)
    assert np.max(np.abs(ue - np.clip(u, -100, 100))) > 0.5  # the feedback moved the input


def test_rate_dependent_width_scales_the_hysteretic_deviation():
    w = RateDependentWidth(DT, c=0.1, exponent=1.0, rho_ref=100.0, tau_v=1e-3)
    u = np.linspace(0, 10, 1001)  # 10 V/s: factor 0.1 -> 1 % of the deviation
    x = np.full(u.size, 2.0)
    anh = np.full(u.size, 1.0)
    y = w.apply(x, u, anh)
    assert y[-1] == pytest.approx(2.0 + 0.1 * 0.1 * 1.0, rel=1e-3)
    with pytest.raises(TypeError, match="apply"):
        w.run(x)


def test_reversible_relaxation_lags_a_ramp_by_k_tau_rate_and_settles():
    tau, k, rate = 0.6e-3, 0.02, 800.0  # s, V/V, V/s
    b = ReversibleRelaxation(DT, k=k, tau=tau)
    u = np.concatenate([rate * DT * np.arange(400), np.full(100, rate * DT * 399)])
    x = np.zeros(u.size)
    y = b.apply(x, u)
    p = math.exp(-DT / tau)  # a ramp under the exact zero-order-hold lag: u - z = p R dt/(1-p)
    assert y[399] == pytest.approx(-k * p * rate * DT / (1 - p), rel=1e-9)
    assert abs(y[-1]) < 1e-12 * k * rate  # a held input settles within a few tau
    np.testing.assert_array_equal(b.apply(x, np.full(u.size, 3.0)), x)  # none at rest
    back = effect_from_dict(b.to_dict())
    assert type(back) is ReversibleRelaxation and back.params == b.params
    with pytest.raises(TypeError, match="apply"):
        b.run(x)
    with pytest.raises(ValueError, match="tau"):
        ReversibleRelaxation(DT, k=k, tau=0.0)


def test_augmented_model_runs_the_blocks_that_need_the_preisach_input():
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    u = 80 * np.sin(np.linspace(0, 4 * np.pi, 2000))
    s0 = m.negative_saturation()
    x = m.simulate(u, s0, sample_time=DT).output
    grid = np.linspace(m.u_min, m.u_max, 401)
    anh = np.interp(u, grid, np.asarray(core.neutral_locus(m.table, grid)))
    w = RateDependentWidth(DT, c=0.1, exponent=1.0, rho_ref=100.0, tau_v=1e-3)
    r = ReversibleRelaxation(DT, k=0.02, tau=0.6e-3)
    want = r.apply(w.apply(x, u, anh), u)
    got = AugmentedModel(m, [w, r]).simulate(u, s0, sample_time=DT).output
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert np.max(np.abs(got - x)) > 0.05  # the blocks act
    mode = SecondOrderMode(DT, f_n=50.0, zeta=0.1, participation=1.0)
    assert not mode.needs_chain and w.needs_chain and r.needs_chain
    with pytest.raises(TypeError, match="run"):
        mode.apply_chain(x, u, s0, m)


def test_parameter_errors_name_block_and_parameter():
    with pytest.raises(ValueError, match="structural_mode: parameter f_n"):
        SecondOrderMode(DT, f_n=-1.0, zeta=0.1, participation=1.0)
    with pytest.raises(ValueError, match="delay: parameter tau"):
        FractionalDelay(DT, tau=-1e-3)
    with pytest.raises(TypeError, match="unknown parameter"):
        FractionalDelay(DT, tau=1e-3, bogus=1.0)
    with pytest.raises(TypeError, match="missing parameter"):
        GainOffset(DT, gain=1.0)
    with pytest.raises(ValueError, match="creep: need one weight per time constant"):
        PronyCreep(DT, taus=[0.1, 1.0], weights=[0.1], gain=1.0)
    with pytest.raises(ValueError, match="input sample 2 is not finite"):
        GainOffset(DT, gain=1.0, offset=0.0).run([0.0, 1.0, math.nan])
    with pytest.raises(ValueError, match="unknown type"):
        effect_from_dict({"type": "Nope", "dt": DT, "params": {}})


def test_core_kernels_errors():
    with pytest.raises(ValueError, match="width"):
        core.play_operator(np.zeros(3), np.zeros(2), 0.0)
    with pytest.raises(ValueError, match=r"width\[1\]"):
        core.play_operator(np.zeros(3), np.array([0.0, -1.0, 0.0]), 0.0)
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    with pytest.raises(ValueError, match="span"):
        core.simulate_moving(m.table, np.zeros(3), m.negative_saturation(), 0.1, 0.0, 0.0, 0.0)


def test_a_sensor_curve_statement_names_non_congruence_beside_it():
    """A static curve of the output and loops that change with the output level read alike on
    loop experiments: the statement names both and the experiment that separates them."""
    from types import SimpleNamespace

    from preisach.diagnose.candidates import OutputCurveCandidate

    ctx = SimpleNamespace(y_lo=-3.5, y_hi=3.5, y_centre=0.0, y_half_span=3.5)
    cand = OutputCurveCandidate()
    assert cand.key == "non_congruence/output_curve"
    cand.prepare(ctx)
    text = cand.statement(np.array([0.02, -0.01]), None, ctx)
    assert "minor loops are not congruent" in text and "sensor nonlinearity" in text
    assert "same minor loop recorded at several output levels" in text
