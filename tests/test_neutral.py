"""The neutral locus N(l) (Eq 2.18), its inverse (Eq 2.19/2.20) and the Mp check."""

from __future__ import annotations

import numpy as np
import pytest
from preisach import PreisachModel
from preisach.neutral import MpCheck, NeutralLocus, check_mp, neutral_locus, neutral_output


@pytest.fixture(scope="module")
def ss15():
    return {f: PreisachModel.builtin(f"ss15-{f}hz") for f in (1, 2, 4)}


@pytest.fixture(scope="module")
def bumpy():
    """A model outside Mp whose locus is not monotone: a band of negative weight about s = 0.3."""
    lv = np.linspace(-1.0, 1.0, 41)
    mid = 0.5 * (lv[:-1] + lv[1:])
    a, b = np.meshgrid(mid, mid, indexing="ij")
    lower = np.tri(40, dtype=bool)
    w = np.where(lower, 0.01, 0.0)
    s = 0.5 * (a + b)
    w[(s > 0.2) & (s < 0.45) & lower] -= 0.02
    return PreisachModel.from_weights(lv, w)


def test_locus_is_the_readout_of_the_exact_neutral_state(ss15):
    m = ss15[1]
    rng = np.random.default_rng(3)
    ls = np.sort(rng.uniform(-100, 100, 25))
    got = neutral_output(m, ls)
    want = [m.readout(m.neutral_state(x)) for x in ls]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    assert float(neutral_output(m, 0.0)) == pytest.approx(
        m.readout(m.anhysteretic_state()), abs=1e-13
    )


@pytest.mark.parametrize("f", [1, 2, 4])
def test_ss15_locus_spans_the_major_loop_and_is_monotone(ss15, f):
    m = ss15[f]
    loc = neutral_locus(m)
    assert loc.l.size == 2 * len(m.levels) - 1
    assert loc.N[0] == pytest.approx(m.y_min, abs=1e-12)
    assert loc.N[-1] == pytest.approx(m.y_max, abs=1e-12)
    assert loc.monotone  # thesis §4.3: "a dash-dot line which is monotonic"
    # inside the major loop: between the ascending and the descending branch
    inner = loc.l[20:-20:20]
    up = m.simulate(
        inner, m.negative_saturation()
    ).output  # inner is increasing: the ascending branch
    down = [m.readout(m.positive_saturation().apply([x])) for x in inner]
    assert np.all(loc(inner) > up) and np.all(loc(inner) < down)


@pytest.mark.parametrize("f", [1, 2, 4])
def test_inverse_round_trip_and_both_definitions_agree_when_monotone(ss15, f):
    loc = neutral_locus(ss15[f])
    for y in (-3.0, -0.5, 0.0, 1.0, 2.7):
        l_inv = loc.inverse(y)
        assert float(loc(l_inv)) == pytest.approx(y, abs=1e-9)
        assert loc.inverse(y, "inverse") == l_inv
        assert loc.inverse(y, "min-abs") == pytest.approx(l_inv, abs=1e-12)
        assert loc.solutions(y).size == 1


def test_inverse_of_y_d_1(ss15):
    # y_d = 1 V needs a positive offset on all three models; it shrinks with the frequency
    ls = [neutral_locus(ss15[f]).inverse(1.0) for f in (1, 2, 4)]
    assert 0 < ls[2] < ls[1] < ls[0] < 40


def test_non_monotone_locus_uses_smallest_abs_l(bumpy):
    loc = neutral_locus(bumpy)
    assert not loc.monotone
    y = float(loc(0.3))
    sols = loc.solutions(y)
    assert sols.size == 3
    np.testing.assert_allclose(loc(sols), y, atol=1e-9)
    assert np.any(np.isclose(sols, 0.3, atol=1e-9))
    expected = sols[np.argmin(np.abs(sols))]
    assert loc.inverse(y) == pytest.approx(expected)
    assert loc.inverse(y, "min-abs") == pytest.approx(expected)
    assert abs(loc.inverse(y)) < 0.3
    with pytest.raises(ValueError, match="monotone"):
        loc.inverse(y, "inverse")


def test_min_abs_prefers_the_negative_root_when_it_is_nearer():
    offsets = np.linspace(-1.0, 1.0, 201)
    loc = NeutralLocus(offsets, offsets**3 - 0.5 * offsets)  # measured, not monotone
    sols = loc.solutions(0.1)
    assert sols.size == 3
    np.testing.assert_allclose(sols**3 - 0.5 * sols, 0.1, atol=2e-4)  # linear interpolation
    smallest = sols[np.argmin(np.abs(sols))]
    assert smallest < 0
    assert loc.inverse(0.1) == smallest


def test_measured_locus_interpolates():
    offsets = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    n = np.array([-3.0, -1.0, 0.0, 2.0, 3.0])
    loc = NeutralLocus(offsets, n)
    assert loc.source == "measured" and loc.table is None
    assert loc.inverse(1.0) == pytest.approx(0.5)
    assert loc.inverse(-2.0) == pytest.approx(-1.5)
    assert loc.inverse(2.0) == pytest.approx(1.0)  # exact grid root
    assert float(loc(0.25)) == pytest.approx(0.5)


def test_locus_errors(ss15):
    loc = neutral_locus(ss15[1])
    with pytest.raises(ValueError, match="outside the range"):
        loc.inverse(5.0)
    with pytest.raises(ValueError, match="method"):
        loc.inverse(1.0, "newton")
    with pytest.raises(ValueError, match="l\\[1\\]"):
        neutral_output(ss15[1], [0.0, 150.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        NeutralLocus([0.0, 0.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="same length"):
        NeutralLocus([0.0, 1.0], [0.0])
    with pytest.raises(ValueError, match="either l or points"):
        neutral_locus(ss15[1], [0.0, 1.0], points=3)


def test_mp_check(ss15, bumpy):
    c1 = check_mp(ss15[1])
    assert isinstance(c1, MpCheck) and c1.in_mp and c1.bounded and c1.n_negative == 0
    assert c1.total_mass == pytest.approx((ss15[1].y_max - ss15[1].y_min) / 2)
    # 2 Hz and 4 Hz: tiny negative masses at the far corner (thesis §3.3.3: (100, -100), ...)
    for f in (2, 4):
        c = check_mp(ss15[f])
        assert not c.in_mp and c.n_negative > 0
        assert -1e-5 < c.min_weight < 0
        worst = c.negative_cells[0]
        assert worst[2] == c.min_weight
        assert worst[0] >= 80 and worst[1] <= -90
        assert check_mp(ss15[f], tolerance=1e-5).in_mp
    cb = check_mp(bumpy)
    assert not cb.in_mp and cb.n_negative > 100 and cb.negative_mass < -1
    assert "not in Mp" in str(cb) and "in Mp" in str(c1)
    assert cb.to_dict()["n_negative"] == cb.n_negative
    with pytest.raises(ValueError, match="tolerance"):
        check_mp(bumpy, tolerance=-1.0)


def test_locus_plot(ss15):
    fig = neutral_locus(ss15[1]).plot(model=ss15[1], points={"psi_n": (25.8, 1.0)})
    ax = fig.axes[0]
    assert ax.get_xlabel() == "input u, l (V)" and ax.get_ylabel() == "output y (V)"
    assert len(ax.lines) == 4  # two branches, the locus, the point
