"""The general linear block of diagnosis: fitted by least squares, its response classified.

A pure delay, a moving average, a first-order lag, a lightly damped mode (full and weak
participation), a mode behind a delay, and nothing, each applied to the same broadband
signal with noise and fitted on alternating blocks: the class must be the physics, whatever
the lowest error of a narrow form would say (a delay of 2.5 ms has a broad |H - 1| hump that a
mode with damping ratio ~0.5 imitates).
"""

from __future__ import annotations

import numpy as np
import pytest
from preisach.diagnose.effects import FirstOrderOutputLag, FractionalDelay, SecondOrderMode
from preisach.diagnose.linear_block import classify, fit_linear_block
from scipy import signal

DT = 1e-3
N = 16000


@pytest.fixture(scope="module")
def drive() -> np.ndarray:
    """Steps, a multi-sine, filtered noise and a slow sine (V), like the experiments."""
    rng = np.random.default_rng(3)
    t = np.arange(N) * DT
    x = np.zeros(N)
    x[:4000] = np.repeat(rng.uniform(-1, 1, 40), 100)
    x[4000:8000] = sum(
        0.3 * np.sin(2 * np.pi * f * t[4000:8000] + rng.uniform(0, 6))
        for f in (0.5, 1.3, 3.7, 9.1, 23.0)
    )
    b, a = signal.butter(2, 40 * DT)
    x[8000:12000] = signal.lfilter(b, a, rng.normal(0, 3, 4000))
    x[12000:] = np.sin(2 * np.pi * t[12000:])
    return x


def _run(block, x: np.ndarray) -> np.ndarray:
    block.reset(float(x[0]))
    return np.asarray(block.run(x))


def _moving_average(x: np.ndarray, n: int) -> np.ndarray:
    return signal.lfilter(np.ones(n) / n, [1.0], x - x[0]) + x[0]


