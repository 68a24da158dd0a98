"""Regulation experiments of chapters 4-5: generators, plants, drift and closed-loop tests."""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest
from preisach import PreisachModel, _core, daq
from preisach.experiments import (
    HOLD_BAND,
    HOLD_DURATION,
    KINDS,
    SS15_INPUT_GAIN,
    TABLE_4_1,
    THESIS_GAINS,
    ClosedLoopProtocol,
    DriftProtocol,
    HoldWindowError,
    HoldWindowWarning,
    ModelPlant,
    PIConfig,
    Plant,
    branch_input,
    closed_loop_test,
    closed_loop_trials,
    control_effort,
    default_thresholds,
    differential_drift,
    drift_test,
    drift_trials,
    drive_to_state,
    landing_window,
    measure_locus,
    neutral_input,
    regulation_sweep,
    ss15_plants,
    state_slopes,
    thesis_sample_time,
    trial_noise,
)
from preisach.neutral import neutral_locus
from preisach.noise import NoiseSpec
from preisach.recording import Recording


@pytest.fixture(scope="module")
def plants():
    return ss15_plants()


@pytest.fixture(scope="module")
def inits(plants):
    return {f: {k: drive_to_state(plants[f], k, 1.0, f) for k in KINDS} for f in plants}


SEEDS = range(20)


def _means(run, plants, inits, metric):
    """Mean of ``metric`` over 20 seeds per (frequency, state, gain): all 7 thesis gains."""
    gains = [g for g in THESIS_GAINS for _ in SEEDS]
    seeds = [s for _ in THESIS_GAINS for s in SEEDS]
    out = {}
    for f in plants:
        for k in KINDS:
            rows = run(plants[f], inits[f][k], gains, seeds, keep_traces=False)
            v = np.array([getattr(r, metric) for r in rows]).reshape(len(THESIS_GAINS), -1)
            for g, m in zip(THESIS_GAINS, v.mean(axis=1)):
                out[f, k, g] = float(m)
    return out


@pytest.fixture(scope="module")
def drift_means(plants, inits):
    return _means(drift_trials, plants, inits, "drift")


@pytest.fixture(scope="module")
def effort_means(plants, inits):
    return _means(closed_loop_trials, plants, inits, "nc")


class RigLike:
    """A plant that cannot snapshot or batch, as a DAQ rig: wraps a ModelPlant."""

    def __init__(self, inner: ModelPlant):
        self._inner = inner

    @property
    def sample_time(self):
        return self._inner.sample_time

    @property
    def input_range(self):
        return self._inner.input_range

    def reset(self, state=None):
        if state is not None:
            raise ValueError("a rig cannot be set to a state")
        self._inner.reset(None)

    def run_open_loop(self, u):
        return self._inner.run_open_loop(u)

    def run_closed_loop(self, u_open, controller):
        return self._inner.run_closed_loop(u_open, controller)

    def snapshot(self):
        return None


class LinearPlant:
    """y = k u, no memory, with the PI loop written in Python through PIConfig.controller()."""

    def __init__(self, k=0.03, sample_time=1e-3):
        self.k, self._ts, self.u = k, sample_time, 0.0

    sample_time = property(lambda self: self._ts)
    input_range = property(lambda self: (-100.0, 100.0))

    def reset(self, state=None):
        self.u = 0.0

    def run_open_loop(self, u):
        u = np.asarray(u, float)
        self.u = float(u[-1])
        return self.k * u

    def run_closed_loop(self, u_open, controller):
        pi = controller.controller()
        u, y, uc = (np.zeros(len(u_open)) for _ in range(3))
        c = 0.0
        for i, base in enumerate(u_open):
            u[i] = base + controller.input_gain * c
            y[i] = self.k * u[i]
            e = controller.setpoint - y[i]
            c = pi.update(e) if i >= controller.enable_at else (pi.observe(e), 0.0)[1]
            uc[i] = c
        return u, y, uc

    def snapshot(self):
        return None


