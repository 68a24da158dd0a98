"""Cubic interpolation of the Everett table: the model, identification, inverse, diagnosis."""

from __future__ import annotations

import numpy as np
import pytest
from _lsq_data import gaussian_model, grid_model
from preisach import PreisachModel, Recording, _core
from preisach.identify import identify_fod
from preisach.waveforms import fod_sweep


def _sweep(truth: PreisachModel, seed: int = 1, noise: float = 2e-3) -> Recording:
    u = fod_sweep(21, u_min=-10.0, u_max=10.0, frequency=2.0, shape="triangle").u
    y = truth.simulate(u, truth.negative_saturation()).output
    y = y + np.random.default_rng(seed).normal(0.0, noise, y.size)
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3)


def _test_input(n: int = 6000, seed: int = 4) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(10.0 * np.sin(np.cumsum(rng.normal(0.0, 0.02, n))), -10.0, 10.0)


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def test_identify_chooses_cubic_for_a_smooth_device_and_it_predicts_better():
    # a smooth steep density read on the 21-level FOD grid: the cubic interpolant between the
    # same nodes predicts an experiment it never saw several times better than the bilinear one
    truth = gaussian_model()
    rep = identify_fod(_sweep(truth), delay=0)
    choice = rep.model.metadata["interpolation"]
    assert rep.model.interpolation == "cubic" and choice["interpolation"] == "cubic"
    assert choice["rms_cubic"] < 0.9 * choice["rms_bilinear"]
    u = _test_input()
    s0 = truth.negative_saturation()
    y = truth.simulate(u, s0).output
    e_cubic = _rms(rep.model.simulate(u, s0).output, y)
    e_bilinear = _rms(rep.model.with_interpolation("bilinear").simulate(u, s0).output, y)
    assert e_cubic < 0.5 * e_bilinear
    # forced either way
    assert identify_fod(_sweep(truth), delay=0, interpolation="bilinear").model.interpolation == (
        "bilinear"
    )
    with pytest.raises(ValueError, match="interpolation"):
        identify_fod(_sweep(truth), delay=0, interpolation="spline")


def test_identify_keeps_bilinear_for_a_device_that_is_bilinear_between_the_nodes():
    lv = np.linspace(-10.0, 10.0, 21)
    truth = grid_model(lv, 3)  # random cell masses: bilinear between these very nodes
    rep = identify_fod(_sweep(truth, noise=1e-4), lv, delay=0)
    assert rep.model.interpolation == "bilinear"
    choice = rep.model.metadata["interpolation"]
    assert choice["rms_bilinear"] < choice["rms_cubic"]


def test_a_cubic_model_round_trips_and_older_files_stay_bilinear(tmp_path):
    m = gaussian_model(21).with_interpolation("cubic")
    assert "cubic" in repr(m)
    m.save(tmp_path / "c.npz")
    back = PreisachModel.load(tmp_path / "c.npz")
    assert back == m and back.interpolation == "cubic"
    with np.load(tmp_path / "c.npz") as data:
        assert int(data["version"]) == 3
    b = m.with_interpolation("bilinear")
    assert b != m and np.array_equal(b.everett_values, m.everett_values)
    b.save(tmp_path / "b.npz")
    with np.load(tmp_path / "b.npz") as data:
        assert int(data["version"]) == 1 and "interpolation" not in data.files
    assert PreisachModel.load(tmp_path / "b.npz").interpolation == "bilinear"
    import pickle

    assert pickle.loads(pickle.dumps(m.table)).interpolation == "cubic"
    with pytest.raises(ValueError, match="interpolation"):
        m.with_interpolation("quadratic")


def test_the_inverse_of_a_cubic_model_meets_its_targets():
    m = gaussian_model(21).with_interpolation("cubic")
    lo, hi = m.y_min, m.y_max
    t = np.linspace(0.0, 1.0, 3000)
    y_ref = 0.5 * (lo + hi) + 0.4 * (hi - lo) * np.sin(2 * np.pi * 3 * t) * t
    r = m.inverse(y_ref)
    assert r.unreachable == 0
    # outputs are the cubic model's own: simulate reproduces them
    assert np.array_equal(m.simulate(r.input, r.initial_state).output, r.output)
    assert np.max(np.abs(r.output - y_ref)) < 2e-3 * (hi - lo)
    with pytest.raises(ValueError, match="bilinear"):
        _core.Inverter(m.table, m.negative_saturation())


def test_regressor_rows_of_a_cubic_grid_reproduce_the_simulator():
    m = gaussian_model(21).with_interpolation("cubic")
    u = _test_input(3000, 7)
    s0 = m.anhysteretic_state()
    ptr, idx, val, _ = _core.regressor_rows(m.levels, u, s0, "clamp", "cubic")
    n = m.levels.size
    ii, jj = np.tril_indices(n, -1)
    theta = np.append(m.everett_values[ii, jj], m.y_min)
    import scipy.sparse as sp

    R = sp.csr_matrix((val, idx.astype(np.int64), ptr), shape=(u.size, theta.size))
    assert np.max(np.abs(R @ theta - m.simulate(u, s0).output)) < 1e-10


def test_the_diagnosis_refits_a_cubic_model_with_its_own_interpolation():
    from preisach.diagnose.context import Context, prior_everett
    from preisach.diagnose.data import prepare_recordings

    m = gaussian_model(21).with_interpolation("cubic")
    u = _test_input(2000, 9)
    y = m.simulate(u, m.negative_saturation()).output
    rec = Recording.from_arrays(u=u, y=y, sample_time=1e-3)
    recs = prepare_recordings(m, [rec])
    ctx = Context(m, recs, refit=True)
    assert ctx.interpolation == "cubic"
    from preisach.diagnose.context import Base

    base = Base(ctx.theta0.copy())
    assert ctx.table(base).interpolation == "cubic"
    R = ctx.regressor(0)
    assert np.max(np.abs(R @ ctx.theta0 - ctx.preisach(0, ctx.given))) < 1e-9
    # a finer grid's prior is the cubic model's own interpolant
    fine = np.linspace(m.u_min, m.u_max, 41)
    e = prior_everett(m, fine)
    a, b = np.meshgrid(fine, fine, indexing="ij")
    assert np.allclose(e, np.where(a > b, m.everett(a, np.minimum(a, b)), 0.0))


def test_the_identification_report_says_which_interpolation_and_why():
    rep = identify_fod(_sweep(gaussian_model()), delay=0)
    text = rep.summary()
    assert "interpolation between the nodes: cubic (RMS residual on the recordings" in text
    d = rep.to_dict()["interpolation"]
    assert d["interpolation"] == "cubic" and d["rms_cubic"] < d["rms_bilinear"]
