"""The DAQ layer: virtual SS15 rig, trial runner, safety, interrupts, Comedi (replayed)."""

import _thread
import math
import signal
import threading
import time

import numpy as np
import pytest
from preisach import PreisachModel, Recording, _core, daq
from preisach.daq.calibration import SS15_CHANNEL_B
from preisach.errors import DeviceError, StopSignal, TrialInterrupted

TS = 1e-3


@pytest.fixture(scope="module")
def model():
    return PreisachModel.builtin("ss15-1hz", levels=101)


def sweep(n=3000, amp=90.0, cycles=3):
    return amp * np.sin(2 * np.pi * cycles * np.arange(n) / n)


def test_virtual_rig_applies_eq_b1b_and_one_sample_causality(model, tmp_path):
    rig = daq.virtual_ss15(model, model.anhysteretic_state(), adc_noise=0.0, adc_bits=24)
    u = sweep()
    res = daq.run_trial(rig, u, tmp_path / "r.csv", sample_time=TS)
    assert res.complete and res.samples == u.size and not res.realtime
    rec = Recording.load(tmp_path / "r.csv")
    assert rec.metadata["end_status"] == "complete"
    assert rec.column_names == ("t", "u", "y", "u_cmd", "u_dac", "y_adc", "lateness")
    np.testing.assert_array_equal(rec.t, np.arange(u.size) * TS)
    # the output channel is Eq B.1b: the DAC gets its inverse, the rig's amplifier applies it
    assert rec.metadata["output_gain"] == SS15_CHANNEL_B.gain == -14.12
    assert rec.metadata["output_offset"] == SS15_CHANNEL_B.offset == -0.02
    np.testing.assert_allclose(
        rec.u_dac if hasattr(rec, "u_dac") else rec.columns["u_dac"],
        SS15_CHANNEL_B.inverse(u),
        rtol=1e-12,
    )
    np.testing.assert_allclose(rec.u, u, rtol=1e-12, atol=1e-12)
    assert rig.actuator_voltage == pytest.approx(u[-1])
    # y[k] is read before u[k] is written: it is the model's response to u[..k-1]
    y_model = model.simulate(u, state=model.anhysteretic_state()).output
    np.testing.assert_allclose(rec.y[1:], y_model[:-1], atol=1e-6)
    assert rec.y[0] == pytest.approx(model.readout(model.anhysteretic_state()), abs=1e-6)


def test_adc_is_quantised_noisy_and_seeded(model, tmp_path):
    u = sweep(1000)
    recs = []
    for i, seed in enumerate((5, 5, 6)):
        rig = daq.virtual_ss15(model, seed=seed)  # 14 bit over +/-5 V, 0.5 mV rms
        daq.run_trial(rig, u, tmp_path / f"{i}.csv", sample_time=TS)
        recs.append(Recording.load(tmp_path / f"{i}.csv"))
    lsb = 10.0 / 2**14
    codes = (recs[0].y + 5.0) / lsb
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)
    np.testing.assert_array_equal(recs[0].y, recs[1].y)
    assert not np.array_equal(recs[0].y, recs[2].y)
    noise = recs[0].y - recs[2].y
    assert 0.4e-3 < np.std(noise) / np.sqrt(2) < 0.8e-3


