"""Exact inverse of the Preisach model (preisach.compensate, C++ Inverter)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from preisach import PreisachModel
from preisach.compensate import InverseResult, invert

MODEL = PreisachModel.builtin("ss15-1hz", levels=41)
MODEL_201 = PreisachModel.builtin("ss15-1hz")
volts = st.floats(-100.0, 100.0, allow_nan=False)
initial = st.sampled_from(["anhysteretic", "negative", "positive", "neutral", "history"])


def start_state(model, kind, hist=(40.0, -60.0, 20.0)):
    return {
        "anhysteretic": model.anhysteretic_state,
        "negative": model.negative_saturation,
        "positive": model.positive_saturation,
        "neutral": lambda: model.neutral_state(-37.5),
        "history": lambda: model.state_from_extrema(list(hist)),
    }[kind]()


def walk(points, per_segment=9):
    """Piecewise-linear input through the points (V)."""
    out = [np.linspace(a, b, per_segment, endpoint=False) for a, b in zip(points, points[1:])]
    return np.concatenate(out + [np.array(points[-1:])]) if out else np.array(points, float)


@settings(max_examples=120, deadline=None)
@given(initial, st.lists(volts, min_size=0, max_size=6), st.lists(volts, min_size=2, max_size=10))
def test_simulate_of_inverse_reproduces_reachable_references(kind, hist, pts):
    """Any reference the model can produce from a state is reproduced to 1e-9 V."""
    s0 = start_state(MODEL, kind, hist) if hist else start_state(MODEL, kind)
    u_true = walk(pts)
    y_ref = MODEL.simulate(u_true, s0).output
    r = MODEL.inverse(y_ref, s0)
    assert r.unreachable == 0 and r.reached.all()
    np.testing.assert_allclose(r.output, y_ref, rtol=0, atol=1e-9)
    sim = MODEL.simulate(r.input, s0)
    np.testing.assert_array_equal(sim.output, r.output)  # the same simulator, bit for bit
    assert sim.final_state == r.final_state
    assert np.all(r.input >= MODEL.u_min) and np.all(r.input <= MODEL.u_max)


def test_a_target_exactly_at_saturation_is_reached():
    """Found by the property above in CI: from positive saturation, down to 6 V and up to the
    range end, the last target is y_max exactly; the inverse gave it but counted it
    unreachable (no piece's interior holds it)."""
    s0 = MODEL.positive_saturation()
    y_ref = MODEL.simulate(walk([6.0, 100.0]), s0).output
    assert y_ref[-1] == MODEL.y_max
    r = MODEL.inverse(y_ref, s0)
    assert r.unreachable == 0 and r.reached.all()
    np.testing.assert_allclose(r.output, y_ref, rtol=0, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(initial, st.lists(st.floats(-12.0, 12.0, allow_nan=False), min_size=1, max_size=40))
def test_arbitrary_references_reached_or_counted(kind, ys):
    """Random targets (some beyond saturation): reached exactly or counted, never raised."""
    s0 = start_state(MODEL, kind)
    y_ref = np.array(ys)
    r = MODEL.inverse(y_ref, s0)
    hit = r.reached
    np.testing.assert_allclose(r.output[hit], y_ref[hit], atol=1e-9)
    beyond = (y_ref > MODEL.y_max) | (y_ref < MODEL.y_min)
    assert not hit[beyond].any()  # a monotone model reaches everything in [y_min, y_max]
    assert r.unreachable == int(beyond.sum())
    np.testing.assert_array_equal(r.input[y_ref > MODEL.y_max], MODEL.u_max)
    np.testing.assert_array_equal(r.input[y_ref < MODEL.y_min], MODEL.u_min)
    np.testing.assert_array_equal(MODEL.simulate(r.input, s0).output, r.output)


def test_recovers_the_input_sample_for_sample():
    """mu > 0: the input is unique, so a shifted, stale or mis-stated inverse would differ."""
    rng = np.random.default_rng(3)
    u_true = np.clip(np.cumsum(rng.normal(0, 6.0, 3000)), -100, 100)
    s0 = MODEL.neutral_state(12.0)
    y_ref = MODEL.simulate(u_true, s0).output
    r = MODEL.inverse(y_ref, s0)
    np.testing.assert_allclose(r.input, u_true, atol=1e-7)
    # Off by one sample: the input shifted by one gives outputs visibly off.
    shifted = MODEL.simulate(np.r_[s0.input, u_true[:-1]], s0).output
    assert np.max(np.abs(shifted - y_ref)) > 0.05
    # Wrong state: the same reference inverted from another state needs another input.
    other = MODEL.inverse(y_ref, MODEL.negative_saturation())
    assert np.max(np.abs(other.input - u_true)) > 1.0
    truth = MODEL.simulate(u_true, s0).final_state
    np.testing.assert_allclose(r.final_state.b0, truth.b0, atol=1e-7)
    np.testing.assert_allclose(r.final_state.v, truth.v, atol=1e-7)


def test_reversal_is_taken_at_the_right_sample():
    """Up to a maximum and back: the input turns at the same sample and the loop closes."""
    s0 = MODEL.negative_saturation()
    u_true = np.r_[np.linspace(-100, 55, 40), np.linspace(54, -30, 30), np.linspace(-29, 55, 30)]
    y_ref = MODEL.simulate(u_true, s0).output
    r = MODEL.inverse(y_ref, s0)
    k = int(np.argmax(r.input[:70]))
    assert k == 39 and r.input[k] == pytest.approx(55.0, abs=1e-9)
    assert r.input[40] < r.input[39]  # the descent starts the sample after the maximum
    # wiping-out: back at 55 V the state is the one after the first rise
    first = MODEL.simulate(u_true[:40], s0).final_state
    assert r.final_state.input == pytest.approx(55.0, abs=1e-9)
    np.testing.assert_allclose(r.final_state.v, first.v, atol=1e-9)
    # The descending branch differs from the ascending one: a mirrored (no-memory) inverse fails.
    assert abs(r.input[55] - np.interp(y_ref[55], y_ref[:40], u_true[:40])) > 1.0


def test_step_by_step_matches_the_array_and_continues_from_the_final_state():
    rng = np.random.default_rng(4)
    s0 = MODEL.anhysteretic_state()
    y_ref = MODEL.simulate(np.clip(np.cumsum(rng.normal(0, 8.0, 500)), -100, 100), s0).output
    whole = MODEL.inverse(y_ref, s0)
    inv = MODEL.inverter(s0)
    u = np.array([inv.step(y) for y in y_ref])
    np.testing.assert_array_equal(u, whole.input)
    assert inv.state == whole.final_state and inv.output == whole.output[-1]
    first = MODEL.inverse(y_ref[:200], s0)
    second = MODEL.inverse(y_ref[200:], first.final_state)
    # a restart recomputes the stack's sums from the state: equal to rounding
    np.testing.assert_allclose(np.r_[first.input, second.input], whole.input, rtol=0, atol=1e-9)
    u_next, ok = inv.solve(0.0)
    assert ok and inv.input == whole.input[-1]  # solve does not move the state
    assert inv.step(0.0) == u_next and inv.output == pytest.approx(0.0, abs=1e-12)


def test_unreachable_and_bad_targets():
    inv = MODEL.inverter(MODEL.negative_saturation())
    assert inv.monotone
    assert inv.step(MODEL.y_max + 3.0) == MODEL.u_max
    assert inv.unreachable == 1 and inv.output == pytest.approx(MODEL.y_max)
    with pytest.raises(ValueError, match=r"y\[0\]"):
        inv.step(float("nan"))
    with pytest.raises(ValueError, match=r"y\[2\] is not finite"):
        MODEL.inverse([0.0, 1.0, np.inf])
    with pytest.raises(ValueError, match="y_ref"):
        MODEL.inverse(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="nonmonotone"):
        MODEL.inverse([0.0], nonmonotone="guess")
    r = MODEL.inverse([], MODEL.negative_saturation())
    assert len(r) == 0 and r.max_error == 0.0


def test_result_time_and_unpacking():
    t = np.array([0.0, 0.1, 0.3])
    r = MODEL.inverse([0.0, 1.0, 2.0], t=t)
    assert isinstance(r, InverseResult)
    tt, u = r
    np.testing.assert_array_equal(tt, t)
    np.testing.assert_array_equal(u, r.input)
    assert r.max_error < 1e-9
    assert np.array_equal(invert(MODEL, [0.0], sample_time=0.5).time, [0.0])
    with pytest.raises(ValueError, match="t"):
        MODEL.inverse([0.0, 1.0], t=[0.0, 0.0])


@pytest.mark.parametrize("name", ["ss15-2hz", "ss15-4hz"])
def test_nonmonotone_surfaces(name):
    """Negative cells: inverted as is (smallest excursion) or projected; both well defined."""
    model = PreisachModel.builtin(name)  # 201 levels: a few cells of negative weight
    assert np.any(model.cell_weights() < 0)
    rng = np.random.default_rng(5)
    s0 = model.anhysteretic_state()
    y_ref = model.simulate(np.clip(np.cumsum(rng.normal(0, 5.0, 800)), -100, 100), s0).output
    r = model.inverse(y_ref, s0)
    assert not model.inverter(s0).monotone
    np.testing.assert_allclose(r.output[r.reached], y_ref[r.reached], atol=1e-9)
    assert r.reached.mean() > 0.95
    np.testing.assert_array_equal(model.simulate(r.input, s0).output, r.output)
    # the smallest excursion: no input between the previous one and the chosen one reaches it
    inv = model.inverter(s0)
    for k in range(200):
        u_prev, state = inv.input, inv.state
        u_k = inv.step(y_ref[k])
        if abs(u_k - u_prev) > 1e-6:
            grid = np.linspace(u_prev, u_k, 50)[1:-1]
            ys = model.simulate_batch(grid[:, None], [state] * grid.size)[0][:, 0]
            y0 = model.readout(state)
            crossed = np.sign(ys - y_ref[k]) != np.sign(y0 - y_ref[k])
            assert not crossed.any()
    p = model.inverse(y_ref, s0, nonmonotone="project")
    assert p.extra["projected"]
    np.testing.assert_array_equal(model.simulate(p.input, s0).output, p.output)
    assert np.max(np.abs(p.output - y_ref)) < 0.05 * (model.y_max - model.y_min)
