"""The user-facing PreisachModel: construction, built-in SS15 models, states, simulation."""

import copy
import pickle

import numpy as np
import preisach
import pytest
from preisach import PreisachModel, State
from preisach.reference import RelayGrid
from preisach.surface import TABLE_3_1


@pytest.fixture(scope="module")
def ss15():
    return {f: PreisachModel.builtin(f"ss15-{f}hz") for f in (1, 2, 4)}


def smooth_everett(a, b):
    """Everett function of a smooth positive density on [-1, 1] plus a reversible part."""
    d = a - b
    return 0.3 * d**2 * (1.2 + 0.2 * (a + b)) + 0.25 * d


def random_walk(n, seed, lo=-1.0, hi=1.0, step=0.05):
    rng = np.random.default_rng(seed)
    return np.clip(np.cumsum(rng.normal(0, step, n)), lo, hi)


# ---------------------------------------------------------------- built-in SS15 models
@pytest.mark.parametrize("f", [1, 2, 4])
def test_builtin_matches_table_3_1_saturation_outputs(ss15, f):
    m, t = ss15[f], TABLE_3_1[f]
    assert m.y_max == pytest.approx(t.y_max, abs=1e-12)
    assert m.y_min == pytest.approx(t.y_min, abs=1e-12)
    # Driving the model: rise to u_max gives y(u,u) = y_max, then down to u_min gives y_min.
    res = m.simulate(
        np.r_[np.linspace(-100, 100, 401), np.linspace(100, -100, 401)], m.negative_saturation()
    )
    assert res.output[400] == pytest.approx(t.y_max, abs=1e-12)
    assert res.output[-1] == pytest.approx(t.y_min, abs=1e-12)
    assert m.readout(m.positive_saturation()) == pytest.approx(t.y_max, abs=1e-12)
    assert m.readout(m.negative_saturation()) == pytest.approx(t.y_min, abs=1e-12)


def test_builtin_weight_sign_on_thesis_grid_matches_section_3_3_3():
    g = np.linspace(-100, 100, 40)
    a, b = np.meshgrid(g, g, indexing="ij")
    lower = a >= b
    mu1 = TABLE_3_1[1].weight_density(a, b)
    assert np.all(mu1[lower] >= 0), "1 Hz weight must be non-negative (mu in Mp)"
    mu2 = TABLE_3_1[2].weight_density(a, b)
    neg = np.argwhere((mu2 < 0) & lower)
    assert len(neg) > 0
    assert np.all(g[neg[:, 1]] == -100.0)
    assert np.all(g[neg[:, 0]] >= 84.0)
    assert mu2[lower].min() > -1e-5  # tiny, as the thesis says (-1.18e-6)


def test_builtin_fod_nodes_follow_eq_3_2(ss15):
    m, s = ss15[2], TABLE_3_1[2]
    lv = m.levels
    y = m.fod_grid()
    i, j = np.tril_indices(len(lv))
    np.testing.assert_allclose(y[i, j], s(lv[i], lv[j]), atol=1e-12)


def test_builtin_unknown_name():
    with pytest.raises(ValueError, match="ss15-1hz"):
        PreisachModel.builtin("ss16")


# ---------------------------------------------------------------- construction paths
def test_from_fod_grid_round_trip(ss15):
    m = ss15[1]
    m2 = PreisachModel.from_fod_grid(m.levels, m.fod_grid())
    np.testing.assert_allclose(m2.everett_values, m.everett_values, atol=1e-13)
    assert m2.y_min == pytest.approx(m.y_min, abs=1e-13)


def test_from_weights_matches_relay_masses():
    lv = np.linspace(-1, 1, 21)
    m = PreisachModel.from_everett(smooth_everett, lv)
    w = m.cell_weights()
    assert np.all(w[np.tril_indices(20)] > 0)
    m2 = PreisachModel.from_weights(lv, w, y_min=m.y_min)
    np.testing.assert_allclose(m2.everett_values, m.everett_values, atol=1e-13)
    # Classical default offset: y = sum(w * gamma), symmetric saturations.
    m3 = PreisachModel.from_weights(lv, w)
    assert m3.y_max == pytest.approx(-m3.y_min) == pytest.approx(w.sum())


def test_from_weights_rejects_upper_triangle():
    lv = np.linspace(0, 1, 4)
    with pytest.raises(ValueError, match="above the diagonal"):
        PreisachModel.from_weights(lv, np.ones((3, 3)))