def test_safety_clamp_slew_and_ramp_after_abort(model, tmp_path):
    rig = daq.virtual_ss15(model)
    # a 300 V step (clamped to 135 V and slew limited), then NaN at sample 150
    ctl = daq.CallbackController(lambda k, t, y: float("nan") if k == 150 else 300.0, 400)
    safety = daq.SafetyLimits(slew_rate=20_000.0, ramp_rate=10_000.0)  # 20 and 10 V a sample
    res = daq.run_trial(rig, ctl, tmp_path / "s.csv", sample_time=TS, safety=safety)
    assert res.end_status.startswith(
        "aborted: controller returned a non-finite output at sample 150"
    )
    assert res.final_output == 0.0 and rig.actuator_voltage == pytest.approx(0.0, abs=1e-12)
    rec = Recording.load(tmp_path / "s.csv")
    assert len(rec) == res.samples + res.ramp_samples == 151 + 14  # 135 V at 10 V a sample
    # from the rig's idle output (0 V at the DAC: -0.02 V) at the slew rate, then the clamp
    np.testing.assert_allclose(rec.u[:7], [*(-0.02 + 20.0 * np.arange(1, 7)), 135.0])
    assert np.all(np.abs(np.diff(rec.u[:151])) <= 20.0 + 1e-9)
    # the ramp to 0 V at the ramp rate, slower than the slew rate
    np.testing.assert_allclose(rec.u[150:], [*(135.0 - 10.0 * np.arange(14)), 0.0])
    assert rec.u.max() == pytest.approx(135.0) and rec.u[-1] == 0.0
    assert rec.metadata["end_reason"].startswith("controller returned a non-finite output")
    np.testing.assert_allclose(np.diff(rec.t), TS)


def test_ramp_faster_than_the_slew_limit_is_rejected():
    msg = r"^safety: ramp_rate = 20000.* V/s exceeds slew_rate = 10000.* V/s"
    with pytest.raises(ValueError, match=msg):
        daq.SafetyLimits(slew_rate=10_000.0, ramp_rate=20_000.0)
    daq.SafetyLimits(slew_rate=10_000.0, ramp_rate=10_000.0)  # equal is fine


def test_out_of_range_reading_aborts(model, tmp_path):
    rig = daq.virtual_ss15(model)
    res = daq.run_trial(
        rig,
        np.full(2000, 100.0),
        tmp_path / "y.csv",
        sample_time=TS,
        safety=daq.SafetyLimits(y_max=2.0),
    )
    assert "outside the safety limits [-inf, 2] V at sample" in res.end_status
    rec = Recording.load(tmp_path / "y.csv")
    assert rec.y[res.samples - 1] > 2.0 and res.samples < 2000
    # the ADC saturating (a reading at the end of its range) reads NaN and aborts too
    rig2 = daq.virtual_ss15(model, input=daq.channel("V_out", 1, (-1.0, 1.0)))
    res2 = daq.run_trial(rig2, np.full(2000, 100.0), tmp_path / "sat.csv", sample_time=TS)
    assert "read NaN (converter out of range [-1, 1] V)" in res2.end_status
    assert res2.dropped >= 1
    Recording.load(tmp_path / "sat.csv")


def test_callback_exception_is_reraised_after_the_file_is_finished(model, tmp_path):
    rig = daq.virtual_ss15(model)

    def ctl(k, t, y):
        if k == 40:
            raise KeyError("no such setpoint")
        return 20.0

    with pytest.raises(KeyError, match="no such setpoint"):
        daq.run_trial(rig, daq.CallbackController(ctl, 100), tmp_path / "e.csv", sample_time=TS)
    rec = Recording.load(tmp_path / "e.csv")
    status = rec.metadata["end_status"]
    assert status.startswith("aborted: controller raised at sample 40: KeyError")
    assert len(rec) >= 41 and rec.u[-1] == 0.0
    assert not rig.busy