# ------------------------------------------------------------------ waveforms
def test_neutral_input_follows_eq_4_1_and_4_2():
    w = neutral_input(25.0, 2.0, u_range=(-100, 100), cycles=10, sample_time=1e-3)
    assert w.kind == "n" and w.offset == 25.0 and len(w.input) == 5000
    assert w.input[0] == pytest.approx(100.0)  # starts at +u_hat for l > 0
    assert w.input[250] == pytest.approx(25 - 75 * (5 - 0.25) / 5, abs=1e-9)  # first minimum
    assert w.time[0] == pytest.approx(-5.0) and w.time[-1] == pytest.approx(-1e-3)
    assert w.input[-1] == pytest.approx(
        25 + 75 * 1e-3 / 5
    )  # (t1 - t)/(t1 - t0) A at the last sample
    assert w.with_hold()[-1] == 25.0
    wneg = neutral_input(-40.0, 1.0, u_range=(-100, 100), cycles=5)
    assert wneg.input[0] == pytest.approx(-100.0)  # sgn(l) u_hat for l < 0
    assert wneg.input[500] == pytest.approx(-40 + 60 * 4.5 / 5, abs=1e-9)
    w0 = neutral_input(0.0, 1.0, u_range=(-100, 100))  # Eq 4.2: amplitude u_hat about 0
    assert w0.input[0] == pytest.approx(100.0) and w0.input[500] == pytest.approx(-95.0)
    with pytest.raises(ValueError, match="outside the input range"):
        neutral_input(120.0, 1.0, u_range=(-100, 100))


def test_neutral_input_reaches_the_neutral_state(plants):
    p = plants[1.0]
    m = p.model
    offset = 25.0
    exact = m.neutral_state(offset)
    for cycles, tol in ((5, 2e-3), (20, 5e-4)):
        p.reset()
        wave = neutral_input(offset, 1.0, u_range=p.input_range, cycles=cycles)
        y = p.run_open_loop(wave.with_hold())
        assert y[-1] == pytest.approx(m.readout(exact), abs=tol)
    sl = p.slopes()
    ex = m.slopes(exact)
    assert sl.rising == pytest.approx(ex.rising, rel=2e-3)
    assert sl.falling == pytest.approx(ex.falling, rel=2e-3)


def test_branch_inputs_follow_eq_4_3_and_4_4():
    f, ts = 2.0, 1e-3
    a = branch_input("a", 30.0, f, u_range=(-100, 100), sample_time=ts)
    assert len(a.input) == 750
    assert a.input[0] == pytest.approx(-100) and a.input[250] == pytest.approx(100)
    assert a.input[500] == pytest.approx(-100)
    assert np.all(np.diff(a.input[500:]) > 0)  # the last half period rises to u_bar
    assert a.with_hold()[-1] == 30.0 and abs(a.input[-1] - 30.0) < 0.01
    d = branch_input("d", 10.0, f, u_range=(-100, 100), sample_time=ts)
    assert d.input[0] == pytest.approx(100) and d.input[250] == pytest.approx(-100)
    assert d.input[500] == pytest.approx(100)
    assert np.all(np.diff(d.input[500:]) < 0)  # ... falls to u_bar, no jump (see Eq 4.4 note)
    step = 2 * np.pi * f * 100 * ts
    assert np.max(np.abs(np.diff(d.input))) < 1.01 * step
    assert np.max(np.abs(np.diff(a.input))) < 1.01 * step
    small = branch_input("a", 0.0, 1.0, u_range=(-100, 100), u_hat=7.0)
    assert small.input.min() == pytest.approx(-7.0) and small.u_hat == 7.0
    with pytest.raises(ValueError, match="'a' or 'd'"):
        branch_input("n", 0.0, 1.0, u_range=(-100, 100))
    with pytest.raises(ValueError, match="kind"):
        branch_input("x", 0.0, 1.0, u_range=(-100, 100))


