"""Verification (preisach.verify): error tables, the wiping-out and congruent-minor-loop metrics."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure
from preisach import PreisachModel, Recording
from preisach.verify import congruency_metric, predict, verify, wiping_out_metric
from preisach.waveforms import cml_input, fod_sweep, wiping_out_input


@pytest.fixture(scope="module")
def model() -> PreisachModel:
    return PreisachModel.builtin("ss15-2hz", levels=101)


def rec_of(model: PreisachModel, u: np.ndarray, name: str, y_extra=None, state=None) -> Recording:
    y = model.simulate(u, model.negative_saturation() if state is None else state).output
    if y_extra is not None:
        y = y + y_extra
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3, experiment=name)


def test_verify_reports_max_and_rms_in_volts_and_percent(model):
    sig = wiping_out_input(2.0)
    err = 0.01 * np.sin(np.arange(sig.u.size) * 0.01)
    rec = rec_of(model, sig.u, "wiping-out 2 Hz", y_extra=-err)
    table = verify(model, rec)
    (row,) = table.rows
    assert (
        row.experiment == "wiping-out 2 Hz" and row.n_samples == sig.u.size and row.n_skipped == 0
    )
    assert row.max_error == pytest.approx(np.max(np.abs(err)))
    assert row.rms_error == pytest.approx(np.sqrt(np.mean(err**2)))
    assert row.output_range == pytest.approx(np.ptp(rec.y))
    assert row.max_pct == pytest.approx(100 * row.max_error / row.output_range)
    assert table.max_pct == row.max_pct
    assert "wiping-out 2 Hz" in table.table() and "max %" in table.table()
    assert verify(model, rec, output_range=10.0).rows[0].max_pct == pytest.approx(
        10 * row.max_error
    )
    d = table.to_dict()
    assert d["rows"][0]["rms_pct"] == pytest.approx(row.rms_pct)


def test_verify_several_experiments_names_and_plot(model):
    recs = [rec_of(model, s.u, s.name) for s in (wiping_out_input(), cml_input(), fod_sweep(11))]
    table = verify(model, recs, names=["a", "b", "c"])
    assert [r.experiment for r in table.rows] == ["a", "b", "c"]
    assert all(r.max_error < 1e-12 for r in table.rows)
    fig = table.plot()
    assert isinstance(fig, Figure) and fig.axes[0].get_xlabel() == "time t (s)"
    assert fig.axes[0].get_ylabel() == "output y (V)"
    with pytest.raises(ValueError, match="names"):
        verify(model, recs, names=["a"])
    with pytest.raises(ValueError, match="at least one"):
        verify(model, [])


def test_verify_counts_and_warns_about_inputs_outside_the_model_range(model):
    from preisach.errors import PreisachWarning

    u = np.r_[np.linspace(-100.0, 100.0, 200), np.linspace(100.0, 120.0, 30)[1:], -105.0, 0.0]
    rec = rec_of(model, u, "overdriven")  # the model clamps the 29 + 1 samples beyond +-100 V
    inside = rec_of(model, np.linspace(-100.0, 100.0, 50), "inside")
    with pytest.warns(PreisachWarning, match=r"overdriven: 30 of 231 input samples .*outside"):
        table = verify(model, [rec, inside])
    assert [r.n_out_of_range for r in table.rows] == [30, 0]
    assert table.rows[0].max_error < 1e-12  # clamped consistently with the recording
    assert table.to_dict()["rows"][0]["n_out_of_range"] == 30
    lines = table.table().splitlines()
    assert "clamped" in lines[1]
    assert lines[3].split()[:3] == ["overdriven", "231", "30"]
    assert lines[4].split()[:3] == ["inside", "50", "0"]
    # with a delay only the simulated inputs count
    with pytest.warns(PreisachWarning, match="29 of 229"):
        assert verify(model, rec, delay=2).rows[0].n_out_of_range == 29
    # the counts without the warning
    assert verify(model, rec, warn_out_of_range=False).rows[0].n_out_of_range == 30


def test_initial_state_policies_and_delay(model):
    t = np.arange(6000) * 1e-3
    u = 70.0 * np.sin(2 * np.pi * t) * np.exp(-0.1 * t) + 10.0  # never saturates
    start = model.anhysteretic_state()
    rec = rec_of(model, u, "inner", state=start)
    burn = verify(model, rec).rows[0]
    assert not burn.exact_state and burn.n_skipped > 0
    assert "state not exact" in verify(model, rec).table()
    exact = verify(model, rec, initial_state="anhysteretic").rows[0]
    assert exact.n_skipped == 0 and exact.max_error < 1e-12
    wrong = verify(model, rec, initial_state="positive").rows[0]
    assert wrong.max_error > 0.1
    late = Recording.from_arrays(u=rec.u, y=np.append(rec.y[:2], rec.y[:-2]), sample_time=1e-3)
    assert verify(model, late, initial_state=start, delay=2).rows[0].max_error < 1e-12
    p = predict(model, late, initial_state=start, delay=2)
    assert p.u.size == p.y.size == u.size - 2 and p.first == 0
    with pytest.raises(ValueError, match="delay"):
        verify(model, rec, delay=-1)
    with pytest.raises(ValueError, match="initial_state"):
        verify(model, rec, initial_state="warm")
    with pytest.raises(ValueError, match="output_range"):
        verify(model, rec, output_range=0.0)
    with pytest.raises(TypeError, match="recording"):
        predict(model, object())


# -- wiping-out ------------------------------------------------------------------------------
def test_wiping_out_metric_on_the_thesis_input_compares_the_4th_branch_with_the_others(model):
    rec = rec_of(model, wiping_out_input(1.0).u, "wo")
    res = wiping_out_metric(rec, branches="ascending")
    levels = sorted(c.level for c in res.comparisons)
    assert levels == [44.0, 72.0, 100.0]  # the reversal levels of Figs 3.10-3.12
    assert res.max_difference < 1e-4 and res.passed
    both = wiping_out_metric(rec)
    assert any(c.kind == "descending" and c.level == -40.0 for c in both.comparisons)
    assert "PASS" in both.table() and both.to_dict()["passed"]


def test_wiping_out_metric_fails_a_drifting_system(model):
    u = wiping_out_input(1.0).u
    drift = 1.0 * np.arange(u.size) / u.size  # 1 V of output drift over the 6 s test
    res = wiping_out_metric(rec_of(model, u, "drift", y_extra=drift), branches="ascending")
    assert not res.passed
    c100 = next(c for c in res.comparisons if c.level == 100.0)
    # the 4th branch reaches 100 V 3 s after the 1st: 3/6 of the drift
    assert c100.difference == pytest.approx(1.0 * 3.0 / 6.0, rel=0.01)
    assert res.max_pct > 5.0
    assert wiping_out_metric(rec_of(model, u, "drift", y_extra=drift), tolerance=20.0).passed


def test_wiping_out_metric_tolerates_noise_on_the_input(model):
    rng = np.random.default_rng(0)
    u = wiping_out_input(1.0).u
    rec = rec_of(model, u, "wo")
    noisy = Recording.from_arrays(u=u + rng.normal(0, 0.05, u.size), y=rec.y, sample_time=1e-3)
    res = wiping_out_metric(noisy, branches="ascending")
    assert sorted(round(c.level) for c in res.comparisons) == [44, 72, 100]
    assert res.max_pct < 1.0


def test_wiping_out_metric_arguments(model):
    rec = rec_of(model, wiping_out_input().u, "wo")
    with pytest.raises(ValueError, match="branches"):
        wiping_out_metric(rec, branches="up")
    with pytest.raises(ValueError, match="tolerance"):
        wiping_out_metric(rec, tolerance=0)
    with pytest.raises(ValueError, match="reversal_tol"):
        wiping_out_metric(rec, reversal_tol=-1.0)
    flat = Recording.from_arrays(u=np.zeros(5), y=np.arange(5.0), sample_time=1e-3)
    with pytest.raises(ValueError, match="constant"):
        wiping_out_metric(flat)
    one_rise = Recording.from_arrays(
        u=np.linspace(0, 1, 50), y=np.linspace(0, 2, 50), sample_time=1e-3
    )
    res = wiping_out_metric(one_rise)
    assert res.comparisons == [] and not res.passed  # nothing to test is not a pass


# -- congruent minor loops -------------------------------------------------------------------
def test_congruency_metric_on_the_thesis_cml_input(model):
    rec = rec_of(model, cml_input(2.0).u, "cml")
    res = congruency_metric(rec)
    (pair,) = res.pairs
    assert (pair.low, pair.high) == (0.0, 50.0)
    assert pair.shape_difference < 1e-4 and res.passed
    # the peak before loop B shifts it upwards (section 3.2.2)
    expected = model.readout(model.state_from_extrema([50, 0, 100, 0])) - model.readout(
        model.state_from_extrema([50, 0])
    )
    assert pair.shift == pytest.approx(expected, rel=1e-3)
    assert "PASS" in res.table() and res.to_dict()["n_loops"] == res.n_loops


def test_congruency_metric_fails_a_system_with_a_drifting_gain(model):
    u = cml_input(1.0).u
    y = model.simulate(u, model.negative_saturation()).output
    t = np.arange(u.size) / u.size
    rec = Recording.from_arrays(u=u, y=y * (1.0 + 0.5 * t), sample_time=1e-3)  # gain +50 %
    res = congruency_metric(rec, tolerance=1.0)
    assert not res.passed and res.max_pct > 1.0
    with pytest.raises(ValueError, match="points"):
        congruency_metric(rec, points=2)
    with pytest.raises(ValueError, match="match_tol"):
        congruency_metric(rec, match_tol=-1.0)
