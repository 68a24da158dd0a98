"""The C++ identification core through preisach._core: Mayergoyz with gaps, weight density and
kappa (Eq 2.12-2.14), projection to mu >= 0, and the linear regressor / normal equations."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from preisach import PreisachModel, _core
from preisach.surface import TABLE_3_1
from scipy.optimize import minimize


def _theta(model: PreisachModel) -> np.ndarray:
    e = model.everett_values
    return np.append(e[np.tril_indices(e.shape[0], -1)], model.y_min)


def test_mayergoyz_complete_grid_equals_from_fod():
    m = PreisachModel.builtin("ss15-2hz", levels=21)
    y = m.fod_grid()
    table, filled, n_col0, n_ymin, rows = _core.mayergoyz(m.levels, y, "raise")
    ref = _core.EverettTable.from_fod(m.levels, y)
    np.testing.assert_array_equal(np.asarray(table.values), np.asarray(ref.values))
    assert table.y_min == pytest.approx(ref.y_min, abs=1e-15)
    assert filled.shape == (0, 2) and n_col0 == 0 and n_ymin == 21 and rows.size == 0


def test_mayergoyz_gaps():
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    y = m.fod_grid()
    y[14, 2:7] = np.nan  # a curve with a hole
    y[20, :5] = np.nan  # the top curve stopped early (its end point by the u_min rule)
    with pytest.raises(ValueError, match=r"y_grid\[14, 2\] \(alpha = 40 V, beta = -80 V\)"):
        _core.mayergoyz(m.levels, y, "raise")
    table, filled, n_col0, _, _ = _core.mayergoyz(m.levels, y, "fill")
    assert len(filled) == 10 and n_col0 == 1
    assert {tuple(r) for r in filled} == {(14, j) for j in range(2, 7)} | {
        (20, j) for j in range(5)
    }
    # the smoothest-density fill stays within a millivolt of the true surface (E up to 3.6 V)
    assert np.max(np.abs(np.asarray(table.values) - m.everett_values)) < 1e-3
    with pytest.raises(ValueError, match="gaps"):
        _core.mayergoyz(m.levels, y, "zero")


def test_weight_density_matches_eq_2_13_and_2_14_of_the_surface():
    surf = TABLE_3_1[1]
    m = PreisachModel.builtin("ss15-1hz")  # 201 levels, h = 1 V
    v, kappa = _core.weight_density(m.table)
    c = 0.5 * (m.levels[1:] + m.levels[:-1])
    i, j = np.tril_indices(c.size, -1)
    ref_v = surf.weight_density(c[i], c[j])
    np.testing.assert_allclose(v[i, j], ref_v, rtol=2e-3, atol=1e-3 * np.max(np.abs(ref_v)))
    # kappa = mass of the diagonal half-cell / width: Eq 2.14 plus the half-cell's share of v
    ref_k = surf.kappa(c) + 0.5 * 1.0 * surf.weight_density(c, c)
    np.testing.assert_allclose(kappa, ref_k, rtol=2e-3)
    assert np.all(np.isnan(np.diag(v)))
    w = m.cell_weights()
    np.testing.assert_allclose(kappa * np.diff(m.levels), np.diag(w))


def _slsqp_projection(levels: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Reference: nearest E' (least squares over the nodes) with all cell masses >= 0 and the
    corner node fixed, by SLSQP on the free nodes."""
    n = levels.size
    a, b = np.tril_indices(n, -1)
    corner = (a == n - 1) & (b == 0)
    free = ~corner

    def full(x: np.ndarray) -> np.ndarray:
        v = np.zeros((n, n))
        v[a[free], b[free]] = x
        v[n - 1, 0] = E[n - 1, 0]
        return v

    def masses(x: np.ndarray) -> np.ndarray:
        t = _core.EverettTable(levels, full(x), 0.0)
        w = np.asarray(t.cell_weights())
        return w[np.tril_indices(n - 1)]

    x0 = E[a[free], b[free]]
    res = minimize(
        lambda x: 0.5 * np.sum((x - x0) ** 2),
        x0,
        jac=lambda x: x - x0,
        constraints=[{"type": "ineq", "fun": masses}],
        method="SLSQP",
        options={"ftol": 1e-15, "maxiter": 500},
    )
    assert res.success, res.message
    return full(res.x)