def test_landing_windows():
    assert landing_window("a", 1.0) == pytest.approx((0.97, 1.03))
    assert landing_window("psi_d", 1.0, 2.0, thresholds="experiment") == pytest.approx((1.22, 1.28))
    assert landing_window("a", 1.0, 4.0, thresholds="experiment") == pytest.approx((0.56, 0.62))
    assert landing_window("n", 1.0, 4.0, thresholds="experiment") == pytest.approx((0.97, 1.03))
    assert TABLE_4_1[1.0]["a"] == (-0.22, -0.14)
    with pytest.raises(ValueError, match="Table 4.1"):
        landing_window("a", 1.0, 3.0, thresholds="experiment")


# ------------------------------------------------------------------ drive_to_state
@pytest.mark.parametrize("f", [1.0, 2.0, 4.0])
def test_drive_to_state_lands_in_the_window(plants, inits, f):
    p = plants[f]
    m = p.model
    for init in inits[f].values():
        assert init.window == pytest.approx((0.97, 1.03))
        assert 0.97 <= init.y_end <= 1.03
        assert m.readout(init.state) == pytest.approx(init.y_end, abs=1e-12)
        assert init.waveform.sample_time == thesis_sample_time(f)
    # psi_a sits on the ascending, psi_d on the descending major branch
    a, d = inits[f]["a"], inits[f]["d"]
    assert a.y_end == pytest.approx(m.readout(m.state_from_extrema([a.offset])), abs=1e-6)
    assert d.y_end == pytest.approx(
        m.readout(m.state_from_extrema([d.offset], start="positive")), abs=1e-6
    )
    # psi_n from N_inv: the decaying sinusoid lands close to N(l) without correction
    n = inits[f]["n"]
    assert n.offset == n.l_inverse == pytest.approx(neutral_locus(m).inverse(1.0))
    assert d.offset < n.offset < a.offset


def test_drive_to_state_with_experiment_thresholds_and_errors(plants):
    p = plants[2.0]
    init = drive_to_state(p, "a", 1.0, 2.0, thresholds="experiment")
    assert 0.72 <= init.y_end <= 0.78
    with pytest.raises(ValueError, match="cannot reach"):
        drive_to_state(p, "a", 5.0, 2.0)
    with pytest.raises(ValueError, match="outside the range"):
        drive_to_state(p, "n", 5.0, 2.0)
    with pytest.raises(ValueError, match="kind"):
        drive_to_state(p, "q", 1.0, 2.0)
    with pytest.raises(ValueError, match="no model"):
        drive_to_state(LinearPlant(), "n", 1.0, 1.0)


def test_thresholds_default_to_table_4_1_on_a_device_and_to_simulation_on_a_model(
    plants, inits, tmp_path
):
    """§4.2: the simulations land within y_d +/- 0.03 V, the experiments in Table 4.1's windows."""
    model = plants[1.0].model
    dev = daq.DevicePlant(daq.virtual_ss15(model, seed=2), model=model, record_dir=tmp_path)
    assert default_thresholds(dev) == "experiment"
    assert default_thresholds(plants[1.0]) == default_thresholds(LinearPlant()) == "simulation"
    for k in ("a", "d"):
        init = drive_to_state(dev, k, 1.0, 1.0)
        lo, hi = TABLE_4_1[1.0][k]
        assert init.thresholds == "experiment" and init.window == pytest.approx((1 + lo, 1 + hi))
        assert 1 + lo <= init.y_end <= 1 + hi
        assert inits[1.0][k].thresholds == "simulation"
        assert inits[1.0][k].window == pytest.approx((0.97, 1.03))
    # psi_n keeps y_d +/- 0.03 V (reached through the locus) on the device too
    n = drive_to_state(dev, "n", 1.0, 1.0)
    assert n.window == pytest.approx((0.97, 1.03)) and n.hold_ok
    # explicit choices still win, and Table 4.1 has no 3 Hz row: the error says what to do
    sim = drive_to_state(dev, "a", 1.0, 1.0, thresholds="simulation")
    assert sim.thresholds == "simulation" and 0.97 <= sim.y_end <= 1.03
    assert drive_to_state(dev, "a", 1.0, 1.0, window=(0.9, 0.95)).thresholds == "window"
    with pytest.raises(ValueError, match="default on a DAQ device.*thresholds='simulation'"):
        drive_to_state(dev, "a", 1.0, 3.0)