@pytest.mark.parametrize(
    "levels, match",
    [([0.0, 0.0, 1.0], "strictly increasing"), ([1.0], "at least 2"), ([[0, 1], [2, 3]], "1-D")],
)
def test_bad_levels(levels, match):
    with pytest.raises(ValueError, match=match):
        PreisachModel.from_everett(smooth_everett, levels)


def test_everett_table_shape_error_names_expected_shape():
    with pytest.raises(ValueError, match=r"expected \(3, 3\)"):
        preisach._core.EverettTable(np.arange(3.0), np.zeros((2, 3)), 0.0)


def test_from_everett_rejects_non_finite():
    with pytest.raises(ValueError, match="not finite"):
        PreisachModel.from_everett(
            lambda a, b: np.where(a > 0.5, np.nan, a - b), np.linspace(0, 1, 5)
        )


# ---------------------------------------------------------------- simulation correctness
def test_agrees_with_relay_grid_and_gap_shrinks():
    m = PreisachModel.from_everett(smooth_everett, np.linspace(-1, 1, 401))
    u = random_walk(1500, seed=3)
    y = m.simulate(u, m.negative_saturation()).output
    gaps = []
    for n in (20, 40, 80, 160):
        rg = RelayGrid.from_everett(smooth_everett, -1, 1, n, m.y_min)
        gaps.append(np.abs(rg.run(u) - y).max())
    assert all(g2 < 0.7 * g1 for g1, g2 in zip(gaps, gaps[1:])), gaps
    assert gaps[-1] < 0.01 * (m.y_max - m.y_min)


def test_everett_interpolation_is_continuous_and_zero_on_diagonal(ss15):
    m = ss15[4]
    x = np.linspace(-100, 100, 2001)
    np.testing.assert_array_equal(m.everett(x, x), 0.0)
    # Continuity across grid lines: tiny step, tiny change.
    g = m.levels[1:-1]
    eps = 1e-9
    e_lo = m.everett(g - eps, -100.0 + 0.3)
    e_hi = m.everett(g + eps, -100.0 + 0.3)
    assert np.abs(e_hi - e_lo).max() < 1e-8


def test_saturation_states_and_limits(ss15):
    m = ss15[1]
    y = m.simulate([100.0, 100.0, -100.0], m.anhysteretic_state()).output
    assert y[0] == pytest.approx(m.y_max) and y[2] == pytest.approx(m.y_min)


def test_step_and_run_agree(ss15):
    m = ss15[2]
    u = 100 * np.sin(np.linspace(0, 20, 3000)) * np.linspace(1, 0.2, 3000)
    sim = m.simulator(m.negative_saturation())
    ys = np.array([sim.step(x) for x in u])
    np.testing.assert_array_equal(ys, m.simulate(u, m.negative_saturation()).output)
    assert sim.state == m.simulate(u, m.negative_saturation()).final_state


def test_final_state_continues_the_run(ss15):
    m = ss15[1]
    u = 90 * np.sin(np.linspace(0, 30, 4000)) * np.exp(-np.linspace(0, 2, 4000))
    whole = m.simulate(u, m.negative_saturation()).output
    first = m.simulate(u[:1700], m.negative_saturation())
    second = m.simulate(u[1700:], first.final_state)
    np.testing.assert_array_equal(np.r_[first.output, second.output], whole)
    assert m.readout(first.final_state) == first.output[-1]


def decaying_oscillation(lv, ratio, u_hat=100.0):
    """Extrema of a sinusoid about lv decaying from amplitude u_hat - |lv| (after saturation)."""
    n = int(np.log(1e-6) / np.log(ratio))
    amps = (u_hat - abs(lv)) * ratio ** np.arange(n)
    start = [u_hat] if lv > 0 else [-u_hat]
    return start + list(lv + amps * np.where(np.arange(n) % 2 == 0, -1.0, 1.0)) + [lv]


