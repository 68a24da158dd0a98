"""Tests of the square-root FOD surface identification (thesis 3.3.2, Eq 3.1-3.2)."""

from __future__ import annotations

import numpy as np
import pytest
from preisach.identify.surface_fit import SurfaceFitResult, fit_sqrt_surface, format_table
from preisach.surface import TABLE_3_1, SqrtSurface

LEVELS = np.arange(-100.0, 100.0 + 1e-9, 10.0)  # the thesis' 21 levels (V)
PARAMS = ("xbar4", "xbar5", "x7", "x8", "x9")
NOISE_STD = 2e-3  # V
LSB = 10.0 / 2**14  # 14-bit ADC over +-5 V


def fod_grid(surf: SqrtSurface, levels: np.ndarray = LEVELS) -> np.ndarray:
    """Noise-free FOD grid ``y[i, j] = surf(levels[i], levels[j])`` for ``j <= i``, NaN above."""
    a, b = np.meshgrid(levels, levels, indexing="ij")
    return np.where(a >= b, surf(a, np.minimum(a, b)), np.nan)


def noisy_grid(surf: SqrtSurface, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = fod_grid(surf)
    y = y + rng.normal(0.0, NOISE_STD, y.shape)
    y = np.clip(np.round(y / LSB) * LSB, -5.0, 5.0 - LSB)  # NaN stays NaN
    return y


def fine_triangle(lo: float = -100.0, hi: float = 100.0, n: int = 201):
    g = np.linspace(lo, hi, n)
    a, b = np.meshgrid(g, g, indexing="ij")
    m = a >= b
    return a[m], b[m]


def surface_deviation(s1: SqrtSurface, s2: SqrtSurface, lo=-100.0, hi=100.0) -> np.ndarray:
    a, b = fine_triangle(lo, hi)
    return s1(a, b) - s2(a, b)


def rel_err(fit: SqrtSurface, truth: SqrtSurface, name: str) -> float:
    return abs(getattr(fit, name) / getattr(truth, name) - 1.0)


@pytest.fixture(scope="module")
def clean_fits() -> dict[int, SurfaceFitResult]:
    return {f: fit_sqrt_surface(LEVELS, fod_grid(s), frequency=f) for f, s in TABLE_3_1.items()}


# -- (1) noise-free recovery of Table 3.1 ------------------------------------------------
@pytest.mark.parametrize("freq", sorted(TABLE_3_1))
def test_recovers_table_3_1_surface(clean_fits, freq):
    truth = TABLE_3_1[freq]
    res = clean_fits[freq]
    assert res.warnings == []
    assert res.refined
    # the key criterion: the surface itself (parameters can trade off)
    assert np.max(np.abs(surface_deviation(res.surface, truth))) < 1e-7
    # noise-free, the problem is well conditioned enough for every parameter
    for name in PARAMS:
        tol = 1e-5 if name == "xbar4" else 1e-6
        assert rel_err(res.surface, truth, name) < tol, name
    assert res.surface.y_max == truth.y_max
    assert res.surface.y_min == pytest.approx(truth.y_min, abs=1e-12)
    assert (res.surface.u_min, res.surface.u_max) == (-100.0, 100.0)
    assert res.surface.frequency == freq
    assert res.n_points == 231
    assert res.root_sum_sq_error < 1e-8
    assert res.surface.fit_error == res.root_sum_sq_error
    assert res.max_error < 1e-8


@pytest.mark.parametrize("freq", sorted(TABLE_3_1))
def test_per_curve_and_polynomial_stages(clean_fits, freq):
    truth = TABLE_3_1[freq]
    res = clean_fits[freq]
    cp = res.curve_params
    # curves with more than 3 points: alpha = -70 ... 100 V
    assert cp.shape == (18, 4)
    np.testing.assert_allclose(cp[:, 0], LEVELS[3:])
    np.testing.assert_array_equal(res.curve_n_points, np.arange(4, 22))
    alpha = cp[:, 0]
    np.testing.assert_allclose(cp[:, 2], truth._scale() * truth._f2(alpha), rtol=1e-6)
    np.testing.assert_allclose(cp[:, 3], truth._f3(alpha), rtol=1e-6)
    assert np.all(res.curve_rms < 1e-8)
    poly = res.poly
    assert poly.shape == (9,)
    np.testing.assert_allclose(poly[6:], [truth.x7, truth.x8, truth.x9], rtol=1e-5)
    np.testing.assert_allclose(poly[3] / poly[5], truth.xbar4, rtol=1e-4)
    np.testing.assert_allclose(poly[4] / poly[5], truth.xbar5, rtol=1e-5)


@pytest.mark.parametrize("freq", sorted(TABLE_3_1))
def test_thesis_procedure_without_refinement(freq):
    truth = TABLE_3_1[freq]
    res = fit_sqrt_surface(LEVELS, fod_grid(truth), frequency=freq, refine=False)
    assert not res.refined
    assert res.unrefined_surface is not None
    for name in PARAMS:
        assert getattr(res.surface, name) == getattr(res.unrefined_surface, name)
    assert res.root_sum_sq_error == pytest.approx(res.unrefined_root_sum_sq_error)
    assert np.max(np.abs(surface_deviation(res.surface, truth))) < 1e-6
    for name in PARAMS:
        assert rel_err(res.surface, truth, name) < 1e-4, name


def test_non_uniform_asymmetric_levels():
    truth = SqrtSurface(5e-06, 4e-03, -2e-03, -3e-01, -1.6e02, 2.9, -1.1, u_max=120.0, u_min=-40.0)
    levels = np.array([-40, -30, -25, -10, 0, 5, 20, 30, 45, 60, 70, 85, 100, 110, 120.0])
    res = fit_sqrt_surface(levels, fod_grid(truth, levels))
    assert (res.surface.u_min, res.surface.u_max) == (-40.0, 120.0)
    assert np.max(np.abs(surface_deviation(res.surface, truth, -40.0, 120.0))) < 1e-6


def test_missing_points_are_skipped():
    truth = TABLE_3_1[2]
    y = fod_grid(truth)
    y[15, 7] = np.nan
    y[9, 2] = np.nan
    res = fit_sqrt_surface(LEVELS, y)
    assert res.n_points == 229
    assert np.max(np.abs(surface_deviation(res.surface, truth))) < 1e-6


# -- (2) noisy, quantised data ------------------------------------------------------------
@pytest.mark.parametrize("freq", sorted(TABLE_3_1))
def test_noisy_quantised_data(freq):
    truth = TABLE_3_1[freq]
    y = noisy_grid(truth, seed=freq)
    res = fit_sqrt_surface(LEVELS, y, frequency=freq)
    dev = surface_deviation(res.surface, truth)
    y_max_err = abs(y[-1, -1] - truth.y_max)  # the surface is pinned to this measured point
    assert np.max(np.abs(dev)) < 6e-3
    assert np.max(np.abs(dev)) <= y_max_err + 2e-3
    assert np.sqrt(np.mean(dev**2)) < 1.2e-3
    # the residuals are the noise: rmse ~ 2 mV, and the error measures are consistent
    assert 1.5e-3 < res.rmse < 2.5e-3
    assert res.root_sum_sq_error == pytest.approx(res.rmse * np.sqrt(res.n_points))
    assert res.mean_error_per_point == pytest.approx(res.root_sum_sq_error / 231)
    assert res.max_error >= res.rmse
    # the joint refinement can only improve on the thesis' polynomial stage
    assert res.root_sum_sq_error <= res.unrefined_root_sum_sq_error
    assert rel_err(res.surface, truth, "x9") < 0.02
    assert rel_err(res.surface, truth, "xbar5") < 0.05


# -- (3) constraints of Eq 3.2 --------------------------------------------------------------
@pytest.mark.parametrize("refine", [True, False])
def test_constraints_exact(refine):
    y = noisy_grid(TABLE_3_1[1], seed=11)
    res = fit_sqrt_surface(LEVELS, y, refine=refine)
    s = res.surface
    assert s(100.0, 100.0) == pytest.approx(y[-1, -1], abs=1e-12)
    col = y[:, 0]
    y_min = np.mean(col[np.isfinite(col)])
    assert s.y_min == pytest.approx(y_min, abs=1e-15)
    alphas = np.linspace(-100.0, 100.0, 81)
    np.testing.assert_allclose(s(alphas, -100.0), y_min, rtol=0, atol=1e-12)


def test_constraint_corner_y_min():
    y = noisy_grid(TABLE_3_1[4], seed=5)
    res = fit_sqrt_surface(LEVELS, y, y_min_source="corner")
    assert res.surface.y_min == y[-1, 0]
    np.testing.assert_allclose(res.surface(LEVELS, -100.0), y[-1, 0], rtol=0, atol=1e-12)
    assert res.surface(100.0, 100.0) == pytest.approx(y[-1, -1], abs=1e-12)


# -- (4) input validation --------------------------------------------------------------------
def test_bad_levels():
    y = fod_grid(TABLE_3_1[1])
    with pytest.raises(ValueError, match="levels"):
        fit_sqrt_surface(LEVELS[::-1], y)
    bad = LEVELS.copy()
    bad[5] = bad[4]
    with pytest.raises(ValueError, match="levels"):
        fit_sqrt_surface(bad, y)
    with pytest.raises(ValueError, match="levels"):
        fit_sqrt_surface(LEVELS[None, :], y)
    nan_levels = LEVELS.copy()
    nan_levels[3] = np.nan
    with pytest.raises(ValueError, match="levels"):
        fit_sqrt_surface(nan_levels, y)


def test_bad_y_grid():
    y = fod_grid(TABLE_3_1[1])
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS, y[:, :-1])
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS[:-1], y)
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS, y[0])
    missing_max = y.copy()
    missing_max[-1, -1] = np.nan
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS, missing_max)
    inverted = -y
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS, inverted)
    with_inf = y.copy()
    with_inf[10, 3] = np.inf
    with pytest.raises(ValueError, match="y_grid"):
        fit_sqrt_surface(LEVELS, with_inf)