@pytest.fixture
def sigint_raises():
    """Python's Ctrl-C handler, also where SIGINT is inherited ignored (a shell's background job:
    there ``interrupt_main`` is silently dropped)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_keyboard_interrupt_requests_a_stop_and_finishes_the_file(model, tmp_path, sigint_raises):
    rig = daq.virtual_ss15(model)
    calls = []

    def ctl(k, t, y):
        calls.append(k)
        if k == 300:
            _thread.interrupt_main()  # Ctrl-C arrives in the main thread, which waits
        return 30.0

    with pytest.raises(TrialInterrupted) as info:
        daq.run_trial(
            rig, daq.CallbackController(ctl, 10**7), tmp_path / "i.csv", sample_time=TS, poll=0.01
        )
    res = info.value.result
    assert res.end_status == "interrupted" and 300 < res.samples < 10**7
    rec = Recording.load(tmp_path / "i.csv")
    assert rec.metadata["end_status"] == "interrupted"
    assert len(rec) == res.samples + res.ramp_samples
    np.testing.assert_array_equal(rec.t, np.arange(len(rec)) * TS)
    assert rec.u[-1] == 0.0


def test_a_ctrl_c_at_the_first_sample_still_finishes_the_file(model, tmp_path, sigint_raises):
    """Ctrl-C from the first callback, while ``Thread.start`` may still wait for the worker.

    The worker used to begin the trial at once, so an interrupt that reached the calling thread
    before it entered its ``try`` escaped with the output live (a fresh CI run under load
    aborted so).  Fails when that window opens again: the interrupt then escapes as a bare
    ``KeyboardInterrupt`` instead of :class:`TrialInterrupted` with a complete file.
    """
    for k in range(20):
        rig = daq.virtual_ss15(model)

        def ctl(i, t, y):
            if i == 0:
                _thread.interrupt_main()
            return 30.0

        path = tmp_path / f"first{k}.csv"
        with pytest.raises(TrialInterrupted) as info:
            daq.run_trial(rig, daq.CallbackController(ctl, 10**6), path, sample_time=TS, poll=0.01)
        res = info.value.result
        assert res.end_status == "interrupted", res
        rec = Recording.load(path)
        assert len(rec) == res.samples + res.ramp_samples and rec.u[-1] == 0.0


@pytest.mark.parametrize("started", [True, False])
@pytest.mark.parametrize("sigterm", [False, True])
def test_a_ctrl_c_while_the_worker_starts_drives_nothing_and_leaves_no_thread(
    model, tmp_path, monkeypatch, started, sigterm
):
    """Ctrl-C or SIGTERM inside ``Thread.start`` (after the thread began, or before).

    ``start`` once ran before the runner's ``try``: an interrupt there escaped and left the
    worker waiting for its go-ahead forever.  Fails if the worker survives, if a sample was
    driven or written, or if a SIGTERM loses its name (the command's exit code).
    """

    class Interrupted(threading.Thread):
        def start(self) -> None:
            if started:
                super().start()
            raise StopSignal(signal.SIGTERM) if sigterm else KeyboardInterrupt

    monkeypatch.setattr(daq.runner.threading, "Thread", Interrupted)
    rig = daq.virtual_ss15(model)
    path = tmp_path / "never.csv"
    with pytest.raises(StopSignal if sigterm else KeyboardInterrupt) as info:
        daq.run_trial(rig, np.full(100, 30.0), path, sample_time=TS)
    assert str(info.value) == (
        "stopped by SIGTERM" if sigterm else "interrupted before the trial began"
    )
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and any(
        t.name == "preisach-trial" for t in threading.enumerate()
    ):
        time.sleep(0.01)
    assert not any(t.name == "preisach-trial" for t in threading.enumerate())
    assert not path.exists()


def test_progress_callback_error_stops_the_worker_and_finishes_the_file(model, tmp_path):
    rig = daq.virtual_ss15(model)
    seen = []

    def progress(done, planned):
        seen.append(done)
        if done >= 100:
            raise RuntimeError("progress display broke")

    path = tmp_path / "p.csv"
    n = 20_000  # 20 s in real time: the error must stop it long before
    with pytest.raises(RuntimeError, match="progress display broke"):
        daq.run_trial(
            rig,
            np.full(n, 30.0),
            path,
            sample_time=TS,
            realtime=True,
            safety=daq.SafetyLimits(max_consecutive_missed=-1),  # a shared machine
            progress=progress,
            poll=0.01,
        )
    # returned only once the worker finished: the output is at 0 V and the file complete
    assert not rig.busy and rig.actuator_voltage == pytest.approx(0.0, abs=1e-12)
    rec = Recording.load(path)
    assert rec.metadata["end_status"] == "interrupted"
    assert "RuntimeError" in rec.metadata["end_reason"]
    assert "progress display broke" in rec.metadata["end_reason"]
    samples, ramp = rec.metadata["samples"], rec.metadata["ramp_samples"]
    assert seen[-1] <= samples < n and ramp == 60  # 30 V at 500 V/s, 0.5 V a sample
    assert len(rec) == samples + ramp  # every sample taken is in the file
    np.testing.assert_allclose(rec.t, np.arange(len(rec)) * TS, atol=1e-12)
    np.testing.assert_allclose(rec.u[5:samples], 30.0)
    assert rec.u[-1] == 0.0 and rec.metadata["final_output"] == 0.0


def test_total_missed_deadline_budget_aborts(model, tmp_path):
    rig = daq.virtual_ss15(model)

    def slow(k, t, y):
        if k % 50 == 25:
            time.sleep(4e-3)  # 4 sample periods late: a few deadlines missed in a row
        return 10.0

    safety = daq.SafetyLimits(max_missed_deadlines=5, max_consecutive_missed=-1)
    res = daq.run_trial(
        rig,
        daq.CallbackController(slow, 5000),
        tmp_path / "m.csv",
        sample_time=TS,
        realtime=True,
        safety=safety,
    )
    assert res.end_status.startswith("aborted: 6 missed deadlines exceed the budget of 5")
    assert res.reason.startswith("6 missed deadlines exceed the budget of 5 (last at sample")
    assert res.missed_deadlines == 6 and res.samples < 5000
    assert res.final_output == 0.0
    rec = Recording.load(tmp_path / "m.csv")
    assert rec.metadata["end_reason"] == res.reason
    assert rec.metadata["missed_deadlines"] == 6


def test_pi_controller_regulates_the_rig(model, tmp_path):
    rig = daq.virtual_ss15(model, seed=1)
    ff = np.full(4000, 20.0)
    pi = daq.PIController(
        kp=1.5 * 14.12,
        ki=30 * 14.12,
        setpoint=1.0,
        sample_time=TS,
        feedforward=ff,
        enable_at=1000,
        average=25,
    )
    res = daq.run_trial(rig, pi, tmp_path / "pi.csv", sample_time=TS)
    rec = Recording.load(tmp_path / "pi.csv")
    assert res.complete
    assert abs(rec.y[:1000].mean() - 1.0) > 0.05  # open loop: not at the setpoint
    assert rec.y[-500:].mean() == pytest.approx(1.0, abs=0.005)
    assert abs(pi.error) < 0.01


def test_realtime_pacing_reports_lateness(model, tmp_path):
    rig = daq.virtual_ss15(model)
    res = daq.run_trial(
        rig,
        np.zeros(200),
        tmp_path / "rt.csv",
        sample_time=TS,
        realtime=True,
        safety=daq.SafetyLimits(max_consecutive_missed=-1),
    )
    rec = Recording.load(tmp_path / "rt.csv")
    assert res.realtime and rec.metadata["realtime"] == 1
    assert res.elapsed >= 0.19  # paced: 200 samples take at least 199 periods
    late = rec.columns["lateness"]
    assert np.all(late >= 0) and res.max_lateness == late.max()
    assert res.missed_deadlines == rec.metadata["missed_deadlines"]


def test_files_are_never_clobbered_and_metadata_is_checked(model, tmp_path):
    rig = daq.virtual_ss15(model)
    p = tmp_path / "x.csv"
    daq.run_trial(rig, np.zeros(10), p, sample_time=TS, metadata={"experiment": "a", "n": 3})
    with pytest.raises(FileExistsError):
        daq.run_trial(rig, np.zeros(10), p, sample_time=TS)
    daq.run_trial(rig, np.zeros(5), p, sample_time=TS, overwrite=True)
    assert len(Recording.load(p)) == 5
    with pytest.raises(ValueError, match="reserved"):
        daq.run_trial(
            rig, np.zeros(5), tmp_path / "z.csv", sample_time=TS, metadata={"end_status": "x"}
        )
    with pytest.raises(ValueError, match="built for a sample time of 0.001"):
        daq.run_trial(rig, np.zeros(5), tmp_path / "w.csv", sample_time=2e-3)


def test_rig_state_and_reset(model):
    rig = daq.virtual_ss15(model, "negative_saturation", adc_noise=0.0)
    assert rig.state == model.negative_saturation()
    assert rig.plant_output == pytest.approx(model.y_min)
    rig.reset(model.positive_saturation())
    assert rig.plant_output == pytest.approx(model.y_max)
    assert rig.simulated and "virtual SS15" in rig.description


COMEDI_SETUP = """
    open /dev/comedi0 -> 1
    board_name -> pci-multiq
    find_subdevice_by_type 2 0 -> 1
    get_n_channels 1 -> 4
    find_range 1 1 -10 10 -> 0
    get_maxdata 1 1 -> 4095
    get_subdevice_flags 1 -> 0
    hardcal_converter 1 1 0 from -> 0 : 1 -10 0 204.75
    find_subdevice_by_type 1 0 -> 0
    get_n_channels 0 -> 8
    find_range 0 1 -5 5 -> 0
    get_maxdata 0 1 -> 8191
    get_subdevice_flags 0 -> 0
    hardcal_converter 0 1 0 to -> 0 : 1 0 -5 0.001220703125
"""
COMEDI_PROTOCOL = (
    COMEDI_SETUP
    + """
    # sample 0: read 1 V, write u = 10 V at the actuator
    data_read 0 1 0 0 -> 0 4915
    data_write 1 1 0 0 {code0} -> 0
    # sample 1: read, write u = 20 V
    data_read 0 1 0 0 -> 0 4915
    data_write 1 1 0 0 {code1} -> 0
"""
)


def _connector_code(connector):
    """comedi_from_physical of the 12-bit +/-10 V output above (round half to even)."""
    return int(round(204.75 * (connector + 10.0)))


def _dac_code(u):
    """The output code for ``u`` volts at the actuator (channel B calibration)."""
    return _connector_code(SS15_CHANNEL_B.inverse(u))


def test_comedi_protocol_replays_through_a_trial(tmp_path):
    protocol = COMEDI_PROTOCOL.format(code0=_dac_code(10.0), code1=_dac_code(20.0))
    dev = _core.ComediDevice.replay(
        protocol, "/dev/comedi0", [daq.ss15_output_channel()], [daq.ss15_input_channel()]
    )
    assert dev.description == "comedi /dev/comedi0 (pci-multiq)"
    assert dev.conversions == ["hardcal", "hardcal"] and not dev.simulated
    res = daq.run_trial(
        dev,
        [10.0, 20.0],
        tmp_path / "c.csv",
        sample_time=TS,
        safety=daq.SafetyLimits(max_consecutive_missed=-1),
    )
    assert res.complete and res.realtime  # a real device is always paced
    calls = dev.verify_protocol()
    assert calls[-1] == f"data_write 1 1 0 0 {_dac_code(20.0)}"
    rec = Recording.load(tmp_path / "c.csv")
    np.testing.assert_allclose(rec.y, -5 + 4915 * 0.001220703125)
    # a wrong call is reported with the step, what was expected and what came
    bad = protocol.replace("find_range 0 1 -5 5", "find_range 0 1 -10 10")
    with pytest.raises(
        RuntimeError,
        match=r"step 11: expected 'find_range 0 1 -10 10', got "
        r"'find_range 0 1 -5 5'",
    ):
        _core.ComediDevice.replay(
            bad, "/dev/comedi0", [daq.ss15_output_channel()], [daq.ss15_input_channel()]
        )


def test_comedi_missing_device_names_the_file():
    with pytest.raises(DeviceError, match="'/dev/comedi_preisach_missing'") as info:
        daq.comedi_device("/dev/comedi_preisach_missing")
    assert isinstance(info.value, OSError)
    msg = "^cannot open Comedi device '/dev/comedi3': No such file"
    with pytest.raises(DeviceError, match=msg):
        _core.ComediDevice.replay(
            "open /dev/comedi3 -> -1 : No such file or directory",
            "/dev/comedi3",
            [daq.ss15_output_channel()],
            [daq.ss15_input_channel()],
        )


def test_comedi_build_matches_the_library():
    import ctypes.util

    found = ctypes.util.find_library("comedi") is not None
    if found:  # CI installs libcomedi-dev, so the backend must be compiled in
        assert daq.comedi_available()


def test_device_plant_runs_the_experiments_like_the_model(model, tmp_path):
    from preisach.experiments import ModelPlant, closed_loop_test, drift_test, drive_to_state

    rig = daq.virtual_ss15(model, adc_noise=0.0, adc_bits=24)
    plants = {
        "model": ModelPlant(model, TS),
        "rig": daq.DevicePlant(rig, model=model, record_dir=tmp_path),
    }
    out = {}
    for name, plant in plants.items():
        init = drive_to_state(plant, "a", 1.0, 1.0, thresholds="simulation")
        out[name] = (
            init.offset,
            drift_test(plant, init, 1.6, 0).drift,
            closed_loop_test(plant, init, 1.6, 0).nc,
        )
    np.testing.assert_allclose(out["rig"], out["model"], rtol=1e-5)
    runs = sorted(tmp_path.glob("run_*.csv"))
    assert runs and all(Recording.load(p).metadata["end_status"] == "complete" for p in runs)
    assert plants["rig"].snapshot() == rig.state


def test_comedi_close_ramps_the_actuator_to_zero():
    """close() ramps the output to 0 V at <= close_ramp_rate instead of stepping it there."""
    c_last = SS15_CHANNEL_B.inverse(20.0)  # 20 V at the actuator: -1.418 V at the connector
    # 500 V/s at the actuator is 35.4 mV/ms at the connector: ceil(1.418 / 0.0354) = 41 writes
    steps = math.ceil(abs(c_last) / (500.0 * 1e-3 / abs(SS15_CHANNEL_B.gain)) - 1e-9)
    assert steps == 41
    ramp = [_connector_code(c_last * (1.0 - s / steps)) for s in range(1, steps)] + [
        _connector_code(0.0)
    ]
    protocol = (
        COMEDI_SETUP
        + f"data_write 1 1 0 0 {_connector_code(c_last)} -> 0\n"
        + "".join(f"data_write 1 1 0 0 {c} -> 0\n" for c in ramp)
        + "close ->\n"
    )
    dev = _core.ComediDevice.replay(
        protocol, "/dev/comedi0", [daq.ss15_output_channel()], [daq.ss15_input_channel()]
    )
    assert (dev.close_ramp_rate, dev.close_ramp_period) == (500.0, 1e-3)
    dev.write([c_last])
    dev.close()
    calls = dev.verify_protocol()  # every expected call made, in order: no step to 0 V
    assert calls[-1] == "close" and not dev.is_open
    written = np.array(
        [_connector_code(c_last)] + [int(c.split()[-1]) for c in calls[-steps - 1 : -1]]
    )
    u = SS15_CHANNEL_B.gain * (written / 204.75 - 10.0) + SS15_CHANNEL_B.offset  # actuator V
    assert np.all(np.diff(u) < 0)  # monotone from 20 V ...
    assert np.max(np.abs(np.diff(u))) <= 0.5 + 14.12 / 204.75  # 0.5 V/ms (+ 1 code rounding)
    assert written[-1] == _connector_code(0.0)  # ... to 0 V at the connector
    with pytest.raises(ValueError, match="close_ramp_rate"):
        _core.ComediDevice.replay(
            COMEDI_SETUP,
            "/dev/comedi0",
            [daq.ss15_output_channel()],
            [daq.ss15_input_channel()],
            close_ramp_rate=-1.0,
        )