def test_neutral_state_is_the_limit_of_a_decaying_oscillation(ss15):
    m = ss15[1]

    def probe_up(lv):
        return np.r_[np.linspace(lv, lv + 20, 50), np.linspace(lv + 20, lv - 30, 80)]

    for lv in (-40.0, 0.0, 25.0, 70.0):
        exact = m.neutral_state(lv)
        errs = []
        for ratio in (0.8, 0.9, 0.97, 0.995):
            approx = m.state_from_extrema(decaying_oscillation(lv, ratio))
            errs.append(abs(m.readout(approx) - m.readout(exact)))
        # The staircase approaches the exact horizontal segment as the decay slows.
        assert all(e2 < 0.5 * e1 for e1, e2 in zip(errs, errs[1:])), errs
        assert errs[-1] < 3e-6
        np.testing.assert_allclose(
            m.simulate(probe_up(lv), approx).output,
            m.simulate(probe_up(lv), exact).output,
            atol=2e-6,
        )


def test_anhysteretic_is_neutral_at_zero(ss15):
    m = ss15[2]
    assert m.anhysteretic_state() == m.neutral_state(0.0)
    assert m.anhysteretic_state().input == 0.0


def test_state_from_extrema_wipes_out(ss15):
    m = ss15[1]
    s = m.state_from_extrema([50, -20, 30, -10, 60, 0])
    assert s.extrema() == [60.0, 0.0]
    with pytest.raises(ValueError, match="start"):
        m.state_from_extrema([1.0], start="middle")


# ---------------------------------------------------------------- derivatives (Appendix A)
def test_slopes_match_finite_differences(ss15):
    m = ss15[2]
    h = 1e-4
    for seq in ([60.0, -30.5], [70.3, -40.2, 20.7], [-100.0, 33.3], [80.0, -60.0, 10.0, -20.0]):
        s = m.state_from_extrema(seq)
        u = s.input
        sl = m.slopes(s)
        y0 = m.readout(s)
        up = (m.simulate([u + h], s).output[0] - y0) / h
        down = (y0 - m.simulate([u - h], s).output[0]) / h
        assert sl.rising == pytest.approx(up, rel=1e-5)
        assert sl.falling == pytest.approx(down, rel=1e-5)


def _appendix_a_interval(surf, us, prev):
    """Ends of the subderivative interval of Eq A.38 at a reversal ``us`` (V) whose previous
    dominant extremum is ``prev`` (V), by quadrature of the surface's weight density.

    Appendix A works in (r, s) = ((alpha - beta) / 2, (alpha + beta) / 2): the density there is
    v(r, s) = 2 v(alpha, beta) (the Jacobian of alpha = s + r, beta = s - r is 2), and its
    kappa(u) is the slope just after a reversal (A.14 with r~ = 0), i.e. twice the kappa of
    Eq 2.14 (half the initial FOD slope), which SqrtSurface.kappa returns.  A.38:
    y'_lambda(us) = 2 lambda int_0^{|us - prev| / 2} v(r, us - sgn(us - prev) r) dr + kappa(us).
    """
    from scipy.integrate import quad

    sgn = np.sign(us - prev)

    def v_rs(r):
        s = us - sgn * r
        return 2.0 * float(surf.weight_density(s + r, s - r))

    integral, _ = quad(v_rs, 0.0, abs(us - prev) / 2.0, epsabs=1e-12)
    kappa = 2.0 * float(surf.kappa(us))
    return kappa, kappa + 2.0 * integral  # lambda = 0 and lambda = 1


@pytest.mark.parametrize(
    "extrema",
    [
        [60.0, -30.0],  # minimum on the grid
        [60.0, -30.5],  # minimum between grid levels
        [-100.0, 33.3],  # maximum after negative saturation
        [70.3, -40.2, 20.7],  # maximum on a minor loop
        [80.0, -60.0, 10.0, -20.0],  # minimum on a minor loop
        [90.0, -90.0, 50.5],
    ],
)
def test_subderivative_interval_at_reversal(ss15, extrema):
    m, surf = ss15[1], TABLE_3_1[1]
    s = m.state_from_extrema(extrema)
    us, prev = s.input, extrema[-2]
    lo, hi = m.slopes(s).interval
    # one-sided finite-difference slopes just after the reversal lie in [lo, hi]: continuing
    # in the direction of the last leg follows the branch (the steep end), reversing starts on
    # the diagonal (the kappa end)
    y0 = m.readout(s)
    for h in (1e-2, 1e-3):
        up = (m.simulate([us + h], s).output[0] - y0) / h
        down = (y0 - m.simulate([us - h], s).output[0]) / h
        for fd in (up, down):
            assert lo - 1e-6 <= fd <= hi + 1e-6
        at_max = us > prev
        assert (up if at_max else down) == pytest.approx(hi, rel=1e-4)
        assert (down if at_max else up) == pytest.approx(lo, rel=1e-4)
    assert hi - lo > 0.05 * lo  # a real interval, not a point
    # the ends against Appendix A (Eq A.38 with lambda = 0 and 1, i.e. A.27 and A.13 at the
    # reversal) computed from the surface itself, within the error of the h = 1 V grid: the
    # diagonal half-cell (area h^2 / 2) holds v as well as kappa, so the table's reversal slope
    # is off by about 2 (v h^2 / 2) / h = h max|v|
    k_end, branch_end = _appendix_a_interval(surf, us, prev)
    a, b = np.meshgrid(np.linspace(-100, 100, 201), np.linspace(-100, 100, 201), indexing="ij")
    grid_error = 1.0 * float(np.max(np.abs(surf.weight_density(a, np.minimum(a, b)))))
    assert abs(lo - k_end) <= grid_error
    assert abs(hi - branch_end) <= grid_error
    assert grid_error < 0.05 * (branch_end - k_end)  # the check separates the two ends


