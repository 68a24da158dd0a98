"""The rate-dependent model: reduction to the classical model, the ss15-rate built-in on
triangle sweeps, persistence, batches, and the experiments running on it as a plant."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from preisach import PreisachModel, State
from preisach.experiments import PIConfig, closed_loop_trials, drive_to_state
from preisach.experiments.closed_loop import ClosedLoopProtocol
from preisach.experiments.rate_plant import RatePlant
from preisach.rate_model import (
    RateDependentPreisachModel,
    RateState,
    triangle_rate,
)


@pytest.fixture(scope="module")
def ss15_rate() -> RateDependentPreisachModel:
    return RateDependentPreisachModel.builtin("ss15-rate", levels=101)


def fod_triangle(alphas, rate: float, dt: float, lo: float = -100.0) -> np.ndarray:
    """FOD sweep at a constant |du/dt|: from lo up to each alpha and back to lo."""
    h = rate * dt
    parts = []
    for a in alphas:
        n = int(round((a - lo) / h))
        up = lo + h * np.arange(1, n + 1)
        parts += [up, up[::-1][1:], [lo]]
    return np.concatenate(parts)


def test_one_table_is_the_classical_model_bit_for_bit() -> None:
    base = PreisachModel.builtin("ss15-2hz", 61)
    rm = RateDependentPreisachModel.from_models([base], [800.0], 0.05)
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(0, 4, 4000)).clip(-100, 100)
    s0 = base.neutral_state(13.0)
    a = rm.simulate(u, RateState(s0, 321.0))
    b = base.simulate(u, s0)
    assert np.array_equal(a.output, b.output)
    assert a.final_state == b.final_state


@pytest.mark.parametrize("freq", [1, 2, 4])
def test_ss15_rate_reduces_to_each_table_on_its_triangle_sweep(ss15_rate, freq) -> None:
    classical = PreisachModel.builtin(f"ss15-{freq}hz", 101)
    rate = triangle_rate(freq)  # 4 * 100 V * f
    assert rate == 400.0 * freq
    dt = 1e-3 if freq < 4 else 5e-4  # the thesis's sample times
    u = fod_triangle(np.linspace(-60, 100, 9), rate, dt)
    s0 = classical.negative_saturation()
    got = ss15_rate.simulate(u, RateState(s0, rate), sample_time=dt)
    ref = classical.simulate(u, s0)
    assert np.max(np.abs(got.output - ref.output)) < 1e-9
    # the other tables differ visibly on the same sweep
    other = PreisachModel.builtin("ss15-1hz" if freq != 1 else "ss15-4hz", 101).simulate(u, s0)
    assert np.max(np.abs(other.output - ref.output)) > 0.05
    # from rest, the filter reaches the sweep's rate and then the outputs agree too
    u3 = np.tile(u, 3)  # long enough for the filter to settle (8 tau)
    cold = ss15_rate.simulate(u3, RateState(s0, 0.0), sample_time=dt)
    ref3 = classical.simulate(u3, s0)
    settle = int(8 * ss15_rate.tau / dt)
    assert settle < u3.size // 2
    assert np.max(np.abs(cold.output[settle:] - ref3.output[settle:])) < 1e-4  # e^-8 of the gap


def test_constant_rate_between_knots_is_the_blended_model(ss15_rate) -> None:
    rate = 400.0 * 2**0.5  # halfway between 1 and 2 Hz in ln(rate)
    w = ss15_rate.weights(rate)
    assert w == pytest.approx([0.5, 0.5, 0.0])
    blend = ss15_rate.at_rate(rate)
    u = fod_triangle([20.0, 99.0], rate, 1e-3)  # no clamped step: the rate stays constant
    s0 = blend.negative_saturation()
    got = ss15_rate.simulate(u, RateState(s0, rate)).output
    assert np.max(np.abs(got - blend.simulate(u, s0).output)) < 1e-9


def test_held_input_relaxes_to_the_slowest_table(ss15_rate) -> None:
    u = np.concatenate([fod_triangle([50.0], 1600.0, 5e-4), np.full(8000, -100.0), [30.0] * 8000])
    res = ss15_rate.simulate(u, ss15_rate.negative_saturation(1600.0), sample_time=5e-4)
    assert res.rate[-1] < 1e-3 * 1600
    slow = PreisachModel(ss15_rate.table)
    assert res.output[-1] == pytest.approx(slow.readout(res.final_state), abs=1e-9)
    assert ss15_rate.readout(res.final_rate_state) == pytest.approx(res.output[-1], abs=1e-9)


def test_batch_equals_single_runs(ss15_rate) -> None:
    rng = np.random.default_rng(4)
    u = np.cumsum(rng.normal(0, 2, (4, 1500)), axis=1).clip(-100, 100)
    states = [ss15_rate.neutral_state(x, r) for x, r in [(0, 0), (10, 500), (-20, 900), (5, 3000)]]
    y, finals = ss15_rate.simulate_batch(u, states, threads=2)
    for r in range(4):
        one = ss15_rate.simulate(u[r], states[r])
        assert np.array_equal(y[r], one.output)
        assert finals[r] == one.final_rate_state


def test_save_load_round_trip_and_errors(ss15_rate, tmp_path) -> None:
    p = tmp_path / "rate.npz"
    ss15_rate.save(p)
    back = RateDependentPreisachModel.load(p)
    assert back == ss15_rate
    assert back.name == "ss15-rate" and back.tau == ss15_rate.tau
    assert [f.name for f in tmp_path.iterdir()] == ["rate.npz"]  # no temporary file left
    assert pickle.loads(pickle.dumps(ss15_rate)) == ss15_rate
    PreisachModel.builtin("ss15-1hz", 11).save(tmp_path / "classical.npz")
    with pytest.raises(ValueError, match="not a rate-dependent"):
        RateDependentPreisachModel.load(tmp_path / "classical.npz")
    (tmp_path / "bad.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match="bad.npz"):
        RateDependentPreisachModel.load(tmp_path / "bad.npz")
    data = dict(np.load(p))
    data["version"] = np.array(99)
    np.savez(tmp_path / "new.npz", **data)
    with pytest.raises(ValueError, match="newer"):
        RateDependentPreisachModel.load(tmp_path / "new.npz")
    ss15_rate.metadata["bad"] = object()
    try:
        with pytest.raises(TypeError, match="JSON"):
            ss15_rate.save(tmp_path / "x.npz")
    finally:
        del ss15_rate.metadata["bad"]
    assert not (tmp_path / "x.npz").exists()


def test_validation(ss15_rate) -> None:
    with pytest.raises(ValueError, match="rate"):
        RateState(ss15_rate.anhysteretic_state().boundary, -1.0)
    with pytest.raises(ValueError, match="uniformly"):
        ss15_rate.simulate([0.0, 1.0, 2.0], t=[0.0, 1e-3, 3e-3])
    with pytest.raises(ValueError, match="knots"):
        RateDependentPreisachModel.from_models(
            [PreisachModel.builtin("ss15-1hz", 11)] * 2, [800.0, 400.0], 0.1
        )
    with pytest.raises(ValueError, match="outside"):
        ss15_rate.simulate([150.0], out_of_range="raise")
    with pytest.raises(ValueError, match="unknown"):
        RateDependentPreisachModel.builtin("ss15-9hz")


def test_plant_runs_the_regulation_experiment(ss15_rate) -> None:
    plant = RatePlant(ss15_rate, 1e-3, threads=2)
    init = drive_to_state(plant, "n", 1.0, 2.0)
    assert isinstance(init.state, RateState)
    assert abs(init.y_end - 1.0) <= 0.03
    # snapshots restore exactly
    plant.reset(init.state)
    y1 = plant.run_open_loop(np.full(50, init.offset))
    plant.reset(init.state)
    assert np.array_equal(plant.run_open_loop(np.full(50, init.offset)), y1)
    proto = ClosedLoopProtocol()
    batch = closed_loop_trials(plant, init, [1.6, 3.2], [0, 1], proto)
    assert all(r.nc > 0 for r in batch)

    # the sequential path (reset + waveform + loop in one run) gives the same efforts
    class NoBatch:
        def __init__(self, p: RatePlant) -> None:
            self._p = p
            self.sample_time, self.input_range = p.sample_time, p.input_range

        def reset(self, state: State | None = None) -> None:
            self._p.reset(state)

        def run_open_loop(self, u):
            return self._p.run_open_loop(u)

        def run_closed_loop(self, u, c: PIConfig):
            return self._p.run_closed_loop(u, c)

        def snapshot(self) -> None:
            return None

    seq = closed_loop_trials(NoBatch(plant), init, [1.6, 3.2], [0, 1], proto)
    for a, b in zip(batch, seq):
        assert a.nc == pytest.approx(b.nc, rel=1e-9)


def test_rate_plots_and_loop_width(ss15_rate) -> None:
    from preisach import Recording
    from preisach.plotting import plot_everett_across_rates, plot_loop_width, plot_rate_loops
    from preisach.plotting.rate import _triangle, loop_width

    # the width measured from a simulated 2 Hz triangle is the 2 Hz classical model's
    dt = 5e-4
    u = _triangle(2.0, 100.0, dt)
    classical = PreisachModel.builtin("ss15-2hz", 101)
    y = classical.simulate(u, classical.negative_saturation()).output
    got = ss15_rate.simulate(u, ss15_rate.negative_saturation(800.0), sample_time=dt).output
    assert loop_width(u, got) == pytest.approx(loop_width(u, y), abs=1e-9)
    assert loop_width(u, y) > 0.1
    rec = Recording.from_arrays(u=u, y=y, sample_time=dt, experiment="2 Hz")
    for fig in (
        plot_rate_loops(ss15_rate, (1.0, 4.0)),
        plot_everett_across_rates(ss15_rate),
        plot_loop_width(ss15_rate, [rec], rates=[200.0, 800.0, 3200.0]),
    ):
        assert fig.axes


def test_linear_scale_weights_persistence_and_old_files(tmp_path) -> None:
    m1, m2 = PreisachModel.builtin("ss15-1hz", 21), PreisachModel.builtin("ss15-4hz", 21)
    lin = RateDependentPreisachModel.from_models([m1, m2], [400.0, 1600.0], 0.1, scale="linear")
    log = RateDependentPreisachModel.from_models([m1, m2], [400.0, 1600.0], 0.1)
    assert lin.scale == "linear" and log.scale == "log"
    assert lin.weights(800.0) == pytest.approx([2 / 3, 1 / 3])  # 1/3 of the way in v
    assert log.weights(800.0) == pytest.approx([0.5, 0.5])  # halfway in ln v
    assert lin != log
    lin.save(tmp_path / "lin.npz")
    back = RateDependentPreisachModel.load(tmp_path / "lin.npz")
    assert back == lin and back.scale == "linear"
    assert int(np.load(tmp_path / "lin.npz")["version"]) == 2
    assert pickle.loads(pickle.dumps(lin)) == lin
    # a log-scale model is written as version 1, without the field, as before
    log.save(tmp_path / "log.npz")
    data = np.load(tmp_path / "log.npz")
    assert int(data["version"]) == 1 and "scale" not in data.files
    assert RateDependentPreisachModel.load(tmp_path / "log.npz") == log
    with pytest.raises(ValueError, match="scale"):
        RateDependentPreisachModel.from_models([m1, m2], [400.0, 1600.0], 0.1, scale="ln")


def test_plant_with_physics_blocks_is_the_chain(ss15_rate) -> None:
    from preisach import _core

    dt = 1e-3
    lag = {"kind": "input_lag", "time_constant": 2e-3}
    creep = {"kind": "creep", "rate": 0.01, "tau_min": 0.1, "tau_max": 100.0}
    plant = RatePlant(ss15_rate, dt, input_blocks=[lag], output_blocks=[creep])
    assert plant.has_blocks
    rng = np.random.default_rng(5)
    u = np.cumsum(rng.normal(0, 3, 3000)).clip(-100, 100)
    s0 = ss15_rate.anhysteretic_state()
    plant.reset(s0)
    y = plant.run_open_loop(u)
    # the same as lag -> rate model -> creep, run one after the other
    b_lag = _core.InputLag(dt, 2e-3)
    b_lag.reset(s0.input)
    ui = b_lag.run(u)
    ym = ss15_rate.simulate(ui, s0, sample_time=dt).output
    b_creep = _core.Creep(dt, 0.01, 0.1, 100.0)
    b_creep.reset(ss15_rate.readout(s0))
    assert np.allclose(y, b_creep.run(ym), rtol=0, atol=1e-12)
    # the blocks change the output: not the bare model
    assert np.max(np.abs(y - ss15_rate.simulate(u, s0, sample_time=dt).output)) > 1e-3
    # snapshots restore exactly, the PI loop too
    snap = plant.snapshot()
    cfg = PIConfig(setpoint=1.0, kp=0.1, ki=3.0, sample_time=dt, input_gain=14.12)
    a = plant.run_closed_loop(np.full(400, 10.0), cfg)
    plant.reset(snap)
    b = plant.run_closed_loop(np.full(400, 10.0), cfg)
    for x, z in zip(a, b):
        assert np.array_equal(x, z)
    rows = np.full((2, 400), 10.0)
    rows[1] += 1.0
    batch = plant.run_closed_loop_batch(snap, rows, cfg)
    assert np.array_equal(batch[1][0], a[1])
    with pytest.raises(ValueError, match="clamp"):
        RatePlant(ss15_rate, dt, output_blocks=[creep], out_of_range="raise")
    with pytest.raises(ValueError, match="physics blocks"):
        plant.slopes()
    # plants pickle (studies ship them to worker processes)
    bare = RatePlant(ss15_rate, dt)
    bare.run_open_loop(u[:500])
    back = pickle.loads(pickle.dumps(bare))
    assert back.snapshot() == bare.snapshot()
    assert np.allclose(back.run_open_loop(u[500:900]), bare.run_open_loop(u[500:900]), atol=1e-12)
    back = pickle.loads(pickle.dumps(plant))
    assert back.has_blocks and back.snapshot().chain.kinds == plant.snapshot().chain.kinds
    # the experiments run on it
    init = drive_to_state(plant, "n", 1.0, 1.0)
    assert abs(init.y_end - 1.0) <= 0.03
