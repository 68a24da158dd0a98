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