def test_too_few_curves():
    # 5 levels give only the curves with 4 and 5 points: two curves for a quadratic
    lv = LEVELS[:5]
    with pytest.raises(ValueError, match="y_grid.*at least 3 FOD curves"):
        fit_sqrt_surface(lv, fod_grid(TABLE_3_1[1], lv))
    # enough levels, but only two complete curves; the others keep 2 points each
    full = fod_grid(TABLE_3_1[1])
    y = np.full_like(full, np.nan)
    y[:, 0] = full[:, 0]
    np.fill_diagonal(y, np.diag(full))
    y[-2:] = full[-2:]
    with pytest.raises(ValueError, match="y_grid.*got 2"):
        fit_sqrt_surface(LEVELS, y)


def test_bad_options():
    y = fod_grid(TABLE_3_1[1])
    with pytest.raises(ValueError, match="y_min_source"):
        fit_sqrt_surface(LEVELS, y, y_min_source="median")
    with pytest.raises(ValueError, match="frequency"):
        fit_sqrt_surface(LEVELS, y, frequency=-1.0)


def test_upper_triangle_values_are_ignored_with_warning():
    truth = TABLE_3_1[1]
    y = fod_grid(truth)
    y[3, 10] = 123.0
    res = fit_sqrt_surface(LEVELS, y)
    assert any("above the diagonal" in w for w in res.warnings)
    assert res.n_points == 231
    assert np.max(np.abs(surface_deviation(res.surface, truth))) < 1e-6