def test_hold_check_of_the_experiments(plants, inits, tmp_path):
    """§4.2: the output must stay within y_d +/- 0.1 V from t_1 to t_1 + 2 s."""
    assert (HOLD_BAND, HOLD_DURATION) == (0.1, 2.0)
    # model plant, simulation window: lands within 0.03 V and stays there
    for init in inits[1.0].values():
        assert init.hold_band == pytest.approx((0.9, 1.1)) and init.hold_ok is True
        assert init.hold_range[0] == pytest.approx(init.y_end, abs=1e-12)
        assert init.to_dict()["hold_ok"] is True
    # the virtual rig has no creep to carry psi_a from Table 4.1's window (0.78..0.86 V) to
    # y_d: the output stays near 0.82 V and the check fails, as it would on such a rig
    model = plants[1.0].model
    dev = daq.DevicePlant(daq.virtual_ss15(model, seed=5), record_dir=tmp_path)
    a = drive_to_state(dev, "a", 1.0, 1.0)
    assert a.hold_ok is False and a.hold_range[1] < 0.9
    n_runs = len(dev.results)
    rec = Recording.load(dev.results[-1].path)  # the final run includes the 2 s hold
    assert len(rec) == len(a.waveform.input) + round(HOLD_DURATION / dev.sample_time) + 1
    with pytest.warns(HoldWindowWarning, match=r"left y_d \+/- 0.1 V"):
        drive_to_state(dev, "a", 1.0, 1.0, hold_check="warn")
    with pytest.raises(HoldWindowError, match="during the 2 s hold"):
        drive_to_state(dev, "a", 1.0, 1.0, hold_check="raise")
    # a wider band accepts it; "off" ends the final run at t_1 and records nothing
    assert drive_to_state(dev, "a", 1.0, 1.0, hold_band=0.25, hold_check="raise").hold_ok
    off = drive_to_state(plants[1.0], "d", 1.0, 1.0, hold_check="off")
    assert off.hold_ok is None and off.hold_range is None and off.y_end == inits[1.0]["d"].y_end
    assert len(dev.results) > n_runs
    # the same on a model plant with an explicit window below the band
    with pytest.raises(HoldWindowError):
        drive_to_state(plants[2.0], "d", 1.0, 2.0, window=(1.15, 1.2), hold_check="raise")
    with pytest.raises(ValueError, match="hold_check"):
        drive_to_state(plants[1.0], "a", 1.0, 1.0, hold_check="maybe")


def test_measured_locus_on_a_plant_without_model(plants):
    rig = RigLike(plants[1.0])
    loc = measure_locus(rig, np.linspace(-60, 60, 13), 1.0, cycles=10)
    assert loc.source == "measured" and loc.monotone
    exact = neutral_locus(plants[1.0].model)
    np.testing.assert_allclose(loc.N, exact(loc.l), atol=2e-3)
    init = drive_to_state(rig, "n", 1.0, 1.0, locus=loc)
    assert init.state is None and 0.97 <= init.y_end <= 1.03


# ------------------------------------------------------------------ metrics and protocols
def test_differential_drift_and_control_effort_definitions():
    ts = 1e-3
    t = np.arange(10000) * ts
    y = np.where(t < 2, 1.0, 1.0 + 0.05 * (t - 2))
    d, yb, ya = differential_drift(y, ts)
    assert yb == pytest.approx(1.0)
    assert ya == pytest.approx(1.0 + 0.05 * 7.0 - 0.05 * ts / 2, abs=1e-9)  # mean of t in [8, 10)
    assert d == pytest.approx(ya - yb)
    uc = np.zeros(12000)
    uc[1500:2000] = 0.2  # baseline ubar_c over [1.5, 2)
    uc[2000:10000] = 0.2 + np.where(np.arange(8000) % 2, 0.1, -0.1)
    nc, ubar = control_effort(uc, ts)
    assert ubar == pytest.approx(0.2)
    assert nc == pytest.approx(0.1 * math.sqrt(8000))
    with pytest.raises(ValueError, match="samples"):
        differential_drift(y[:5000], ts)


