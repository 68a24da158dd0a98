"""Mayergoyz's representation properties hold exactly for the simulator (property tests)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from preisach import PreisachModel

MODEL = PreisachModel.builtin("ss15-4hz", levels=41)
volts = st.floats(-100.0, 100.0, allow_nan=False)
history = st.lists(volts, min_size=0, max_size=12)
initial = st.sampled_from(["anhysteretic", "negative", "positive", "neutral"])


def start_state(kind):
    return {
        "anhysteretic": MODEL.anhysteretic_state(),
        "negative": MODEL.negative_saturation(),
        "positive": MODEL.positive_saturation(),
        "neutral": MODEL.neutral_state(37.5),
    }[kind]


def path(points, per_segment=7):
    """Piecewise-linear input through the given points (continuous input)."""
    out = [np.linspace(a, b, per_segment, endpoint=False) for a, b in zip(points, points[1:])]
    return np.concatenate(out + [np.array(points[-1:])]) if out else np.array(points, float)


@settings(max_examples=150, deadline=None)
@given(initial, history, volts, volts, st.lists(st.floats(0.0, 1.0), max_size=10), history)
def test_wiping_out(kind, hist, a, b, fractions, cont):
    """An excursion inside [min(a,b), max(a,b)] between a and b leaves no trace once b is back."""
    lo, hi = min(a, b), max(a, b)
    excursion = [min(max(lo + f * (hi - lo), lo), hi) for f in fractions]
    s0 = start_state(kind)
    with_exc = MODEL.simulate(path(hist + [a] + excursion + [b]), s0)
    without = MODEL.simulate(path(hist + [a, b]), s0)
    assert with_exc.final_state == without.final_state
    assert with_exc.output[-1] == pytest.approx(without.output[-1], abs=1e-12)
    if cont:
        c = path([b] + cont)
        np.testing.assert_allclose(
            MODEL.simulate(c, with_exc.final_state).output,
            MODEL.simulate(c, without.final_state).output,
            atol=1e-12,
        )


@settings(max_examples=150, deadline=None)
@given(initial, initial, history, history, volts, volts, st.integers(1, 3))
def test_congruent_minor_loops(k1, k2, h1, h2, x, y, cycles):
    """Minor loops between the same two inputs have the same shape whatever the history."""
    u1, u2 = min(x, y), max(x, y)
    if u2 - u1 < 1e-3:
        return
    loop = path([u2] + [u1, u2] * cycles)
    shapes = []
    for kind, hist in ((k1, h1), (k2, h2)):
        s = MODEL.simulate(path(hist + [u1, u2]), start_state(kind)).final_state
        y_loop = MODEL.simulate(loop, s).output
        shapes.append(y_loop - y_loop[0])
    np.testing.assert_allclose(shapes[0], shapes[1], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(initial, history)
def test_readout_equals_simulated_output(kind, hist):
    res = MODEL.simulate(path(hist + [0.0]) if hist else np.array([0.0]), start_state(kind))
    assert MODEL.readout(res.final_state) == pytest.approx(res.output[-1], abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(history)
def test_output_stays_within_saturation_limits_for_mp_model(hist):
    m1 = PreisachModel.builtin("ss15-1hz", levels=41)  # mu >= 0: output bounded by y_min, y_max
    y = m1.simulate(path([0.0] + hist)).output
    assert np.all(y >= m1.y_min - 1e-12) and np.all(y <= m1.y_max + 1e-12)
