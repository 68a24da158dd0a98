"""No false alarm on a classical device whose Preisach density is finer than the model's grid.

The device is written here from a physical description, not from any candidate or blind
generator: a piezo ceramic's switching units (relays) with a coercive field spread around
2 V and an interaction field spread of 3 V, each grid cell of a 97-level plane carrying a
random grain-to-grain weight (log-normal, 60 %), so the density is rough on a scale far
below the 21-level identification grid.  Recordings follow one another in one session (each
starts in the state the previous one left), with 3 mV white noise.
"""

from __future__ import annotations

import numpy as np
import pytest
from preisach import PreisachModel, Recording, _core
from preisach.diagnose import diagnose
from preisach.identify import identify
from preisach.waveforms import fod_sweep
from scipy.ndimage import gaussian_filter

LO, HI, NOISE, CLUSTER = -10.0, 10.0, 3e-3, 3.0


def _device(seed: int = 0) -> PreisachModel:
    n = 97
    lv = np.linspace(LO, HI, n)
    mid = 0.5 * (lv[:-1] + lv[1:])
    a, b = np.meshgrid(mid, mid, indexing="ij")
    coercive, interaction = 0.5 * (a - b), 0.5 * (a + b)
    density = np.exp(-0.5 * (interaction / 3.0) ** 2) / (1.0 + ((coercive - 2.0) / 1.0) ** 2)
    # grain clusters: a log-normal weight field correlated over about 0.6 V (three cells)
    rng = np.random.default_rng(seed)
    field = gaussian_filter(rng.normal(0.0, 1.0, density.shape), CLUSTER)
    w = np.tril(density * np.exp(0.6 * field / field.std()))
    w *= 10.0 / w.sum()  # 10 V of output span
    return PreisachModel(_core.EverettTable.from_weights(lv, w, -5.0), name="rough device")


def _session(dev: PreisachModel, inputs: list[np.ndarray], creep: float, seed: int):
    """Record the inputs one after another; ``creep``: a relaxation (V per V of output)."""
    rng = np.random.default_rng(seed)
    state = dev.negative_saturation()
    recs = []
    for k, u in enumerate(inputs):
        sim = dev.simulate(u, state)
        state = sim.final_state
        y = np.asarray(sim.output, float)
        if creep:  # the output relaxes toward its new value with a 0.4 s time constant
            lag = np.empty_like(y)
            acc = y[0]
            for i, v in enumerate(y):
                acc += (v - acc) * (1e-3 / 0.4)
                lag[i] = acc
            y = y + creep * (y - lag)
        y = y + rng.normal(0.0, NOISE, y.size)
        t = np.arange(u.size) * 1e-3
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"e{k}"))
    return recs


def _inputs(seed: int = 1) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(4000) * 1e-3
    multi = sum(
        a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        for a, f in ((4.0, 0.45), (2.5, 1.3), (1.5, 2.9))
    )
    steps = np.repeat(rng.uniform(-8.0, 8.0, 10), 400)
    env = 9.0 * np.exp(-t / 2.0)
    wiping = env * np.sign(np.sin(2 * np.pi * 1.1 * t)) * np.abs(np.sin(2 * np.pi * 1.1 * t)) ** 0.5
    return [multi, steps, wiping]


@pytest.fixture(scope="module")
def model_and_device():
    dev = _device()
    sweep = fod_sweep(21, u_min=LO, u_max=HI, frequency=4.0)
    ident = _session(dev, [np.asarray(sweep.u, float)], 0.0, seed=5)[0]
    model = identify(ident, method="fod", progress=False).model
    model.identification = [ident]
    return model, dev


def test_rough_classical_device_is_none_not_unexplained(model_and_device):
    model, dev = model_and_device
    recs = _session(dev, _inputs(), 0.0, seed=7)
    rep = diagnose(model, recs, candidates=["gain_offset"], progress=False)
    nt = rep.noise_test
    # the base at the model's grid leaves more than the bound: only the resolution check helps
    assert nt["ratio"] > nt["threshold"], nt
    assert nt["classical"] is not None and nt["classical"]["ratio"] < 1.5, nt
    assert rep.verdict == "none" and nt["consistent"] and rep.unexplained is None
    assert nt["classical"]["statement"] in rep.notes


def test_creep_on_the_same_device_stays_unexplained(model_and_device):
    """A relaxation while the input holds is no resolution: no classical model makes it."""
    model, dev = model_and_device
    recs = _session(dev, _inputs(), 0.01, seed=7)
    rep = diagnose(model, recs, candidates=["gain_offset"], progress=False)
    nt = rep.noise_test
    assert nt["classical"] is not None and nt["classical"]["ratio"] > nt["threshold"], nt
    assert rep.verdict == "unexplained" and not nt["consistent"]
    # a scale of the diagnosis recordings takes a part of the relaxation the identification
    # lacks (15-20 % of the held-out error), not the whole: no calibration is named
    first = {c["name"]: c["decision"] for c in rep.candidates if c["step"] == 1}
    assert "lack more than a calibration" in first["gain_offset"], first


