"""The refit's prior on a grid finer than the model's: a smooth interpolant of its nodes."""

from __future__ import annotations

import numpy as np
from preisach import PreisachModel
from preisach.diagnose.context import prior_everett


def _smooth_device() -> PreisachModel:
    """A classical device with a Gaussian density (coercive 0.6 +/- 1.4 V, bias -1 +/- 2.2 V)."""
    lv = np.linspace(-10.0, 10.0, 401)
    a, b = np.meshgrid(lv, lv, indexing="ij")
    r, c = 0.5 * (a - b), 0.5 * (a + b)
    mu = np.exp(-0.5 * ((r - 0.6) / 1.4) ** 2 - 0.5 * ((c + 1.0) / 2.2) ** 2)
    mu = np.where(a > b, mu, 0.0)
    e = np.cumsum(np.cumsum(mu[:, ::-1], axis=1)[:, ::-1], axis=0)
    return PreisachModel.from_everett(
        lambda x, z: (16.0 / e[-1, 0]) * e[np.searchsorted(lv, x), np.searchsorted(lv, z)], lv
    )


def test_finer_grid_prior_is_the_smooth_interpolant_of_the_models_nodes():
    truth = _smooth_device()
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
