"""Held-out evidence for the rate-dependent identification (issue 15), on simulated SS15 data.

A truth (a :class:`~preisach.rate_model.RateDependentPreisachModel`) is recorded with
:data:`NOISE` V of Gaussian sensor noise on FOD sweeps at 1 and 4 Hz (400 and 1600 V/s, the
training set) and, noise-free, on held-out inputs: an FOD sweep at 2 Hz (a third rate), a
multi-sine and low-pass filtered noise (rates from 0 to ~1300 V/s).  The identified rate model
and the single-rate classical least-squares models of each training sweep predict the held-out
inputs; the errors are rms against the noise-free truth after the first second.  Used by
``tests/test_identify_rate.py`` and ``scripts/rate_heldout_study.py``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..identify.identifiers import identify_lsq
from ..identify.rate import RateIdentificationReport, identify_rate
from ..model import PreisachModel
from ..rate_model import RateDependentPreisachModel, RateState, triangle_rate
from ..recording import Recording

__all__ = [
    "NOISE",
    "HeldOutCase",
    "filtered_noise",
    "fod_sweep_at_rate",
    "heldout_error",
    "in_class_truth",
    "multisine",
    "record",
    "run_case",
]

#: Sensor noise (V rms) of the simulated training recordings.
NOISE = 0.005
#: Sample time (s) of every recording.
DT = 1e-3


def fod_sweep_at_rate(rate: float, dt: float, alphas: NDArray[np.float64]) -> NDArray[np.float64]:
    """FOD sweep at a constant ``|du/dt|`` (V/s): from -100 V up to each alpha and back."""
    h = rate * dt
    parts = [np.array([-100.0])]
    for a in alphas:
        k = int(round((a + 100.0) / h))
        up = -100.0 + (a + 100.0) * np.arange(1, k + 1) / k
        parts += [up, up[::-1][1:], np.array([-100.0])]
    return np.concatenate(parts)


def multisine(dt: float, seconds: float, seed: int) -> NDArray[np.float64]:
    """0.4, 2.2 and 5.5 Hz sines (35, 30, 25 V, random phases) after -100 V: |du/dt| 0-1300 V/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds / dt)) * dt
    u = sum(
        a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        for f, a in [(0.4, 35.0), (2.2, 30.0), (5.5, 25.0)]
    )
    return np.concatenate([[-100.0], np.clip(u, -100, 100)])


def filtered_noise(dt: float, seconds: float, seed: int) -> NDArray[np.float64]:
    """Gaussian noise low-passed at 6 Hz (2nd-order Butterworth, zero phase), 70 V rms."""
    from scipy.signal import butter, sosfiltfilt

    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1.0, int(seconds / dt))
    u = sosfiltfilt(butter(2, 6.0, fs=1.0 / dt, output="sos"), x)
    return np.concatenate([[-100.0], np.clip(70.0 * u / np.std(u), -100, 100)])


def record(
    truth: RateDependentPreisachModel, u: NDArray[np.float64], dt: float, name: str, seed: int
) -> tuple[Recording, NDArray[np.float64]]:
    """Simulate ``truth`` from negative saturation at rest; the noisy recording and clean output."""
    y = truth.simulate(u, RateState(truth.negative_saturation().boundary, 0.0), sample_time=dt)
    rng = np.random.default_rng(seed)
    rec = Recording.from_arrays(
        u=u, y=y.output + rng.normal(0.0, NOISE, u.size), sample_time=dt, experiment=name
    )
    return rec, y.output


def heldout_error(
    model: PreisachModel | RateDependentPreisachModel,
    u: NDArray[np.float64],
    y_clean: NDArray[np.float64],
    dt: float,
) -> float:
    """Rms error (V) against the noise-free truth after the first second."""
    if isinstance(model, RateDependentPreisachModel):
        yh = model.simulate(u, model.negative_saturation(), sample_time=dt).output
    else:
        yh = model.simulate(u, model.negative_saturation()).output
    k = int(1.0 / dt)
    return float(np.sqrt(np.mean((yh[k:] - y_clean[k:]) ** 2)))


def in_class_truth(levels: int = 21, scale: str = "linear") -> RateDependentPreisachModel:
    """Return the 1 and 4 Hz surfaces of ``ss15-rate`` at 400 and 1600 V/s (two-rate class)."""
    base = RateDependentPreisachModel.builtin("ss15-rate", levels=levels)
    m1, _, m4 = base.models
    return RateDependentPreisachModel.from_models([m1, m4], [400.0, 1600.0], base.tau, scale=scale)


@dataclass
class HeldOutCase:
    """One identification and its held-out errors (V rms).

    Attributes
    ----------
    model : RateDependentPreisachModel
    report : RateIdentificationReport
    classical : list of PreisachModel
        The least-squares model of each training sweep.
    errors : dict
        Held-out input name -> (rate model error, best classical error).

    """

    model: RateDependentPreisachModel
    report: RateIdentificationReport
    classical: list[PreisachModel]
    errors: dict[str, tuple[float, float]]
    held: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]


def run_case(
    truth: RateDependentPreisachModel,
    levels: int = 21,
    *,
    seed: int = 0,
    identify: Mapping[str, Any] | None = None,
) -> HeldOutCase:
    """Record, identify from the 1 and 4 Hz sweeps, and predict the held-out inputs."""
    dt = DT
    alphas = np.linspace(-90, 100, 20)
    train = [
        record(truth, fod_sweep_at_rate(triangle_rate(f), dt, alphas), dt, f"fod-{f:g}hz", s)[0]
        for f, s in [(1.0, 1 + 10 * seed), (4.0, 2 + 10 * seed)]
    ]
    inputs = {
        "fod-2hz": fod_sweep_at_rate(triangle_rate(2.0), dt, alphas + 5.0),
        "multisine": multisine(dt, 6.0, 3 + 10 * seed),
        "noise": filtered_noise(dt, 6.0, 4 + 10 * seed),
    }
    held = {k: (u, record(truth, u, dt, k, 0)[1]) for k, u in inputs.items()}
    model, report = identify_rate(train, levels, u_range=(-100, 100), **dict(identify or {}))
    classical = [identify_lsq([r], levels, u_range=(-100, 100))[0] for r in train]
    errors = {
        k: (
            heldout_error(model, u, y, dt),
            min(heldout_error(c, u, y, dt) for c in classical),
        )
        for k, (u, y) in held.items()
    }
    return HeldOutCase(model, report, classical, errors, held)