def test_protocol_defaults_are_the_thesis_values():
    d, c = DriftProtocol(), ClosedLoopProtocol()
    assert (d.hold, d.noise_duration, d.before, d.after) == (2.0, 8.0, (0.0, 2.0), (8.0, 10.0))
    assert (c.kp, c.ki, c.controller_on, c.noise_start, c.noise_end, c.end) == (
        1.5,
        30.0,
        1,
        2,
        10,
        12,
    )
    assert c.baseline == (1.5, 2.0) and c.effort == (2.0, 10.0)
    assert d.noise.amplitude == 0.5 and d.input_gain == pytest.approx(14.12)
    assert THESIS_GAINS == pytest.approx([0.8 * i for i in range(1, 8)])
    cfg = ClosedLoopProtocol(average_window=0.025).pi_config(1.0, 5e-4)
    assert (cfg.average, cfg.enable_at, cfg.sample_time) == (50, 2000, 5e-4)
    assert thesis_sample_time(4.0) == 5e-4 and thesis_sample_time(1.0) == 1e-3
    with pytest.raises(ValueError, match="after the test"):
        DriftProtocol(after=(8.0, 11.0))
    with pytest.raises(ValueError, match="timing"):
        ClosedLoopProtocol(noise_start=5.0, noise_end=4.0)
    with pytest.raises(ValueError, match="input_gain"):
        DriftProtocol(input_gain=0.0)


def test_trial_noise_is_seeded_scaled_and_shared():
    spec = NoiseSpec()
    a = trial_noise(spec, 1e-3, 8.0, 3)
    b = trial_noise(spec, 1e-3, 8.0, 3)
    assert a is b and not a.flags.writeable and len(a) == 8000
    assert np.max(np.abs(a)) == pytest.approx(0.5)
    assert not np.array_equal(a, trial_noise(spec, 1e-3, 8.0, 4))
    assert len(trial_noise(spec, 5e-4, 8.0, 3)) == 16000
    rows = DriftProtocol().open_inputs(10.0, [1.6, 0.8], [3, 3], 1e-3)
    assert np.all(rows[:, :2000] == 10.0)
    np.testing.assert_allclose(rows[0, 2000:] - 10.0, SS15_INPUT_GAIN * 1.6 * a)
    np.testing.assert_allclose(rows[0, 2000:] - 10.0, 2 * (rows[1, 2000:] - 10.0))
    with pytest.raises(ValueError, match="seed"):
        trial_noise(spec, 1e-3, 8.0, -1)


# ------------------------------------------------------------------ drift test
def test_drift_on_a_linear_plant_is_the_mean_noise():
    """No hysteresis, no drift beyond the noise's own mean: checks the timing of steps 4-6."""
    plant = LinearPlant(k=0.03)
    init = drive_to_state(plant, "a", 1.0, 1.0)
    res = drift_test(plant, init, 2.4, 5)
    eta = trial_noise(NoiseSpec(), 1e-3, 8.0, 5)
    assert res.ybar_before == pytest.approx(0.03 * init.offset)
    assert res.drift == pytest.approx(
        0.03 * SS15_INPUT_GAIN * 2.4 * eta[6000:8000].mean(), abs=1e-12
    )
    assert res.input is not None and len(res.output) == 10000


def test_drift_batch_equals_rig_replay(plants, inits):
    p = plants[1.0]
    init = inits[1.0]["a"]
    fast = drift_trials(p, init, [0.8, 4.0], [1, 2])
    slow = drift_trials(RigLike(p), init, [0.8, 4.0], [1, 2])
    for x, y in zip(fast, slow):
        assert x.drift == pytest.approx(y.drift, abs=1e-12)
        np.testing.assert_allclose(x.output, y.output, atol=1e-12)


