"""Inverse of augmented models: delay by preview, linear dynamics, creep, input lag."""

from __future__ import annotations

import numpy as np
import pytest
from preisach import AugmentedModel, PreisachModel
from preisach.compensate.augmented import invert_augmented
from preisach.diagnose.effects import (
    FirstOrderInputLag,
    FractionalDelay,
    GainOffset,
    LagrangeDelay,
    OutputFeedback,
    PronyCreep,
    ReversibleRelaxation,
    SecondOrderMode,
)

DT = 1e-3
BASE = PreisachModel.builtin("ss15-1hz", levels=41)


def sine(f=1.0, seconds=2.0):
    t = np.arange(int(seconds / DT)) * DT
    mid, amp = 0.5 * (BASE.y_min + BASE.y_max), 0.35 * (BASE.y_max - BASE.y_min)
    return mid - amp * np.cos(2 * np.pi * f * t)


def from_steady(y0, f=2.0, seconds=2.0):
    """Leave the steady output y0 smoothly (raised cosine, 0.25 s), then a sine above it."""
    span = BASE.y_max - BASE.y_min
    lo, hi = y0 + 0.15 * span, y0 + 0.75 * span
    t = np.arange(int(seconds / DT)) * DT
    ramp = y0 + (lo - y0) * 0.5 * (1 - np.cos(np.pi * np.minimum(t / 0.25, 1.0)))
    ts = np.maximum(t - 0.25, 0.0)
    return np.where(t < 0.25, ramp, lo + (hi - lo) * 0.5 * (1 - np.cos(2 * np.pi * f * ts)))


@pytest.mark.parametrize("tau", [0.0, 3e-3, 2.3e-3, 2.7e-3])
def test_delay_by_preview_is_exact(tau):
    model = AugmentedModel(BASE, [FractionalDelay(DT, tau=tau)])
    y = sine()
    r = invert_augmented(model, y, BASE.negative_saturation(), sample_time=DT)
    n = int(np.ceil(tau / DT)) + 1
    np.testing.assert_allclose(r.output[n:-n], y[n:-n], atol=1e-7)
    if tau == 3e-3:  # a whole number of samples: the classical inverse of the advanced reference
        np.testing.assert_allclose(
            r.input[:-3], BASE.inverse(y[3:], BASE.negative_saturation()).input, atol=1e-9
        )


@pytest.mark.parametrize("tau", [0.4e-3, 0.5e-3, 2.0e-3, 2.7e-3])
def test_a_lagrange_delay_is_undone_by_reading_the_reference_ahead(tau):
    """The flat-magnitude delay of diagnosis (``delay/lagrange``): the drive reads the
    reference ``tau`` ahead with the same interpolation; a slow reference comes back."""
    model = AugmentedModel(BASE, [LagrangeDelay(DT, tau=tau)])
    y = sine()
    r = invert_augmented(model, y, BASE.negative_saturation(), sample_time=DT)
    n = int(np.ceil(tau / DT)) + 2
    swing = float(np.ptp(y))
    np.testing.assert_allclose(r.output[n:-n], y[n:-n], atol=1e-8 * swing)  # linear: 2e-6
    if tau == 2.0e-3:  # whole samples: the classical inverse of the advanced reference
        np.testing.assert_allclose(
            r.input[:-2], BASE.inverse(y[2:], BASE.negative_saturation()).input, atol=1e-9
        )


@pytest.mark.parametrize("hold", [0.0, 1.0])  # the mode's input held or linear between samples
def test_full_chain_beats_the_classical_inverse(hold):
    blocks = [
        FirstOrderInputLag(DT, tau=2e-3),
        SecondOrderMode(DT, f_n=120.0, zeta=0.05, participation=0.6, hold=hold),
        PronyCreep(DT, taus=[0.05, 0.5], weights=[0.03, 0.02], gain=1.0),
        GainOffset(DT, gain=1.05, offset=0.1),
        FractionalDelay(DT, tau=1.5e-3),
    ]
    model = AugmentedModel(BASE, blocks)
    s0 = BASE.negative_saturation()
    y = from_steady(model.simulate([BASE.u_min], s0).output[0])  # steady output at s0
    r = invert_augmented(model, y, s0, sample_time=DT)
    assert r.extra["clamped"] == 0
    # the first-order hold puts the mode's numerator roots at radius 0.97: pulled in to
    # r_max, the inverse stops compensating near the Nyquist frequency and says where
    assert ("bandwidth_hz" in r.extra) == (hold == 1.0)
    # the delay's first samples come from the steady start and its last have no preview
    np.testing.assert_allclose(r.output[3:-3], y[3:-3], atol=1e-6 if hold == 0.0 else 1e-3)
    classical = BASE.inverse(y, s0)
    err_classic = np.max(np.abs(model.simulate(classical.input, s0).output - y)[3:-3])
    assert err_classic > 100 * np.max(np.abs(r.output[3:-3] - y[3:-3]))


def test_mode_seen_fully_is_band_limited_and_stated():
    model = AugmentedModel(BASE, [SecondOrderMode(DT, f_n=150.0, zeta=0.02, participation=1.0)])
    s0 = BASE.negative_saturation()
    y = from_steady(BASE.y_min, f=1.0)
    r = invert_augmented(model, y, s0, sample_time=DT)
    bw = r.extra.get("bandwidth_hz")
    if bw is not None:  # the ZOH sampling zero was pulled inside r_max
        assert 0 < bw <= 500
    span = BASE.y_max - BASE.y_min
    assert np.max(np.abs(r.output - y)) < 1e-3 * span
    classical = BASE.inverse(y, s0)
    assert np.max(np.abs(model.simulate(classical.input, s0).output - y)) > np.max(
        np.abs(r.output - y)
    )


def test_mode_in_a_recoiling_frame_is_inverted_exactly():
    # y = x - r s^2/D x: a numerator with direct feedthrough 1 - r (python's own design)
    model = AugmentedModel(
        BASE, [SecondOrderMode(DT, f_n=120.0, zeta=0.08, participation=0.0, reaction=0.4)]
    )
    s0 = BASE.negative_saturation()
    y = from_steady(BASE.y_min, f=1.0)
    r = invert_augmented(model, y, s0, sample_time=DT)
    assert r.extra["clamped"] == 0 and "bandwidth_hz" not in r.extra
    np.testing.assert_allclose(r.output, y, atol=1e-6)


def test_not_invertible_blocks_are_refused():
    fb = AugmentedModel(BASE, [OutputFeedback(DT, a=0.1, b=0.0, c=0.0, y_c=0.0, span=10.0)])
    with pytest.raises(ValueError, match="not invertible"):
        invert_augmented(fb, sine(), sample_time=DT)
    relax = AugmentedModel(BASE, [ReversibleRelaxation(DT, k=0.01, tau=1e-3)])
    with pytest.raises(ValueError, match="rate_dependence.*not invertible"):
        invert_augmented(relax, sine(), sample_time=DT)
    with pytest.raises(ValueError, match="r_max"):
        invert_augmented(AugmentedModel(BASE, []), sine(), sample_time=DT, r_max=1.0)
    with pytest.raises(ValueError, match="not finite"):
        invert_augmented(AugmentedModel(BASE, []), [0.0, np.nan], sample_time=DT)