def test_projection_is_the_least_squares_nearest_table_in_mp():
    rng = np.random.default_rng(4)
    lv = np.linspace(-1.0, 1.0, 7)
    w = np.tril(rng.uniform(0.0, 1.0, (6, 6)))
    w[4, 1], w[5, 5], w[2, 0] = -0.6, -0.3, -0.2
    t = _core.EverettTable.from_weights(lv, w, -1.0)
    r = _core.project_nonnegative(t)
    assert r.converged and r.kept_y_max and r.n_negative == 3
    assert r.negative_mass == pytest.approx(-1.1)
    wp = np.asarray(r.table.cell_weights())
    assert np.all(wp[np.tril_indices(6)] >= -1e-15)  # zero up to round-off
    assert r.table.y_max == pytest.approx(t.y_max, rel=1e-11)  # kept to the projection's tol
    assert r.table.y_min == t.y_min
    ref = _slsqp_projection(lv, np.asarray(t.values))
    np.testing.assert_allclose(np.asarray(r.table.values), ref, atol=2e-7)
    assert r.mass_moved == pytest.approx(np.abs(wp - w)[np.tril_indices(6)].sum())
    assert r.max_node_change == pytest.approx(
        np.max(np.abs(np.asarray(r.table.values) - np.asarray(t.values)))
    )


def test_projection_of_the_thesis_2hz_surface_moves_little_mass():
    m = PreisachModel.builtin("ss15-2hz")
    r = _core.project_nonnegative(m.table)
    assert r.n_negative > 0  # the thesis finds negative weights at 2 Hz (section 3.3.3)
    assert r.converged and r.kept_y_max
    assert r.mass_moved / r.total_mass < 1e-4
    assert 2 * r.max_node_change < 1e-4  # outputs move by at most 0.1 mV


@pytest.mark.parametrize("start", ["negative", "positive", "anhysteretic", "neutral"])
def test_regressor_rows_reproduce_the_simulator(start):
    m = PreisachModel.builtin("ss15-4hz", levels=31)
    states = {
        "negative": m.negative_saturation(),
        "positive": m.positive_saturation(),
        "anhysteretic": m.anhysteretic_state(),
        "neutral": m.neutral_state(-37.5),
    }
    rng = np.random.default_rng(7)
    u = np.cumsum(rng.normal(0.0, 6.0, 5000))
    u = 100.0 * np.sin(u / 100.0)  # a bounded random walk with many reversals
    s0 = states[start]
    ip, ix, data, final = _core.regressor_rows(m.levels, u, s0)
    A = sp.csr_matrix((data, ix, ip), shape=(u.size, 31 * 30 // 2 + 1))
    res = m.simulate(u, s0)
    np.testing.assert_allclose(A @ _theta(m), res.output, atol=1e-12)
    assert final == res.final_state


def test_normal_equations_match_the_explicit_design_matrix():
    m = PreisachModel.builtin("ss15-1hz", levels=11)
    rng = np.random.default_rng(2)
    u = np.clip(np.cumsum(rng.normal(0.0, 9.0, 3000)), -100, 100)
    y = rng.normal(0.0, 1.0, u.size)
    fold = (np.arange(u.size) * 3 // u.size).astype(np.int32)
    fold[:50] = -1
    G, b, yy, ysum, count, final = _core.normal_equations(
        m.levels, u, y, m.anhysteretic_state(), fold, 3
    )
    ip, ix, data, final2 = _core.regressor_rows(m.levels, u, m.anhysteretic_state())
    A = sp.csr_matrix((data, ix, ip), shape=(u.size, 56)).toarray()
    for k in range(3):
        sel = fold == k
        np.testing.assert_allclose(G[k], A[sel].T @ A[sel], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(b[k], A[sel].T @ y[sel], rtol=1e-12, atol=1e-9)
        assert yy[k] == pytest.approx(np.sum(y[sel] ** 2))
        assert ysum[k] == pytest.approx(np.sum(y[sel]))
        assert count[k] == np.count_nonzero(sel)
    assert final == final2
    with pytest.raises(ValueError, match="same length"):
        _core.normal_equations(m.levels, u, y[:-1], m.anhysteretic_state(), fold, 3)
    with pytest.raises(ValueError, match=r"fold\[0\] = 5"):
        _core.normal_equations(m.levels, u, y, m.anhysteretic_state(), fold * 0 + 5, 3)
    with pytest.raises(ValueError, match=r"y\[7\]"):
        yb = y.copy()
        yb[7] = np.nan
        _core.normal_equations(m.levels, u, yb, m.anhysteretic_state(), fold * 0, 3)
