"""Inverse of the rate-dependent model (preisach.compensate.rate)."""

from __future__ import annotations

import numpy as np
import pytest
from preisach.compensate.rate import invert_rate
from preisach.rate_model import RateDependentPreisachModel

MODEL = RateDependentPreisachModel.builtin("ss15-rate", levels=41)


@pytest.mark.parametrize("f", [0.5, 2.0, 6.0])
def test_simulate_of_inverse_reproduces_a_reachable_reference(f):
    t = np.arange(int(1.5 / 1e-3)) * 1e-3
    u_true = 80 * np.sin(2 * np.pi * f * t) - 10 * np.sin(2 * np.pi * 3.1 * f * t)
    s0 = MODEL.negative_saturation()
    y_ref = MODEL.simulate(u_true, s0).output
    r = invert_rate(MODEL, y_ref, s0)
    assert r.unreachable == 0
    np.testing.assert_allclose(r.output, y_ref, atol=1e-9)
    np.testing.assert_array_equal(MODEL.simulate(r.input, s0).output, r.output)
    if f >= 2.0:  # rates above the first knot: the slow table's classical inverse misses
        classical = MODEL.models[0].inverse(y_ref, s0.boundary)
        miss = np.max(np.abs(MODEL.simulate(classical.input, s0).output - y_ref))
        assert miss > 1e3 * np.max(np.abs(r.output - y_ref))


def test_unreachable_targets_are_counted():
    s0 = MODEL.negative_saturation()
    y = np.array([0.0, 100.0, 0.0])
    r = invert_rate(MODEL, y, s0)
    assert r.unreachable == 1 and not r.reached[1]
    assert r.input[1] == MODEL.u_max
    with pytest.raises(ValueError, match="not finite"):
        invert_rate(MODEL, [0.0, np.nan], s0)
