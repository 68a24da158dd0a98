"""identify_rate: evidence on simulated SS15 data with a rate-dependent truth.

Sweeps at 1 and 4 Hz (400 and 1600 V/s) train; held out are a 2 Hz sweep and multi-rate
inputs (a multi-sine and filtered noise).  The rate model's held-out error must be at least
50 % below the best single-rate classical model's, and within 2x the noise when the truth is in
the model class.
"""

from __future__ import annotations

import numpy as np
import pytest
from preisach import Recording
from preisach.identify.identifiers import identify_lsq
from preisach.identify.rate import identify_rate
from preisach.rate_model import RateDependentPreisachModel, RateState, triangle_rate

NOISE = 0.005  # V, sensor noise of the simulated recordings
LEVELS = 21


def fod_sweep(rate: float, dt: float, alphas: np.ndarray) -> np.ndarray:
    h = rate * dt
    parts = [np.array([-100.0])]
    for a in alphas:
        k = int(round((a + 100.0) / h))
        up = -100.0 + (a + 100.0) * np.arange(1, k + 1) / k
        parts += [up, up[::-1][1:], [-100.0]]
    return np.concatenate(parts)


def multisine(dt: float, seconds: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds / dt)) * dt
    u = sum(
        a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        for f, a in [(0.4, 35.0), (2.2, 30.0), (5.5, 25.0)]  # |du/dt| from 0 to ~1300 V/s
    )
    return np.concatenate([[-100.0], np.clip(u, -100, 100)])


def filtered_noise(dt: float, seconds: float, seed: int) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1.0, int(seconds / dt))
    sos = butter(2, 6.0, fs=1.0 / dt, output="sos")
    u = sosfiltfilt(sos, x)
    return np.concatenate([[-100.0], np.clip(70.0 * u / np.std(u), -100, 100)])


def record(truth: RateDependentPreisachModel, u: np.ndarray, dt: float, name: str, seed: int):
    y = truth.simulate(u, RateState(truth.negative_saturation().boundary, 0.0), sample_time=dt)
    rng = np.random.default_rng(seed)
    return Recording.from_arrays(
        u=u, y=y.output + rng.normal(0.0, NOISE, u.size), sample_time=dt, experiment=name
    ), y.output


def heldout_error(model, u, y_clean, dt) -> float:
    """Rms error (V) against the noise-free truth after the first second."""
    if isinstance(model, RateDependentPreisachModel):
        yh = model.simulate(u, model.negative_saturation(), sample_time=dt).output
    else:
        yh = model.simulate(u, model.negative_saturation()).output
    k = int(1.0 / dt)
    return float(np.sqrt(np.mean((yh[k:] - y_clean[k:]) ** 2)))


def run_case(truth: RateDependentPreisachModel):
    dt = 1e-3
    alphas = np.linspace(-90, 100, 20)
    train, clean = [], {}
    for f, seed in [(1.0, 1), (4.0, 2)]:
        rec, _ = record(truth, fod_sweep(triangle_rate(f), dt, alphas), dt, f"fod-{f:g}hz", seed)
        train.append(rec)
    held = {
        "fod-2hz": fod_sweep(triangle_rate(2.0), dt, alphas + 5.0),
        "multisine": multisine(dt, 6.0, 3),
        "noise": filtered_noise(dt, 6.0, 4),
    }
    for k, u in held.items():
        _, clean[k] = record(truth, u, dt, k, 0)
    model, report = identify_rate(train, LEVELS, u_range=(-100, 100), tau=truth.tau)
    assert list(report.knots) == pytest.approx([400.0, 1600.0], rel=0.02)
    classical = [identify_lsq([r], LEVELS, u_range=(-100, 100))[0] for r in train]
    errs = {}
    for k, u in held.items():
        e_rate = heldout_error(model, u, clean[k], dt)
        e_cls = min(heldout_error(c, u, clean[k], dt) for c in classical)
        errs[k] = (e_rate, e_cls)
    return model, report, errs


def test_rate_model_in_class_predicts_held_out_rates_within_twice_the_noise() -> None:
    base = RateDependentPreisachModel.builtin("ss15-rate", levels=LEVELS)
    m1, _, m4 = base.models
    truth = RateDependentPreisachModel.from_models([m1, m4], [400.0, 1600.0], base.tau)
    _, report, errs = run_case(truth)
    assert "fod-1hz" in report.summary() and "V/s" in report.summary()
    for k, (e_rate, e_cls) in errs.items():
        assert e_rate <= 0.5 * e_cls, (k, e_rate, e_cls)
        assert e_rate <= 2.0 * NOISE, (k, e_rate, e_cls)


def test_ss15_rate_truth_held_out_error_against_the_best_classical() -> None:
    # The truth has a third table at 800 V/s that is not the ln-rate blend of the 1 and 4 Hz
    # tables, so it is outside the class a two-rate identification can reach: the 2 Hz sweep
    # must still be predicted with half the classical error; every held-out input better.
    truth = RateDependentPreisachModel.builtin("ss15-rate", levels=LEVELS)
    _, _, errs = run_case(truth)
    e_rate, e_cls = errs["fod-2hz"]
    assert e_rate <= 0.5 * e_cls, (e_rate, e_cls)
    for k, (e_rate, e_cls) in errs.items():
        assert e_rate < e_cls, (k, e_rate, e_cls)


def test_identify_rate_needs_two_rates() -> None:
    truth = RateDependentPreisachModel.builtin("ss15-rate", levels=LEVELS)
    dt = 1e-3
    rec, _ = record(truth, fod_sweep(800.0, dt, np.linspace(-50, 100, 4)), dt, "one", 0)
    with pytest.raises(ValueError, match="two or more distinct rates"):
        identify_rate([rec, rec], LEVELS)


def test_cli_method_rate(tmp_path) -> None:
    import argparse

    from preisach.identify.cli import add_parser

    truth = RateDependentPreisachModel.builtin("ss15-rate", levels=LEVELS)
    dt = 1e-3
    paths = []
    for f in (1.0, 4.0):
        rec, _ = record(
            truth, fod_sweep(triangle_rate(f), dt, np.linspace(-80, 100, 10)), dt, f"fod-{f:g}hz", 7
        )
        rec.save(tmp_path / f"fod{f:g}.csv")
        paths.append(str(tmp_path / f"fod{f:g}.csv"))
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command")
    add_parser(sub)
    out = tmp_path / "rate.npz"
    args = parser.parse_args(
        [
            "identify",
            *paths,
            "--method",
            "rate",
            "--levels",
            "11",
            "-o",
            str(out),
            "--json",
            str(tmp_path / "r.json"),
        ]
    )
    assert args.func(args) == 0
    model = RateDependentPreisachModel.load(out)
    assert model.n_tables == 2 and len(model.levels) == 11
    assert (tmp_path / "r.json").exists()
    bad = parser.parse_args(["identify", paths[0], "--method", "rate", "-o", str(out)])
    with pytest.raises(ValueError, match="two or more distinct rates"):
        bad.func(bad)