# -- table output -----------------------------------------------------------------------------
def test_table(clean_fits):
    text = clean_fits[1].table()
    lines = text.splitlines()
    assert [ln.split()[0] for ln in lines] == [
        "f",
        "xbar4",
        "xbar5",
        "x7",
        "x8",
        "x9",
        "umax",
        "umin",
        "ymax",
        "ymin",
        "error",
    ]
    assert "8.81e-06" in text and "-1.94e+02" in text and "-3.63" in text
    # format_table reproduces Table 3.1 from the stored surfaces
    t31 = format_table(TABLE_3_1.values()).splitlines()
    assert t31[1].split() == ["xbar4", "8.81e-06", "2.24e-06", "-5.28e-06"]
    assert t31[5].split() == ["x9", "-1.94e+02", "-1.55e+02", "-1.24e+02"]
    assert t31[-1].split() == ["error", "0.38", "0.57", "1.10"]
    both = format_table([clean_fits[2], TABLE_3_1[2]]).splitlines()
    assert both[3].split() == ["x7", "-1.73e-03", "-1.73e-03"]
    with pytest.raises(TypeError, match="fits"):
        format_table([1.0])  # type: ignore[list-item]


def test_straight_fod_curves_hit_the_linear_limit():
    # outside the Eq 3.2 family: every FOD curve is a straight line in beta
    a, b = np.meshgrid(LEVELS, LEVELS, indexing="ij")
    y = np.where(a >= b, -3.6 + (0.02 + 1e-4 * a) * (np.minimum(a, b) + 100.0), np.nan)
    res = fit_sqrt_surface(LEVELS, y)
    assert sum("straight" in w for w in res.warnings) == 18
    assert res.rmse < 2e-3
    assert res.surface(100.0, 100.0) == pytest.approx(y[-1, -1], abs=1e-12)
