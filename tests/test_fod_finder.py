"""Tests of preisach.identify.fod_finder: FOD / FORC curves found in recordings by themselves."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from preisach.identify.fod_finder import find_fod_curves, find_forc_curves
from preisach.reference import RelayGrid
from preisach.surface import TABLE_3_1

LEVELS = -100.0 + 10.0 * np.arange(21)  # the thesis grid {-100 + 10 i} (V)
II, JJ = np.tril_indices(LEVELS.size)  # the 231 nodes j <= i
SURF = TABLE_3_1[1]


# ------------------------------------------------------------------------------------------
# synthetic recordings
# ------------------------------------------------------------------------------------------
def expected_fod_grid(surf=SURF, levels=LEVELS):
    n = levels.size
    exp = np.full((n, n), np.nan)
    i, j = np.tril_indices(n)
    exp[i, j] = surf(levels[i], levels[j])
    return exp


def fod_leg(surf, alpha, rise, fall):
    """Input and exact output of one FOD: rise samples (ending at alpha), fall samples."""
    u = np.concatenate((rise, fall))
    y = np.concatenate((surf(rise, rise), surf(alpha, fall)))
    return u, y


def thesis_sweep(surf=SURF, alphas=LEVELS, f=1.0, fs=1000.0):
    """Fig 3.17 input: for each alpha the input rises from -100 V to alpha and falls back
    to -100 V within one period 1/f; uniform sampling at fs (Hz)."""
    m = int(round(fs / f))
    h = m // 2
    k = np.arange(m)
    us, ys = [], []
    for a in alphas:
        rise = -100.0 + (a + 100.0) * k[: h + 1] / h  # ends exactly at alpha
        fall = a - (a + 100.0) * (k[h + 1 :] - h) / (m - h)
        u, y = fod_leg(surf, a, rise, fall)
        us.append(u)
        ys.append(y)
    u = np.concatenate(us + [[-100.0]])
    y = np.concatenate(ys + [surf(-100.0, -100.0)[None]])
    return np.arange(u.size) / fs, u, y


def exact_sweep(surf=SURF, alphas=LEVELS, step=0.5, hold=5):
    """Sweep with a constant input step, so that every sample of a ramp sits on a multiple of
    step and every grid level is hit exactly by a sample."""
    us = [np.full(hold, -100.0)]
    ys = [surf(us[0], us[0])]
    for a in alphas[alphas > -100.0]:
        n = int(round((a + 100.0) / step))
        rise = -100.0 + step * np.arange(1, n + 1)
        fall = a - step * np.arange(1, n + 1)
        u, y = fod_leg(surf, a, rise, fall)
        us.append(u)
        ys.append(y)
    u, y = np.concatenate(us), np.concatenate(ys)
    return np.arange(u.size) * 1e-3, u, y


def add_noise(u, y, rng, y_noise=2e-3, bits=14, full_scale=5.0, dither=0.05):
    """2 mV Gaussian noise and 14-bit quantisation (+-5 V) on y, +-0.05 V dither on u."""
    lsb = 2.0 * full_scale / 2**bits
    yn = np.round((y + rng.normal(0.0, y_noise, y.size)) / lsb) * lsb
    un = u + rng.uniform(-dither, dither, u.size)
    return un, yn


# ------------------------------------------------------------------------------------------
# FOD: exact recovery
# ------------------------------------------------------------------------------------------
def test_exact_recovery_when_samples_hit_levels():
    t, u, y = exact_sweep()
    d = find_fod_curves(t, u, y)
    assert d.direction == "descending"
    np.testing.assert_array_equal(d.levels, LEVELS)  # inferred thesis grid, exactly
    assert "regular grid" in d.levels_source
    assert np.all(np.isfinite(d.y_grid[II, JJ]))  # all 231 nodes
    assert np.all(np.isnan(d.y_grid[np.triu_indices(21, 1)]))  # upper triangle empty
    np.testing.assert_allclose(d.y_grid[II, JJ], expected_fod_grid()[II, JJ], rtol=0, atol=1e-12)
    # every FOD node is one curve; node (0, 0) averages the 20 saturation visits
    fod_nodes = II > 0
    assert np.all(d.count[II[fod_nodes], JJ[fod_nodes]] == 1)
    assert d.count[0, 0] == 20
    assert d.count[np.triu_indices(21, 1)].sum() == 0
    assert np.all(np.isnan(d.spread[II[fod_nodes], JJ[fod_nodes]]))
    assert len(d.curves) == 20 and all(c.used and c.first_order for c in d.curves)
    assert [c.level for c in d.curves] == list(range(1, 21))
    np.testing.assert_array_equal([c.alpha for c in d.curves], LEVELS[1:])
    # the diagonal is the output at the turning point
    np.testing.assert_allclose(np.diag(d.y_grid)[1:], SURF(LEVELS[1:], LEVELS[1:]), atol=1e-12)


def test_thesis_sweep_1khz_within_linear_interpolation_error():
    t, u, y = thesis_sweep(f=1.0, fs=1000.0)
    assert u.size == 21001
    d = find_fod_curves(t, u, y)
    np.testing.assert_array_equal(d.levels, LEVELS)
    # bound of linear interpolation between samples: h^2/8 max|d2y/dbeta2|
    h = np.max(np.abs(np.diff(u)))  # 0.4 V per sample for alpha = 100 V
    db = 0.05
    curv = 0.0
    for a in LEVELS[1:]:
        b = np.arange(-100.0 + db, a - db / 2, db)
        y2 = (SURF(a, b + db) - 2 * SURF(a, b) + SURF(a, b - db)) / db**2
        curv = max(curv, float(np.max(np.abs(y2))))
    bound = 1.5 * h**2 / 8 * curv + 1e-12
    assert bound < 1e-4
    err = np.abs(d.y_grid[II, JJ] - expected_fod_grid()[II, JJ])
    assert np.all(np.isfinite(err))
    assert err.max() <= bound
    # turning points and the saturation level are sampled exactly: those nodes are exact
    np.testing.assert_allclose(np.diag(d.y_grid), SURF(LEVELS, LEVELS), atol=1e-12)
    np.testing.assert_allclose(d.y_grid[:, 0], SURF.y_min, atol=1e-12)
    # the same with the levels given explicitly
    d2 = find_fod_curves(t, u, y, LEVELS)
    assert d2.levels_source == "given"
    np.testing.assert_array_equal(d2.y_grid, d.y_grid)


def test_noisy_recording_within_a_few_mv():
    rng = np.random.default_rng(20240531)
    t, u, y = thesis_sweep(f=1.0, fs=1000.0)
    un, yn = add_noise(u, y, rng)
    d = find_fod_curves(t, un, yn)
    np.testing.assert_array_equal(d.levels, LEVELS)  # grid still inferred exactly
    assert len(d.curves) == 20 and all(c.used for c in d.curves)  # dither makes no curves
    err = d.y_grid[II, JJ] - expected_fod_grid()[II, JJ]
    assert np.all(np.isfinite(err))
    assert np.max(np.abs(err)) < 0.010
    assert np.sqrt(np.mean(err**2)) < 0.003


@pytest.mark.parametrize("sigma", [0.08, 0.3, 0.5])
def test_gaussian_dither_on_u_keeps_every_curve_on_the_exact_grid(sigma):
    # Gaussian dither: the extreme samples overstate the turning values by up to ~3 sigma, and
    # with sigma = 0.3 V the input reverses by more than the default 1 V tolerance on the slow
    # legs; the grid must still be exactly -100 + 10 i, inside the recorded input range
    t, u, y = thesis_sweep(f=1.0, fs=1000.0)
    un = u + np.random.default_rng(7).normal(0.0, sigma, u.size)
    d = find_fod_curves(t, un, y)
    np.testing.assert_array_equal(d.levels, LEVELS)
    assert d.input_noise == pytest.approx(sigma, rel=0.1)
    assert d.reversal_tol >= 9.0 * sigma and d.reversal_tol >= 1.0
    assert len(d.curves) == 20 and all(c.used and c.first_order for c in d.curves)
    assert [c.level for c in d.curves] == list(range(1, 21))
    # turning values estimated from the samples around the extreme (the extreme sample is
    # biased upwards by the noise): nearly unbiased, well within level_tol
    tv = np.array([c.turning_value for c in d.curves]) - LEVELS[1:]
    assert abs(np.mean(tv)) < 0.35 * sigma
    assert np.max(np.abs(tv)) < min(2.0 * sigma, 0.9 * d.level_tol)
    err = d.y_grid[II, JJ] - expected_fod_grid()[II, JJ]
    assert np.all(np.isfinite(err)) and np.max(np.abs(err)) < 0.25 * sigma
    assert "input noise estimate" in d.report()


def test_noise_free_turning_values_are_the_extreme_samples():
    t, u, y = thesis_sweep(f=1.0, fs=1000.0)
    d = find_fod_curves(t, u, y)
    assert d.input_noise == 0.0 and d.reversal_tol == pytest.approx(1.0)
    assert [c.turning_value for c in d.curves] == [float(u[c.turn]) for c in d.curves]


def test_inferred_grid_never_extends_beyond_the_input_range():
    # the recording turns at 100 V, but u_max (positive saturation) is declared as 90 V
    t, u, y = exact_sweep()
    d = find_fod_curves(t, u, y, u_min=-100.0, u_max=90.0)
    np.testing.assert_array_equal(d.levels, LEVELS[:-1])
    top = d.curves[-1]
    assert top.turning_value == 100.0 and not top.used and "not on the grid" in top.reason


@pytest.mark.parametrize("f", [2.0, 4.0])
def test_faster_sweeps_and_other_surfaces(f):
    surf = TABLE_3_1[int(f)]
    t, u, y = thesis_sweep(surf, f=f, fs=1000.0)
    d = find_fod_curves(t, u, y, LEVELS)
    err = np.abs(d.y_grid[II, JJ] - expected_fod_grid(surf)[II, JJ])
    assert err.max() < 1e-3  # fewer samples per curve: interpolation only
    np.testing.assert_allclose(np.diag(d.y_grid), surf(LEVELS, LEVELS), atol=1e-12)


# ------------------------------------------------------------------------------------------
# FOD: repeats, truncation, rejection, dither
# ------------------------------------------------------------------------------------------
def test_repeated_sweeps_are_averaged_with_spread():
    rng = np.random.default_rng(7)
    t, u, y = thesis_sweep()
    u1, y1 = add_noise(u, y, rng)
    u2, y2 = add_noise(u, y, rng)
    uu, yy = np.concatenate((u1, u2)), np.concatenate((y1, y2))
    tt = np.arange(uu.size) * 1e-3
    d = find_fod_curves(tt, uu, yy, LEVELS)
    single1 = find_fod_curves(t, u1, y1, LEVELS)
    single2 = find_fod_curves(t, u2, y2, LEVELS)
    fod = II > 0
    assert len(d.used_curves) == 40
    assert np.all(d.count[II[fod], JJ[fod]] == 2)
    assert d.count[0, 0] == 40
    # mean of the two readings, sample std of the two readings
    # (the saturation level j = 0 of the last curve of the first sweep may be read on another
    # sample of the hold that starts the second sweep, so column 0 is compared loosely)
    a, b = single1.y_grid[II, JJ], single2.y_grid[II, JJ]
    inner = fod & (JJ > 0)
    np.testing.assert_allclose(d.y_grid[II[inner], JJ[inner]], ((a + b) / 2)[inner], atol=1e-12)
    np.testing.assert_allclose(
        d.spread[II[inner], JJ[inner]], (np.abs(a - b) / np.sqrt(2))[inner], atol=1e-12
    )
    np.testing.assert_allclose(d.y_grid[II[fod], 0], SURF.y_min, atol=0.01)
    assert 0.0005 < np.median(d.spread[II[fod], JJ[fod]]) < 0.005  # a few mV of noise
    assert np.all(np.isnan(single1.spread[II[fod], JJ[fod]]))
    err = d.y_grid[II, JJ] - expected_fod_grid()[II, JJ]
    assert np.sqrt(np.mean(err**2)) < 0.003
    assert "repeated (count >= 2): 231" in d.report()


def test_noise_free_repeat_has_zero_spread():
    t, u, y = exact_sweep()
    d = find_fod_curves(np.arange(2 * u.size) * 1e-3, np.tile(u, 2), np.tile(y, 2))
    assert np.all(d.count[II[II > 0], JJ[II > 0]] == 2)
    np.testing.assert_allclose(d.spread[II, JJ], 0.0, atol=1e-12)
    np.testing.assert_allclose(d.y_grid[II, JJ], expected_fod_grid()[II, JJ], atol=1e-12)


def test_truncated_last_curve_gives_nan_beyond():
    t, u, y = exact_sweep()
    # cut the last FOD (alpha = 100 V) when its falling input reaches 37 V
    k_peak = int(np.argmax(u))
    k_cut = k_peak + int(np.nonzero(u[k_peak:] <= 37.0)[0][0])
    d = find_fod_curves(t[: k_cut + 1], u[: k_cut + 1], y[: k_cut + 1], LEVELS)
    last = d.curves[-1]
    assert last.used and last.level == 20
    assert "stops early" in last.reason
    assert last.stop == k_cut
    row = d.y_grid[20]
    reached = LEVELS >= 37.0
    np.testing.assert_allclose(row[reached], SURF(100.0, LEVELS[reached]), atol=1e-12)
    assert np.all(np.isnan(row[~reached]))
    assert np.all(d.count[20, ~reached] == 0)
    # the other curves are complete
    exp = expected_fod_grid()
    np.testing.assert_allclose(d.y_grid[:20], exp[:20], atol=1e-12)


def test_curve_not_starting_from_saturation_is_rejected():
    step = 0.5
    # starts at 0 V: rises to 50 V, falls to -100 V (not from saturation) ...
    r0 = np.arange(0.0, 50.0 + step / 2, step)
    f0 = np.arange(50.0 - step, -100.0 - step / 2, -step)
    u0 = np.concatenate((r0, f0))
    y0 = np.full(u0.size, 1.0)  # garbage: must not reach the grid
    # ... then a proper FOD to 30 V
    t1, u1, y1 = exact_sweep(alphas=np.array([30.0]))
    u, y = np.concatenate((u0, u1)), np.concatenate((y0, y1))
    t = np.arange(u.size) * 1e-3
    d = find_fod_curves(t, u, y, LEVELS)
    assert len(d.curves) == 2
    bad, good = d.curves
    assert not bad.used and not bad.first_order
    assert "did not start from negative saturation" in bad.reason
    assert bad.turning_value == 50.0 and bad.level is None
    assert good.used and good.level == 13
    assert np.all(d.count[15] == 0)  # no alpha = 50 V row
    np.testing.assert_allclose(d.y_grid[13, :14], SURF(30.0, LEVELS[:14]), atol=1e-12)
    assert "did not start from negative saturation" in d.report()


def test_non_monotone_rise_is_rejected_and_its_first_part_kept():
    step = 0.5
    t0, u0, y0 = exact_sweep(alphas=np.array([-100.0]))  # a hold at saturation
    # rise to 50, fall to -20 (a first-order curve that stops early), rise to 80, fall
    r1 = np.arange(-100.0 + step, 50.0 + step / 2, step)
    f1 = np.arange(50.0 - step, -20.0 - step / 2, -step)
    r2 = np.arange(-20.0 + step, 80.0 + step / 2, step)
    f2 = np.arange(80.0 - step, -100.0 - step / 2, -step)
    u = np.concatenate((u0, r1, f1, r2, f2))
    y1 = np.concatenate((SURF(r1, r1), SURF(50.0, f1)))
    y = np.concatenate((y0, y1, np.full(r2.size + f2.size, 9.0)))  # second part: garbage
    d = find_fod_curves(np.arange(u.size) * 1e-3, u, y, LEVELS)
    assert len(d.curves) == 2
    first, second = d.curves
    assert first.used and first.level == 15 and "stops early" in first.reason
    np.testing.assert_allclose(d.y_grid[15, 8:16], SURF(50.0, LEVELS[8:16]), atol=1e-12)
    assert np.all(np.isnan(d.y_grid[15, :8]))
    assert not second.used and "non-monotone rise" in second.reason
    assert "reversed at 50 V" in second.reason and "back to -20 V" in second.reason
    assert np.all(d.count[18] == 0)


def test_off_grid_turning_value_is_kept_as_raw_curve():
    step = 0.1
    t0, u0, y0 = exact_sweep(alphas=np.array([-100.0]))
    rise = -100.0 + step * np.arange(1, 1433)  # ends at 43.2 V
    fall = rise[-1] - step * np.arange(1, 1433)
    u1, y1 = fod_leg(SURF, rise[-1], rise, fall)
    u, y = np.concatenate((u0, u1)), np.concatenate((y0, y1))
    d = find_fod_curves(np.arange(u.size) * 1e-3, u, y, LEVELS)
    (c,) = d.curves
    assert c.first_order and not c.used and c.level is None
    assert "43.2 V not on the grid" in c.reason
    assert d.count.sum() == 0 and np.all(np.isnan(d.y_grid))
    (raw,) = d.raw_curves
    alpha, beta, yy = raw
    assert alpha == pytest.approx(43.2)
    np.testing.assert_array_equal(beta, u[c.turn : c.stop + 1])
    np.testing.assert_allclose(yy, SURF(alpha, beta), atol=1e-12)
    assert beta[0] == alpha and beta[-1] == pytest.approx(-100.0)


def test_off_grid_sweep_falls_back_to_equally_spaced_levels():
    alphas = np.array([-100.0, -61.3, -22.7, 7.9, 48.1, 96.3])
    t, u, y = thesis_sweep(alphas=alphas, fs=200.0)
    d = find_fod_curves(t, u, y)
    assert "fallback" in d.levels_source
    np.testing.assert_allclose(d.levels, np.linspace(u.min(), u.max(), 21))
    assert len(d.raw_curves) == 5
    assert all("not on the grid" in c.reason for c in d.curves if not c.used)


def test_recording_ends_during_rise_is_too_short():
    t, u, y = exact_sweep(alphas=np.array([-100.0, 20.0]))
    u2 = np.concatenate((u, np.arange(-99.5, 60.0, 0.5)))
    y2 = np.concatenate((y, SURF(u2[u.size :], u2[u.size :])))
    d = find_fod_curves(np.arange(u2.size) * 1e-3, u2, y2, LEVELS)
    assert [c.used for c in d.curves] == [True, False]
    assert "too short" in d.curves[-1].reason


def test_dither_at_turning_point_and_backward_samples_on_branch():
    a = 60.0
    hold = np.full(3, -100.0)
    rise = np.arange(-99.5, a + 0.25, 0.5)
    wiggle_top = np.array([a - 0.3, a - 0.1, a])  # reversals < reversal_tol (1 V)
    fall1 = np.arange(a - 0.5, 50.0 - 0.25, -0.5)  # ends exactly at 50 V
    wiggle = np.array([49.7, 50.2, 49.6])  # goes back above 50 V after crossing
    fall2 = np.arange(49.5, -100.25, -0.5)
    u = np.concatenate((hold, rise, wiggle_top, fall1, wiggle, fall2))
    y = np.concatenate(
        (
            SURF(hold, hold),
            SURF(rise, rise),
            SURF(a, wiggle_top),
            SURF(a, fall1),
            SURF(a, wiggle) + 0.5,  # backward samples: must be ignored
            SURF(a, fall2),
        )
    )
    d = find_fod_curves(np.arange(u.size) * 1e-3, u, y, LEVELS)
    assert len(d.curves) == 1
    (c,) = d.curves
    assert c.used and c.level == 16
    # the last sample at the top is the turning point; first crossing at each level
    assert u[c.turn] == a and c.turn == hold.size + rise.size + wiggle_top.size - 1
    np.testing.assert_allclose(d.y_grid[16, :17], SURF(a, LEVELS[:17]), atol=1e-12)


def test_level_snapping_of_turning_value_and_branch_end():
    # turning value 0.3 V below the level and a fall that stops 0.4 V above -100 V
    a = 39.7
    rise = np.linspace(-100.0, a, 700)
    fall = np.linspace(a, -99.6, 701)[1:]
    u, y = fod_leg(SURF, a, rise, fall)
    u = np.concatenate((np.full(3, -100.0), u))
    y = np.concatenate((np.full(3, SURF.y_min), y))
    d = find_fod_curves(np.arange(u.size) * 1e-3, u, y, LEVELS, level_tol=0.5)
    (c,) = d.curves
    assert c.used and c.level == 14
    assert d.y_grid[14, 14] == y[c.turn]  # the turning-point sample
    assert d.y_grid[14, 0] == y[-1]  # snapped branch end
    np.testing.assert_allclose(d.y_grid[14, 1:14], SURF(a, LEVELS[1:14]), atol=1e-5)
    d2 = find_fod_curves(np.arange(u.size) * 1e-3, u, y, LEVELS, level_tol=0.2)
    assert not d2.curves[0].used and "not on the grid" in d2.curves[0].reason


# ------------------------------------------------------------------------------------------
# FORC
# ------------------------------------------------------------------------------------------
def forc_recording(grid, betas, step=2.0, start=None):
    """Relay-grid simulation: from +100 V down to each beta and back up to +100 V."""
    us = [np.full(3, 100.0)] if start is None else [start]
    for b in betas:
        n = int(round((100.0 - b) / step))
        us.append(100.0 - step * np.arange(1, n + 1))
        us.append(b + step * np.arange(1, n + 1))
    u = np.concatenate(us)
    grid.reset()
    y = grid.run(u)
    return np.arange(u.size) * 1e-3, u, y


def test_forc_mirror_on_relay_grid():
    surf = TABLE_3_1[2]
    grid = RelayGrid.from_everett(surf.everett, -100.0, 100.0, 80, surf.y_min)
    # a first fall from 0 V that does not start at positive saturation, then the FORCs
    start = np.arange(0.0, -50.0 - 1.0, -2.0)
    start = np.concatenate((start, np.arange(-48.0, 100.0 + 1.0, 2.0)))
    t, u, y = forc_recording(grid, LEVELS[:-1], start=start)
    assert u.size < 3000
    d = find_forc_curves(t, u, y)
    assert d.direction == "ascending"
    np.testing.assert_array_equal(d.levels, LEVELS)
    bad = d.curves[0]
    assert not bad.used and "did not start from positive saturation" in bad.reason
    assert bad.beta == -50.0 and np.isnan(bad.alpha)
    used = d.curves[1:]
    assert len(used) == 20 and all(c.used for c in used)
    assert [c.level for c in used] == list(range(20))
    np.testing.assert_array_equal([c.beta for c in used], LEVELS[:-1])
    # FORC grid: y_grid[i, j] = output at alpha = levels[i] after the reversal at levels[j];
    # for this Preisach model it is y_max - 2 E(u_max, beta) + 2 E(alpha, beta)
    E = surf.everett
    exp = surf.y_max - 2.0 * E(100.0, LEVELS[JJ]) + 2.0 * E(LEVELS[II], LEVELS[JJ])
    np.testing.assert_allclose(d.y_grid[II, JJ], exp, atol=1e-9)
    assert np.all(np.isnan(d.y_grid[np.triu_indices(21, 1)]))
    # the reversal from negative saturation rises along the major ascending branch
    np.testing.assert_allclose(d.y_grid[:, 0], surf(LEVELS, LEVELS), atol=1e-9)
    # diagonal: output at the reversal point; corner: positive saturation, visited 20 times
    np.testing.assert_allclose(d.y_grid[20, 20], surf.y_max, atol=1e-9)
    assert d.count[20, 20] == 20
    assert np.all(d.count[II[JJ < 20], JJ[JJ < 20]] == 1)
    assert "FORC" in d.report() and "positive saturation" in d.report()
    # the FOD finder sees one first-order descending curve here: after the reversal at
    # -100 V the input rises to +100 V and falls to -90 V; the later ones start at -90 V ...
    fod = find_fod_curves(t, u, y, LEVELS)
    assert [c.used for c in fod.curves].count(True) == 1
    (c,) = fod.used_curves
    assert c.alpha == 100.0 and "stops early" in c.reason
    np.testing.assert_allclose(fod.y_grid[20, 1:], surf(100.0, LEVELS[1:]), atol=1e-9)
    assert np.isnan(fod.y_grid[20, 0])
    assert sum("did not start from negative saturation" in c.reason for c in fod.curves) == 20
    assert "too short" in fod.curves[-1].reason  # the recording ends at +100 V


def test_forc_truncated_and_given_levels():
    surf = TABLE_3_1[4]
    grid = RelayGrid.from_everett(surf.everett, -100.0, 100.0, 60, surf.y_min)
    t, u, y = forc_recording(grid, np.array([-40.0, -80.0]))
    k_cut = int(np.nonzero(u == 20.0)[0][-1])  # stop the last rise at 20 V
    d = find_forc_curves(t[: k_cut + 1], u[: k_cut + 1], y[: k_cut + 1], LEVELS)
    c1, c2 = d.curves
    assert c1.used and c1.level == 6 and c2.used and c2.level == 2
    assert "stops early" in c2.reason
    E = surf.everett
    col = surf.y_max - 2.0 * E(100.0, -80.0) + 2.0 * E(LEVELS, -80.0)
    reached = (LEVELS >= -80.0) & (LEVELS <= 20.0)
    np.testing.assert_allclose(d.y_grid[reached, 2], col[reached], atol=1e-9)
    assert np.all(np.isnan(d.y_grid[~reached, 2]))


# ------------------------------------------------------------------------------------------
# interface
# ------------------------------------------------------------------------------------------
def test_recording_like_object_is_accepted():
    t, u, y = exact_sweep()
    rec = SimpleNamespace(t=t, u=u, y=y)
    d1 = find_fod_curves(rec)
    d2 = find_fod_curves(t, u, y)
    np.testing.assert_array_equal(d1.y_grid, d2.y_grid)
    d3 = find_fod_curves(rec, levels=LEVELS)
    np.testing.assert_array_equal(d3.y_grid, d2.y_grid)
    with pytest.raises(TypeError):
        find_fod_curves(rec, u)


@pytest.mark.parametrize("fn", [find_fod_curves, find_forc_curves])
def test_input_validation(fn):
    t, u, y = exact_sweep(alphas=np.array([-100.0, 0.0]))
    with pytest.raises(ValueError, match="same length"):
        fn(t, u[:-1], y)
    with pytest.raises(ValueError, match="at least 2 samples"):
        fn(t[:1], u[:1], y[:1])
    bad = u.copy()
    bad[10] = np.nan
    with pytest.raises(ValueError, match="^u contains NaN"):
        fn(t, bad, y)
    bad = y.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="^y contains NaN"):
        fn(t, u, bad)
    with pytest.raises(ValueError, match="^t must be non-decreasing"):
        fn(t[::-1], u, y)
    with pytest.raises(ValueError, match="level_tol"):
        fn(t, u, y, LEVELS, level_tol=5.0)
    with pytest.raises(ValueError, match="reversal_tol"):
        fn(t, u, y, reversal_tol=0.0)
    with pytest.raises(ValueError, match="levels must be strictly increasing"):
        fn(t, u, y, LEVELS[::-1])
    with pytest.raises(ValueError, match="u_max"):
        fn(t, np.zeros_like(u), y)


def test_report_lists_every_curve():
    t, u, y = exact_sweep(alphas=np.array([-100.0, 10.0, 90.0]))
    d = find_fod_curves(t, u, y, LEVELS)
    text = d.report()
    assert "2 used" in text and "0 rejected" in text
    assert len([ln for ln in text.splitlines() if "used: ok" in ln]) == 2
    alpha, beta, yb, cnt = d.nodes()
    assert alpha.size == 12 + 20 + 1 - 1 + 1  # rows 11 (12 nodes), 19 (20), node (0,0)
    np.testing.assert_allclose(yb, SURF(alpha, beta), atol=1e-12)
    assert np.all(alpha >= beta)