#: the diagnosis recordings' scale and zero after a recalibration of the sensor
RECAL = (1.02, 0.0)


def _recalibrated(recs: list[Recording], gain: float, offset: float) -> list[Recording]:
    return [
        Recording.from_arrays(t=r.t, u=r.u, y=gain * r.y + offset, metadata=r.metadata)
        for r in recs
    ]


def test_a_sensor_recalibrated_after_the_identification_is_named(model_and_device):
    """A scale that differs between identification and diagnosis is the sensor's.

    The diagnosis recordings read 2 % high (the sensor recalibrated after the sweep):
    ``gain_offset`` is named with that scale.  (Not a zero shift: these recordings start
    from unknown initial states, and a shift of a few tens of mV is also an initial state.)
    Fails when the block also scales the identification recordings (a scale common to both
    is the refitted weights' own) or when the calibration's tests against the fine classical
    model refuse a real recalibration.
    """
    model, dev = model_and_device
    recs = _recalibrated(_session(dev, _inputs(), 0.0, seed=7), *RECAL)
    rep = diagnose(model, recs, candidates=["gain_offset"], progress=False)
    assert rep.verdict == "gain_offset", rep.summary()
    gain = rep.effects[0].parameters["gain"]
    assert abs(gain["value"] - 1.02) < max(3 * gain["std"], 2e-3), gain
    statement = rep.effects[0].statement
    assert "zero is not told from the recordings' unknown initial states" in statement


def test_the_zero_of_recordings_from_unknown_states_is_not_fitted(model_and_device):
    """The zero of a recording from an unknown initial state is partly that state.

    Every diagnosis recording here starts where the previous one left the device (states
    unknown to the diagnosis): ``gain_offset`` only scales them, and its zero column in the
    fine classical model is empty (blind seed-24 case 017, a creep, was named by a 26 mV
    zero of five such recordings).  Fails when such a zero is fitted again.
    """
    from preisach.diagnose.candidates import GainOffsetCandidate
    from preisach.diagnose.context import Context, Stage
    from preisach.diagnose.data import prepare_recordings

    model, dev = model_and_device
    recs = _session(dev, _inputs(), 0.0, seed=7)
    ctx = Context(
        model, prepare_recordings(model, recs, identification=model.identification), refit=True
    )
    cand = GainOffsetCandidate()
    x = np.array([1.02, 0.05])
    cols, _ = cand.classical_columns(ctx, x)
    for i in ctx.diag:
        r = ctx.recs[i]
        assert r.history is not None  # unknown initial state
        assert not cols[i][:, 0].any() and cols[i][:, 1].any()
        out = cand.apply(x, r.y, r.dt, Stage(i, r.u, None), ctx)
        np.testing.assert_allclose(out, 1.02 * r.y)


def test_a_calibration_no_classical_model_needs_is_not_named(model_and_device, monkeypatch):
    """The calibration forms must add to the fine classical model what a static curve must.

    The scale common to the identification and the diagnosis recordings adds nothing beyond
    the fine model (the weights scale with it); a scale of the diagnosis recordings alone
    adds many noise variances.  With the bar raised out of reach the recalibration of the
    test above is refused by it, and says why.  Fails when the check gives a common scale
    a gain, or the selection no longer asks it.
    """
    import importlib

    from preisach.diagnose.congruency import output_curve_check
    from preisach.diagnose.context import Context
    from preisach.diagnose.data import prepare_recordings

    selection = importlib.import_module("preisach.diagnose.selection")
    model, dev = model_and_device
    clean = _session(dev, _inputs(), 0.0, seed=7)
    ident = model.identification
    for recs, beyond in ((clean, False), (_recalibrated(clean, *RECAL), True)):
        ctx = Context(model, prepare_recordings(model, recs, identification=ident), refit=True)
        cc = output_curve_check(ctx, NOISE, powers=(1,), identification=False)
        assert (cc.gain > 1.0 and cc.p < 0.01) if beyond else cc.gain < 0.02, cc
    monkeypatch.setattr(selection, "FORM_BEYOND_CLASSICAL", 1e9)
    rep = diagnose(model, _recalibrated(clean, *RECAL), candidates=["gain_offset"])
    assert rep.verdict != "gain_offset"
    first = {c["name"]: c["decision"] for c in rep.candidates if c["step"] == 1}
    assert "initial states explains what it does" in first["gain_offset"], first
