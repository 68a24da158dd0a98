"""Test inputs shared by several diagnosis tests (volts, on the SS15 range of ±100 V)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray
from preisach import Recording
from preisach.waveforms import legs


def shrinking_sweep(sample_time: float) -> NDArray[np.float64]:
    """A 1 Hz FOD-like identification sweep: 0 V down to -100 V, then 5 s of triangles.

    The amplitude shrinks from 100 V to 10 V, so the reversals cover the Preisach plane.
    """
    t = np.arange(int(5 / sample_time)) * sample_time
    env = 100 * np.clip(1 - t / 5, 0.1, 1)
    return np.concatenate(
        [np.linspace(0, -100, 200), env * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t))]
    )


def offset_loops(sample_time: float) -> NDArray[np.float64]:
    """The same 16 V minor loop at five drive offsets (-60 to 60 V), up the range and down.

    Starts at -100 V, 0.1 s per leg; loops at several output levels are what separate a
    congruent (classical) device from one whose loops change with the output level.
    """
    pts = [-100.0]
    for direction in (1, -1):
        for o in np.linspace(-60.0, 60.0, 5)[::direction]:
            pts += [float(o), float(o + 16.0 * direction), float(o)]
        pts.append(100.0 if direction > 0 else -100.0)
    return np.asarray(legs(pts, 0.1, sample_time=sample_time).u, float)


def session(
    parts: Sequence[tuple[str, NDArray[np.float64]]],
    simulate: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    noise: float,
    seed: int,
    sample_time: float,
) -> list[Recording]:
    """One continuous history of the named inputs through ``simulate``, cut into recordings.

    ``noise``: the standard deviation (V) of the white noise added to the outputs.
    """
    rng = np.random.default_rng(seed)
    u_all = np.concatenate([u for _, u in parts])
    y_all = simulate(u_all) + noise * rng.normal(size=u_all.size)
    recs, k = [], 0
    for name, u in parts:
        recs.append(
            Recording.from_arrays(
                u=u, y=y_all[k : k + u.size], sample_time=sample_time, metadata={"name": name}
            )
        )
        k += u.size
    return recs
