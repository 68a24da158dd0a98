"""Mixtures of two effects: the first named right, the second found after it, never a wrong name.

A piezo stack (the built-in SS15 surface) whose displacement reaches the sensor through a
lightly damped mode of its mount (80 Hz, damping ratio 0.06) and then an ADC pipeline of one
sample (1 ms at 1 kHz): both are linear dynamics after the hysteresis.  A first-order lag in
front of the relays (rate dependence) imitates the delay except at sharp reversals, so it
lowers the held-out error nearly as much; it must not be the name (blind case seed 8 / 007, a
resonance and a delay, came out ``rate_dependence``).
"""

from __future__ import annotations

import numpy as np
from preisach import PreisachModel, Recording
from preisach.diagnose import FractionalDelay, SecondOrderMode, diagnose

DT = 1e-3


def _device(m: PreisachModel, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The stack's output through its mount's mode and the sensor's one-sample pipeline (V)."""
    x = np.asarray(m.simulate(u, m.anhysteretic_state()).output)
    mode = SecondOrderMode(DT, f_n=80.0, zeta=0.06, participation=0.3)
    mode.reset(float(x[0]))
    delay = FractionalDelay(DT, tau=1e-3)
    z = np.asarray(mode.run(x))
    delay.reset(float(z[0]))
    return np.asarray(delay.run(z)) + rng.normal(0.0, 5e-3, u.size)


def test_a_delay_and_a_mode_are_not_rate_dependence():
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    rng = np.random.default_rng(2)
    t = np.arange(4000) * DT
    levels = rng.uniform(-90.0, 90.0, 16)
    steps = np.repeat(levels, 250)  # step-and-hold: every step rings the mount
    tri = 90.0 * (2.0 / np.pi) * np.arcsin(np.sin(2 * np.pi * 2.0 * t))  # sharp reversals
    recs = [
        Recording.from_arrays(t=t, u=u, y=_device(m, u, rng), experiment=name)
        for name, u in (("steps", steps), ("triangles", tri))
    ]
    rep = diagnose(
        m,
        recs,
        identification=[],
        candidates=["rate_dependence/input_lag", "delay", "structural_resonance"],
        progress=False,
    )
    names = [e.name for e in rep.effects]
    assert rep.verdict != "rate_dependence", rep.summary()
    assert rep.verdict in ("delay", "structural_resonance"), rep.summary()
    assert set(names) == {"delay", "structural_resonance"}, rep.summary()
    print(rep.summary())