def test_device_trials_record_init_and_test_as_one_run(plants, inits, tmp_path):
    """On a DAQ device the initialisation and the test segment are one continuous trial."""
    p = plants[1.0]
    ts = p.sample_time
    init = inits[1.0]["a"]
    n0 = len(init.waveform.input)
    dev = daq.DevicePlant(daq.virtual_ss15(p.model, seed=1), record_dir=tmp_path)
    for run, metric, tol in ((drift_trials, "drift", 1e-3), (closed_loop_trials, "nc", 0.01)):
        ref = run(p, init, [1.6], [0])[0]  # the model, batched from the snapshot at t_1
        before = len(dev.results)
        res = run(dev, init, [1.6], [0])[0]
        assert len(dev.results) == before + 1  # one device run per trial, no gap at t_1
        rec = Recording.load(dev.results[-1].path)
        n = len(res.output)
        assert n == len(ref.output) and len(rec) == n0 + n + 1  # + the clocked loop's extra sample
        np.testing.assert_allclose(np.diff(rec.t), ts, rtol=1e-6)  # contiguous across t_1
        assert rec.t[0] == 0.0 and rec.t[n0] == pytest.approx(n0 * ts)
        # (the first ~10 samples are slew-limited from 0 V to the waveform's -100 V start)
        np.testing.assert_allclose(rec.u[20:n0], init.waveform.input[20:], atol=1e-9)
        np.testing.assert_allclose(rec.u[n0 : n0 + n], res.input, atol=1e-9)
        np.testing.assert_allclose(res.output, rec.y[n0 + 1 : n0 + n + 1])
        # the same physics as the model path, up to the rig's ADC noise and quantisation
        assert getattr(res, metric) == pytest.approx(getattr(ref, metric), rel=tol, abs=tol)
        np.testing.assert_allclose(res.output, ref.output, atol=5e-3)
    # the controller still starts controller_on = 1 s after t_1, not 1 s into the waveform
    assert np.all(res.control[: round(1.0 / ts)] == 0.0) and res.control[round(1.0 / ts)] != 0.0


@pytest.mark.parametrize("f", [1.0, 2.0, 4.0])
def test_drift_findings_of_chapter_4(drift_means, f):
    """Fig 4.12 at every K_n = 0.8 i (i = 1..7), 20-seed means: |drift(psi_n)| is the smallest,
    psi_a drifts up and psi_d down (the thesis's simulation shows this at 1, 2 and 4 Hz)."""
    assert len(THESIS_GAINS) == 7
    for g in THESIS_GAINS:
        m = {k: drift_means[f, k, g] for k in KINDS}
        assert m["a"] > 0 and m["d"] < 0, (f, g, m)
        assert abs(m["n"]) < min(abs(m["a"]), abs(m["d"])), (f, g, m)
    # and the non-neutral drift grows with the gain (§4.3: "in most cases"; here in all)
    for k in ("a", "d"):
        mags = [abs(drift_means[f, k, g]) for g in THESIS_GAINS]
        assert np.all(np.diff(mags) > 0), (f, k, mags)


# ------------------------------------------------------------------ closed loop
def test_core_closed_loop_equals_a_python_loop(plants, inits):
    """The C++ loop against the same loop written with Simulator.step and PIController."""
    p = plants[1.0]
    init = inits[1.0]["d"]
    cfg = ClosedLoopProtocol(average_window=0.005).pi_config(1.0, 1e-3)
    u_open = ClosedLoopProtocol().open_inputs(init.offset, [3.2], [2], 1e-3)[0][:3000]
    sim = p.model.simulator(init.state)
    pi = cfg.controller()
    y_ref, uc_ref, c = [], [], 0.0
    for k, base in enumerate(u_open):
        y = sim.step(base + cfg.input_gain * c)
        c = pi.update(1.0 - y) if k >= cfg.enable_at else (pi.observe(1.0 - y), 0.0)[1]
        y_ref.append(y)
        uc_ref.append(c)
    u, y, uc = _core.closed_loop(p.model.simulator(init.state), u_open, **cfg.core_kwargs())
    np.testing.assert_allclose(y, y_ref, atol=1e-12)
    np.testing.assert_allclose(uc, uc_ref, atol=1e-12)
    assert np.all(uc[:1000] == 0.0) and np.any(uc[1000:] != 0.0)
    np.testing.assert_allclose(u[1:], u_open[1:] + cfg.input_gain * uc[:-1])