def test_neutral_state_has_diagonal_slope_both_ways(ss15):
    m = ss15[1]
    sl = m.slopes(m.neutral_state(20.0))
    assert sl.rising == pytest.approx(sl.falling, rel=0.01)
    assert sl.rising == pytest.approx(2 * TABLE_3_1[1].kappa(20.0), rel=0.02)
    # On the ascending major branch the rising slope is larger (A.14 with r > 0).
    asc = m.state_from_extrema([20.0])
    assert m.slopes(asc).rising > 1.15 * sl.rising


# ---------------------------------------------------------------- input policy and errors
def test_out_of_range_clamp_and_raise(ss15):
    m = ss15[1]
    y = m.simulate([150.0, -150.0], m.negative_saturation()).output
    assert y[0] == pytest.approx(m.y_max) and y[1] == pytest.approx(m.y_min)
    with pytest.raises(ValueError, match=r"u\[1\] = 150"):
        m.simulate([0.0, 150.0], out_of_range="raise")
    strict = PreisachModel(m.table, out_of_range="raise")
    with pytest.raises(ValueError, match=r"u\[0\]"):
        strict.simulate([-101.0])
    with pytest.raises(ValueError, match="clamp"):
        m.simulate([0.0], out_of_range="wrap")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_input_names_index(ss15, bad):
    u = np.zeros(10)
    u[7] = bad
    with pytest.raises(ValueError, match=r"u\[7\] is not finite"):
        ss15[1].simulate(u)


def test_wrong_shapes_and_dtypes(ss15):
    m = ss15[1]
    with pytest.raises(ValueError, match="1-D"):
        m.simulate(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="2-D"):
        m.simulate_batch(np.zeros(3))
    with pytest.raises(ValueError, match=r"t: shape"):
        m.simulate(np.zeros(3), t=np.zeros(4))
    # integer input is converted
    assert len(m.simulate(np.array([1, 2, 3]))) == 3
    assert len(m.simulate(np.array([1, 2, 3], dtype=np.uint8))) == 3
    for bad in (
        np.array([1.0 + 0j, 2.0]),
        np.array(["1", "2"]),
        np.array([True, False]),
        np.array([1.0, None]),
    ):
        with pytest.raises(ValueError, match=rf"u: .*dtype {bad.dtype}"):
            m.simulate(bad)
        with pytest.raises(ValueError, match=rf"u: .*dtype {bad.dtype}"):
            m.simulate_batch(np.stack([bad, bad]))
    with pytest.raises(ValueError, match="t: .*dtype complex128"):
        m.simulate([1.0, 2.0], t=np.array([0.0, 1.0 + 0j]))
    with pytest.raises(ValueError, match=r"t\[1\] = nan is not finite"):
        m.simulate([1.0, 2.0], t=[0.0, np.nan])
    with pytest.raises(ValueError, match=r"strictly increasing.*t\[2\] = 0\.5"):
        m.simulate([1.0, 2.0, 3.0], t=[0.0, 1.0, 0.5])
    with pytest.raises(ValueError, match=r"strictly increasing.*t\[1\]"):
        m.simulate([1.0, 2.0], t=[0.0, 0.0])
    assert m.simulate([1.0, 2.0], t=[0.0, 0.5]).time.tolist() == [0.0, 0.5]