CASES = {
    "none": (lambda x: x, "none"),
    "delay 2.5 ms": (lambda x: _run(FractionalDelay(DT, tau=2.5e-3), x), "delay"),
    "delay 5 ms": (lambda x: _run(FractionalDelay(DT, tau=5e-3), x), "delay"),
    "moving average of 10": (lambda x: _moving_average(x, 10), "delay"),
    "lag 3 ms": (lambda x: _run(FirstOrderOutputLag(DT, tau=3e-3), x), "lag"),
    "lag 10 ms": (lambda x: _run(FirstOrderOutputLag(DT, tau=10e-3), x), "lag"),
    "mode 150 Hz": (
        lambda x: _run(SecondOrderMode(DT, f_n=150.0, zeta=0.05, participation=1.0), x),
        "mode",
    ),
    "weak mode 40 Hz": (
        lambda x: _run(SecondOrderMode(DT, f_n=40.0, zeta=0.03, participation=0.02), x),
        "mode",
    ),
    "mode behind a delay": (
        lambda x: _run(
            FractionalDelay(DT, tau=2e-3),
            _run(SecondOrderMode(DT, f_n=120.0, zeta=0.04, participation=1.0), x),
        ),
        "mode",
    ),
    # a short delay's |H - 1| = 2 |sin(pi f tau)| rises to 2 toward half the sample rate,
    # as high as a moderately participating mode's peak: the mode is judged with the delay
    # taken out of the response
    "weak mode behind a 1 ms delay": (
        lambda x: _run(
            FractionalDelay(DT, tau=1e-3),
            _run(SecondOrderMode(DT, f_n=100.0, zeta=0.08, participation=0.2), x),
        ),
        "mode",
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_class_is_the_physics(drive, name):
    make, kind = CASES[name]
    rng = np.random.default_rng(11)
    y = make(drive)
    size = float(np.std(y - drive))
    y = y + rng.normal(0.0, max(size / 4, 1e-4), N)  # the effect 4 x the noise
    train = (np.arange(N) // 500) % 2 == 0
    fit = fit_linear_block([drive], [y], [train], DT, n_taps=50)
    cls = classify(fit)
    assert cls.kind == kind, cls.reason
    if kind == "mode":
        truth = {
            "mode 150 Hz": 150.0,
            "weak mode 40 Hz": 40.0,
            "mode behind a delay": 120.0,
            "weak mode behind a 1 ms delay": 100.0,
        }
        assert cls.f_n == pytest.approx(truth[name], rel=0.1)
        assert cls.zeta < 0.3
    if kind in ("delay", "lag"):
        lag = {"delay 2.5 ms": 2.5, "delay 5 ms": 5.0, "moving average of 10": 4.5}.get(name)
        if lag is not None:  # a pure delay's low-frequency group delay is the delay
            assert 1e3 * cls.tau0 == pytest.approx(lag, rel=0.1)


def test_held_out_measurements_do_not_enter_the_fit(drive):
    """Changing the measured output outside the training samples leaves the fit unchanged."""
    y = _run(FractionalDelay(DT, tau=3e-3), drive)
    train = (np.arange(N) // 500) % 2 == 0
    a = fit_linear_block([drive], [y], [train], DT, n_taps=30)
    y2 = np.where(train, y, y + np.random.default_rng(0).normal(0, 1.0, N))
    b = fit_linear_block([drive], [y2], [train], DT, n_taps=30)
    assert np.allclose(a.b, b.b) and np.allclose(a.a, b.a)


def test_a_drift_basis_is_projected_off_the_training_rows(drive):
    """With a drift kept, the drift basis (every sample) is projected off the fitted rows.

    Fails when the basis is not cut to those rows (the fit then stopped with a shape error
    whenever a drift was kept before a linear-dynamics form was tried, seen on blind seed 16
    case 017).
    """
    t = np.arange(N) * DT
    y = _run(FractionalDelay(DT, tau=3e-3), drive) + 0.2 * (t / t[-1]) ** 2  # a slow drift
    train = (np.arange(N) // 500) % 2 == 0
    drift = np.column_stack([np.ones(N), t, t**2])
    fit = fit_linear_block([drive], [y], [train], DT, n_taps=30, nuisance=[drift])
    cls = classify(fit)
    assert cls.kind in ("delay", "short") and 1e3 * cls.tau0 == pytest.approx(3.0, rel=0.1)


def test_a_pure_delay_is_not_a_mode(drive):
    """The issue-13 failure: a 2.5 ms delay must not come out as a resonance of any damping."""
    y = _run(FractionalDelay(DT, tau=2.5e-3), drive)
    y = y + np.random.default_rng(5).normal(0.0, 0.01, N)
    fit = fit_linear_block([drive], [y], [np.ones(N, bool)], DT, n_taps=50)
    cls = classify(fit)
    assert cls.kind == "delay" and cls.flatness > 0.9, cls.reason


def test_a_rate_form_must_beat_the_linear_block_beyond_the_noise():
    """Rate dependence is named over a delay behind the hysteresis only when it predicts
    the held-out blocks better at the parsimony level: 0.3 % better with blocks that
    disagree is a tie (blind seed 23 case 008, a drift with a 0.5 ms delay, named an input
    lag so), and the linear block, which leaves the hysteresis as identified, is kept."""
    from preisach.diagnose.linear_block import rate_not_shown
    from preisach.diagnose.scoring import sign_flip_p

    rng = np.random.default_rng(2)
    lag = 1.0 + rng.uniform(0.0, 0.2, 40)
    names = {"rate_dependence/input_lag": "rate_dependence", "delay": "delay"}
    n_params = {"rate_dependence/input_lag": 1.0, "delay": 1.0}
    ok = {"rate_dependence/input_lag": True, "delay": True}
    jitter = rng.normal(0, 0.05, 40)
    tie = lag - 0.003 * lag.mean() + (jitter - jitter.mean())  # 0.3 % better in sum
    for rate, refused in ((tie, True), (0.8 * lag, False)):
        sse = {"rate_dependence/input_lag": rate, "delay": lag}
        why = rate_not_shown(names, sse, n_params, ok, sign_flip_p, 0.05)
        assert ("rate_dependence/input_lag" in why) == refused, why
        if refused:
            assert rate.sum() < lag.sum()  # better, but not beyond the noise
            assert "as well within the noise" in why["rate_dependence/input_lag"]