def test_closed_loop_regulates_and_batch_equals_rig(plants, inits):
    p = plants[2.0]
    init = inits[2.0]["a"]
    res = closed_loop_test(p, init, 1.6, 0)
    assert abs(res.error_final) < 1e-3  # back at y_d after the noise
    assert res.nc > 0 and res.nc_l2 == pytest.approx(res.nc * math.sqrt(1e-3))
    assert res.error_rms > 0.01  # the noise is not rejected at 15 Hz
    slow = closed_loop_trials(RigLike(p), init, [1.6], [0])[0]
    assert slow.nc == pytest.approx(res.nc, rel=1e-12)
    np.testing.assert_allclose(slow.control, res.control, atol=1e-12)
    fig = res.plot()
    assert [a.get_ylabel() for a in fig.axes] == [
        "output y (V)",
        "controller u_c (DAQ V)",
        "input u (V)",
    ]


def test_closed_loop_on_a_python_plant():
    plant = LinearPlant(k=0.03)
    assert isinstance(plant, Plant)
    init = drive_to_state(plant, "d", 1.0, 1.0)
    res = closed_loop_test(plant, init, 0.8, 1)
    assert abs(res.error_final) < 1e-6
    with pytest.raises(ValueError, match="sample_time"):
        ModelPlant(PreisachModel.builtin("ss15-1hz", 21)).run_closed_loop(
            np.zeros(5), PIConfig(1.0, sample_time=5e-4)
        )


@pytest.mark.parametrize("f", [1.0, 2.0])
def test_effort_findings_of_chapter_5(effort_means, f):
    """Figs 5.5-5.6: n_c(psi_n) below n_c(psi_a) and n_c(psi_d) at every K_n = 0.8 i
    (i = 1..7), 20-seed means, for 1 and 2 Hz initialisation."""
    for g in THESIS_GAINS:
        nc = {k: effort_means[f, k, g] for k in KINDS}
        assert nc["n"] < nc["a"] and nc["n"] < nc["d"], (f, g, nc)


def test_effort_at_4_hz_pins_what_the_simulation_shows(effort_means):
    """At 4 Hz the thesis (Fig 5.7, and on the rig Fig 5.12) finds the advantage of psi_n gone
    for K_n > 4.0.  Our simulation differs: n_c(psi_n) stays the smallest at all seven gains,
    by a steady margin (psi_a 30-39 %, psi_d 12-18 % more effort).  That is plausible: the
    thesis's 4 Hz result is measured on the rig, whose hysteresis is rate dependent (the major
    loop widens with frequency, §4.3, and needed a model per frequency), while a Preisach model
    has no rate effects - a state is a state however fast it was reached.  This test pins the
    simulation's behaviour so that a change to it is noticed; it does not claim the thesis's
    experiment."""
    for g in THESIS_GAINS:
        nc = {k: effort_means[4.0, k, g] for k in KINDS}
        assert nc["n"] < nc["d"] < nc["a"], (g, nc)
        assert 1.2 < nc["a"] / nc["n"] < 1.45, (g, nc)
        assert 1.05 < nc["d"] / nc["n"] < 1.25, (g, nc)
    # n_c grows about linearly with the gain (the noise dominates the controller's work)
    n = np.array([effort_means[4.0, "n", g] for g in THESIS_GAINS])
    np.testing.assert_allclose(n / np.asarray(THESIS_GAINS), n[0] / THESIS_GAINS[0], rtol=0.05)