def test_state_validation_errors():
    with pytest.raises(ValueError, match="non-increasing"):
        State(-1.0, 1.0, 0.0, [-1.0, -0.5], [0.2, 0.6], [False, False])
    with pytest.raises(ValueError, match="diagonal"):
        State(-1.0, 1.0, 0.5, [-1.0], [0.2], [False])
    with pytest.raises(ValueError, match="outside"):
        State.neutral(-1.0, 1.0, 2.0)


def test_state_range_must_match_model(ss15):
    with pytest.raises(ValueError, match="input range"):
        ss15[1].simulate([0.0], State.negative_saturation(-1.0, 1.0))


# ---------------------------------------------------------------- batch
def test_batch_equals_sequential_and_thread_counts_agree(ss15):
    m = ss15[4]
    U = np.stack([random_walk(3000, s, -100, 100, 3.0) for s in range(7)])
    states = [
        m.anhysteretic_state(),
        m.neutral_state(30.0),
        m.positive_saturation(),
        m.negative_saturation(),
        m.neutral_state(-60.0),
        m.anhysteretic_state(),
        m.state_from_extrema([50, -50]),
    ]
    batch = m.simulate_batch(U, states, threads=1)
    Y1, f1 = batch  # unpacks like the pair it always was
    assert batch.output is Y1 and batch.final_states is f1
    Y2, f2 = m.simulate_batch(U, states, threads=2)
    np.testing.assert_array_equal(Y1, Y2)
    assert f1 == f2
    for r in range(7):
        res = m.simulate(U[r], states[r])
        np.testing.assert_array_equal(Y1[r], res.output)
        assert f1[r] == res.final_state


def test_batch_broadcasts_one_input_over_many_initial_states(ss15):
    m = ss15[2]
    u = random_walk(2000, 3, -100, 100, 3.0)
    states = [m.anhysteretic_state(), m.neutral_state(40.0), m.state_from_extrema([70, -30])]
    for uu in (u[None, :], u):  # one row, or a 1-D input, with three states
        Y, finals = m.simulate_batch(uu, states, threads=2)
        assert Y.shape == (3, u.size) and len(finals) == 3
        for r, st in enumerate(states):
            res = m.simulate(u, st)
            np.testing.assert_array_equal(Y[r], res.output)
            assert finals[r] == res.final_state
    # a 1-D input with one (or the default) state is still not a batch
    with pytest.raises(ValueError, match="2-D"):
        m.simulate_batch(u, states[0])
    with pytest.raises(ValueError, match="at least one"):
        m.simulate_batch(u[None, :], [])


def test_simulate_batch_releases_the_gil(ss15):
    import threading
    import time

    m = ss15[1]
    n = 1_500_000
    U = np.tile(np.where(np.arange(n) % 2, 1.0, -1.0) * np.linspace(100.0, 0.0, n), (4, 1))
    count = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            count[0] += 1

    th = threading.Thread(target=spin, daemon=True)
    th.start()
    try:
        time.sleep(0.05)
        c0, t0 = count[0], time.perf_counter()
        time.sleep(0.2)  # the rate of the counter while this thread does not hold the GIL
        free_rate = (count[0] - c0) / (time.perf_counter() - t0)
        c1, t1 = count[0], time.perf_counter()
        m.simulate_batch(U, threads=1)
        busy = time.perf_counter() - t1
        during = count[0] - c1
    finally:
        stop.set()
        th.join()
    assert busy > 0.05
    # with the GIL held the counter only runs in the few switch intervals around the call
    # (measured: about 1 % of the free rate); released, it runs throughout (about 50 %)
    assert during > 0.15 * free_rate * busy


def test_batch_error_names_row(ss15):
    m = ss15[1]
    U = np.zeros((3, 5))
    U[2, 4] = np.nan
    with pytest.raises(ValueError, match=r"row 2: input u\[4\]"):
        m.simulate_batch(U)
    with pytest.raises(ValueError, match="one state or one per"):
        m.simulate_batch(U, [m.anhysteretic_state()] * 2)


# ---------------------------------------------------------------- persistence
def test_save_load_exact(tmp_path, ss15):
    m = ss15[2]
    p = tmp_path / "m.npz"
    m.save(p)
    m2 = PreisachModel.load(p)
    assert m2 == m and m2.name == m.name and m2.metadata == m.metadata
    u = random_walk(5000, 1, -100, 100, 4.0)
    np.testing.assert_array_equal(m.simulate(u).output, m2.simulate(u).output)


