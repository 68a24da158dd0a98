"""The refit's prior on a grid finer than the model's: a smooth interpolant of its nodes."""

from __future__ import annotations

import numpy as np
from _lsq_data import gaussian_model
from preisach import PreisachModel
from preisach.diagnose.context import prior_everett


def test_finer_grid_prior_is_the_smooth_interpolant_of_the_models_nodes():
    truth = gaussian_model(401)
    coarse_lv = np.linspace(-10.0, 10.0, 22)
    coarse = PreisachModel.from_everett(truth.everett, coarse_lv)
    fine = np.linspace(-10.0, 10.0, 41)
    a, b = np.meshgrid(fine, fine, indexing="ij")
    low = a > b
    exact = truth.everett(a, b)[low]
    bilinear = coarse.everett(a, np.minimum(a, b))[low]
    prior = prior_everett(coarse, fine)[low]
    err_bilinear = np.sqrt(np.mean((bilinear - exact) ** 2))
    err_prior = np.sqrt(np.mean((prior - exact) ** 2))
    assert err_prior < 0.2 * err_bilinear  # measured: 2.6 mV against 43 mV on 16 V
    # on the model's own grid (and coarser ones) the prior is the model as it simulates
    ca, cb = np.meshgrid(coarse_lv, coarse_lv, indexing="ij")
    own = prior_everett(coarse, coarse_lv)
    np.testing.assert_array_equal(own, coarse.everett(ca, np.minimum(ca, cb)))
