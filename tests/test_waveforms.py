"""Test inputs of chapter 3 (preisach.waveforms): FOD sweep, wiping-out, CML, initialisation."""

from __future__ import annotations

import numpy as np
import pytest
from preisach import PreisachModel, Recording
from preisach.identify import find_fod_curves
from preisach.waveforms import (
    InputSignal,
    cml_input,
    concatenate,
    decaying_sine,
    fod_sweep,
    legs,
    wiping_out_input,
)


def _legs_monotone(sig: InputSignal) -> bool:
    for a, b in zip(sig.turns[:-1], sig.turns[1:]):
        d = np.diff(sig.u[a : b + 1])
        if not (np.all(d >= 0) or np.all(d <= 0)):
            return False
    return True


def test_fod_sweep_is_the_thesis_identification_input():
    sig = fod_sweep()  # 21 levels, 1 Hz, 1 kHz
    t, u = sig
    assert len(sig) == 20 * 1000 + 1 and sig.duration == pytest.approx(20.0)
    assert t[1] - t[0] == pytest.approx(1e-3)
    assert u[0] == -100.0 and u[-1] == -100.0
    alphas = u[sig.marks["alpha"]]
    np.testing.assert_array_equal(alphas, np.arange(100.0, -100.0, -10.0))  # alpha_1 = 100 V first
    assert np.all(u[sig.turns[::2]] == -100.0)
    assert _legs_monotone(sig)
    # every leg lasts half a period
    assert np.all(np.diff(sig.turns) == 500)


def test_fod_sweep_is_found_by_the_fod_finder_on_the_whole_grid():
    m = PreisachModel.builtin("ss15-1hz", levels=41)
    sig = fod_sweep(frequency=4.0, sample_time=1e-3)
    y = m.simulate(sig.u, m.negative_saturation()).output
    fd = find_fod_curves(Recording.from_arrays(u=sig.u, y=y, sample_time=1e-3))
    np.testing.assert_allclose(fd.levels, np.linspace(-100, 100, 21))
    assert len(fd.used_curves) == 20
    assert int(np.count_nonzero(fd.count)) == 21 * 22 // 2


def test_fod_sweep_options():
    sig = fod_sweep([0.0, 1.0, 2.5], frequency=2.0, order="ascending", shape="triangle", start=1.0)
    assert sig.u[0] == 1.0 and sig.u[sig.turns[1]] == 0.0
    np.testing.assert_array_equal(sig.u[sig.marks["alpha"]], [1.0, 2.5])
    seg = sig.u[sig.turns[1] : sig.turns[2] + 1]
    np.testing.assert_allclose(np.diff(seg, 2), 0.0, atol=1e-12)  # triangle: straight ramps
    assert sig.params["order"] == "ascending" and sig.params["frequency"] == 2.0
    for bad, msg in [
        ({"levels": 1}, "at least 2"),
        ({"levels": [0, 2, 1]}, "increasing"),
        ({"order": "up"}, "order"),
        ({"shape": "sine"}, "shape"),
        ({"frequency": 0.0}, "frequency"),
        ({"u_min": 1.0, "u_max": 0.0}, "exceed"),
    ]:
        with pytest.raises(ValueError, match=msg):
            fod_sweep(**bad)


def test_wiping_out_input_sequence_and_segments():
    sig = wiping_out_input(2.0)
    np.testing.assert_array_equal(
        sig.u[sig.turns], [-100, 100, -40, 72, -40, 44, -40, 100, -40, 72, -40, 44, -40]
    )
    a, b = sig.marks["segment_a"], sig.marks["segment_b"]
    np.testing.assert_array_equal(sig.u[a[1] - 0 : a[1] + 1][-1:], [-40])
    np.testing.assert_array_equal(sig.u[b[0] : b[1] + 1], sig.u[a[0] : a[1] + 1])  # B repeats A
    assert np.all(np.diff(sig.turns) == 250)  # T/2 at 2 Hz and 1 kHz
    assert _legs_monotone(sig)
    with pytest.raises(ValueError, match="decreasing"):
        wiping_out_input(peaks=(50, 60))
    with pytest.raises(ValueError, match="trough"):
        wiping_out_input(trough=50.0)
    with pytest.raises(ValueError, match="two peaks"):
        wiping_out_input(peaks=(100,))


def test_cml_input_has_two_loops_between_the_same_extrema():
    sig = cml_input(4.0, loop=(-20.0, 30.0), peak=90.0)
    np.testing.assert_array_equal(sig.u[sig.turns], [-100, 30, -20, 90, -20, 30, -20])
    np.testing.assert_array_equal(sig.u[sig.marks["loop_a"]], [30, -20])
    np.testing.assert_array_equal(sig.u[sig.marks["loop_b"]], [-20, 30, -20])
    with pytest.raises(ValueError, match="u_min < low < high < peak"):
        cml_input(loop=(40.0, 30.0))
    with pytest.raises(ValueError, match="u_min < low < high < peak"):
        cml_input(peak=20.0)


def test_decaying_sine_and_concatenate_rebuild_the_thesis_sequence():
    init = decaying_sine(12.0, 1.0, 100.0)
    assert init.u[0] == 0.0 and init.u[-1] == 0.0
    assert np.max(np.abs(init.u)) == pytest.approx(100.0 * (1 - 0.25 / 12), rel=1e-3)
    assert np.max(np.abs(init.u[init.t > 11.0])) < 100.0 / 12 + 1e-9
    full = concatenate(init, wiping_out_input(start=0.0))
    assert full.u.size == init.u.size + wiping_out_input(start=0.0).u.size - 1  # shared sample
    assert full.t[full.marks["segment_a"][0]] == pytest.approx(12.0 + 1.0)  # the rise to 100 V ends
    # the test proper starts at t = 12 s: the input reaches u_min half a period later
    assert full.u[int(round(12.5 / 1e-3))] == -100.0
    np.testing.assert_allclose(np.diff(full.t), 1e-3)
    with pytest.raises(ValueError, match="sample times differ"):
        concatenate(init, fod_sweep(sample_time=2e-3))
    with pytest.raises(ValueError, match="at least one"):
        concatenate()


def test_legs_hits_every_turning_value_on_a_sample():
    sig = legs([0.0, 3.0, -1.0, 2.0], [0.0104, 0.02, 0.0297], sample_time=1e-3)
    np.testing.assert_array_equal(sig.u[sig.turns], [0.0, 3.0, -1.0, 2.0])
    np.testing.assert_array_equal(sig.turns, [0, 10, 30, 60])  # rounded leg ends
    assert sig.to_dict()["samples"] == 61
    with pytest.raises(ValueError, match="durations"):
        legs([0.0, 1.0], [-1.0])
    with pytest.raises(ValueError, match="points"):
        legs([0.0], 1.0)
    with pytest.raises(ValueError, match="finite"):
        legs([0.0, np.nan], 1.0)