# ------------------------------------------------------------------ slopes (Appendix A)
def test_slopes_explain_the_drift(plants, inits):
    for f in (1.0, 2.0, 4.0):
        m = plants[f].model
        amp = 0.5 * SS15_INPUT_GAIN * 1.6
        sa = state_slopes(m, inits[f]["a"].state, amp)
        sd = state_slopes(m, inits[f]["d"].state, amp)
        sn = state_slopes(m, inits[f]["n"].state, amp)
        assert sa["dy_du_rising"] > 1.15 * sa["dy_du_falling"]
        assert sd["dy_du_falling"] > 1.1 * sd["dy_du_rising"]
        assert sn["dy_du_rising"] == pytest.approx(sn["dy_du_falling"], rel=2e-3)
        # one excursion up and back from psi_a leaves the output higher, down and back leaves it
        assert sa["residual_up"] > 0 and sa["residual_down"] == pytest.approx(0.0, abs=1e-12)
        assert sd["residual_down"] < 0 and sd["residual_up"] == pytest.approx(0.0, abs=1e-12)
        # from psi_n the two nearly cancel
        assert abs(sn["residual_up"] + sn["residual_down"]) < 0.2 * sa["residual_up"]


# ------------------------------------------------------------------ sweeps
def test_sweep_table_figures_and_json(tmp_path):
    res = regulation_sweep("closed-loop", seeds=range(3), gains=[0.8, 2.4], trace=(0.8, 1))
    assert len(res.rows) == 3 * 3 * 2 * 3
    rec = res.to_records()
    assert set(rec[0]) >= {"frequency", "state", "gain", "seed", "nc", "nc_l2", "offset"}
    text = res.to_csv(tmp_path / "t.csv")
    back = list(csv.DictReader(io.StringIO(text)))
    assert len(back) == len(rec) and float(back[5]["nc"]) == rec[5]["nc"]
    summ = res.summary()
    cell = next(s for s in summ if s["frequency"] == 2.0 and s["state"] == "a" and s["gain"] == 2.4)
    v = res.values(2.0, "a", 2.4)
    assert cell["mean"] == pytest.approx(v.mean()) and cell["std"] == pytest.approx(v.std(ddof=1))
    pct = res.percentage_table()
    row = pct[1]
    assert row["normalised_gain"] == pytest.approx(1.0)
    n1, a1 = res.values(1.0, "n", 2.4).mean(), res.values(1.0, "a", 2.4).mean()
    assert row["a_1"] == pytest.approx(100 * (a1 - n1) / n1)
    comp = res.comparisons()
    assert len(comp) == 6 and all(0 <= c["frac_n_below_a"] <= 1 for c in comp)
    assert set(res.traces) == {(f, k) for f in (1.0, 2.0, 4.0) for k in KINDS}
    assert all(t.seed == 1 and t.gain == 0.8 for t in res.traces.values())
    json.dumps(res.to_dict(), allow_nan=False)
    assert [len(st) for st in (res.states,)] == [9]
    assert {"dy_du_rising", "dy_du_falling", "secant_rising", "residual_up"} <= set(res.states[0])
    for fig in (res.plot(), res.plot_differences(), res.plot_traces(), res.plot_initial_states()):
        assert all(ax.get_xlabel() for ax in fig.axes[-1:])
    assert res.plot().axes[0].get_ylabel() == "control effort n_c (DAQ V)"
    assert "K_n/max" in res.format_percentage_table()
    with pytest.raises(ValueError, match="closed-loop"):
        regulation_sweep("drift", seeds=[0], gains=[0.8], states=["n"]).percentage_table()


def test_sweep_accepts_models_and_rejects_bad_arguments():
    m = PreisachModel.builtin("ss15-1hz", 101)
    res = regulation_sweep(
        "drift", {1.0: m}, states=["a", "d"], seeds=[0, 1], gains=[1.6], trace=None
    )
    assert {r["state"] for r in res.rows} == {"a", "d"} and res.comparisons() == []
    assert res.rows[0]["drift"] > 0
    with pytest.raises(ValueError, match="experiment"):
        regulation_sweep("open-loop")
    with pytest.raises(TypeError, match="DriftProtocol"):
        regulation_sweep("drift", {1.0: m}, protocol=ClosedLoopProtocol())
    with pytest.raises(ValueError, match="states"):
        regulation_sweep("drift", {1.0: m}, states=["x"])
    with pytest.raises(TypeError, match="plants"):
        regulation_sweep("drift", {1.0: "ss15"})