def test_save_is_atomic_and_keeps_the_old_file_on_bad_metadata(tmp_path, ss15):
    p = tmp_path / "m.npz"
    ss15[1].save(p)
    before = p.read_bytes()
    bad = PreisachModel(ss15[2].table, metadata={"when": object()})
    with pytest.raises(TypeError, match=r"m\.npz.*metadata.*JSON"):
        bad.save(p)
    assert p.read_bytes() == before  # the existing model survives
    assert sorted(x.name for x in tmp_path.iterdir()) == ["m.npz"]  # no temporary file left
    assert PreisachModel.load(p) == ss15[1]


def test_load_names_the_file_of_empty_truncated_and_incomplete_models(tmp_path, ss15):
    good = tmp_path / "good.npz"
    ss15[1].save(good)
    data = good.read_bytes()
    cases = {
        "empty.npz": b"",  # EOFError in numpy
        "truncated.npz": data[:300],  # zipfile.BadZipFile
        "damaged.npz": data[:400] + bytes(200) + data[600:],  # a member is corrupt
    }
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
    d = dict(np.load(good))
    del d["version"]
    np.savez(tmp_path / "noversion.npz", **d)  # KeyError in numpy
    del d["everett"]
    np.savez(tmp_path / "nofields.npz", **d)
    np.save(tmp_path / "array.npy", np.zeros(3))
    expected = {
        "empty.npz": "empty",
        "truncated.npz": "not a readable",
        "damaged.npz": "damaged",
        "noversion.npz": "missing 'version'",
        "nofields.npz": "missing 'version', 'everett'",
        "array.npy": "not a preisach model",
    }
    for name, what in expected.items():
        with pytest.raises(ValueError, match=name.replace(".", r"\.")) as exc:
            PreisachModel.load(tmp_path / name)
        assert what in str(exc.value), (name, str(exc.value))


def test_load_rejects_other_files(tmp_path):
    p = tmp_path / "x.npz"
    np.savez(p, a=np.zeros(2))
    with pytest.raises(ValueError, match="not a preisach model"):
        PreisachModel.load(p)
    q = tmp_path / "y.npz"
    q.write_text("hello")
    with pytest.raises(ValueError, match="not a readable model"):
        PreisachModel.load(q)


def test_load_rejects_newer_version(tmp_path, ss15):
    p = tmp_path / "m.npz"
    ss15[1].save(p)
    d = dict(np.load(p))
    d["version"] = np.array(99)
    np.savez(p, **d)
    with pytest.raises(ValueError, match="newer"):
        PreisachModel.load(p)


def test_pickle_and_copy_exact(ss15):
    m = ss15[1]
    m2 = pickle.loads(pickle.dumps(m))
    assert m2 == m
    s = m.state_from_extrema([80, -60, 40, -20, 10])
    n = m.neutral_state(33.0)
    for st in (s, n, m.positive_saturation(), m.negative_saturation()):
        assert pickle.loads(pickle.dumps(st)) == st
        assert copy.deepcopy(st) == st and copy.copy(st) == st
    assert s != n


def test_state_json_round_trip(ss15):
    import json

    from preisach import state_from_dict, state_to_dict

    m = ss15[1]
    for st in (
        m.neutral_state(-20.0),
        m.state_from_extrema([70, -50, 10]),
        m.negative_saturation(),
    ):
        d = json.loads(json.dumps(state_to_dict(st)))
        assert state_from_dict(d) == st
    d = state_to_dict(m.neutral_state(10.0))
    d["pieces"][0][2] = "curved"
    with pytest.raises(ValueError, match="curved"):
        state_from_dict(d)
    with pytest.raises(ValueError, match="malformed"):
        state_from_dict({"u_min": -100})


# ---------------------------------------------------------------- result object
def test_result_unpacks_and_plots(ss15):
    m = ss15[1]
    res = m.simulate(np.linspace(0, 50, 10), sample_time=0.01)
    t, y = res
    np.testing.assert_allclose(t, np.arange(10) * 0.01)
    assert y is res.output
    from matplotlib.figure import Figure

    fig = res.plot()
    assert isinstance(fig, Figure)
    assert fig.axes[0].get_xlabel() == "time t (s)"
