from __future__ import annotations

import json

import numpy as np
import pytest
from preisach.noise import NoiseSpec, uniform_filtered_noise
from scipy import signal


def _power_fraction_below(x: np.ndarray, fs: float, f_max: float) -> float:
    f, pxx = signal.welch(x, fs=fs, nperseg=4096)
    return float(pxx[f <= f_max].sum() / pxx.sum())


def test_same_int_seed_is_identical():
    a = uniform_filtered_noise(5.0, 0.5, seed=42)
    b = uniform_filtered_noise(5.0, 0.5, seed=42)
    np.testing.assert_array_equal(a, b)


def test_generator_seed_matches_int_seed_and_advances():
    a = uniform_filtered_noise(3.0, seed=np.random.default_rng(7))
    b = uniform_filtered_noise(3.0, seed=7)
    np.testing.assert_array_equal(a, b)
    rng = np.random.default_rng(7)
    first = uniform_filtered_noise(3.0, seed=rng)
    second = uniform_filtered_noise(3.0, seed=rng)
    assert not np.array_equal(first, second)


def test_different_seeds_differ():
    a = uniform_filtered_noise(5.0, seed=1)
    b = uniform_filtered_noise(5.0, seed=2)
    assert not np.allclose(a, b)


def test_no_seed_runs_and_differs():
    a = uniform_filtered_noise(2.0)
    b = uniform_filtered_noise(2.0)
    assert a.shape == b.shape == (2000,)
    assert not np.array_equal(a, b)


@pytest.mark.parametrize("amplitude", [0.5, 1.0, 2.3, 1e-3])
def test_peak_equals_amplitude_exactly(amplitude):
    x = uniform_filtered_noise(10.0, amplitude, seed=3)
    assert np.max(np.abs(x)) == amplitude
    assert x.dtype == np.float64 and x.ndim == 1


def test_zero_amplitude_gives_zeros():
    x = uniform_filtered_noise(1.0, 0.0, seed=0)
    np.testing.assert_array_equal(x, np.zeros(1000))


@pytest.mark.parametrize(
    ("duration", "sample_time", "expected"),
    [
        (10.0, 1e-3, 10000),
        (1.0, 1e-3, 1000),
        (0.3, 1e-3, 300),
        (2.0, 5e-3, 400),
        (7.0, 1e-4, 70000),
    ],
)
def test_sample_count(duration, sample_time, expected):
    x = uniform_filtered_noise(duration, sample_time=sample_time, seed=0)
    assert x.size == expected


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_zero_mean_over_long_sequences(seed):
    amplitude = 0.5
    x = uniform_filtered_noise(200.0, amplitude, seed=seed)
    # Std of the mean: sigma ~ 0.35*A, ~ 200 s / 15 ms = 13k independent-ish draws -> ~0.003*A.
    assert abs(x.mean()) < 0.02 * amplitude
    # Not degenerate: a substantial spread around zero.
    assert 0.25 * amplitude < x.std() < 0.5 * amplitude


def test_zero_mean_averaged_over_seeds():
    means = [uniform_filtered_noise(50.0, 1.0, seed=s).mean() for s in range(20)]
    assert abs(np.mean(means)) < 0.01


@pytest.mark.parametrize("seed", [0, 5])
def test_power_is_mostly_below_cutoff(seed):
    x = uniform_filtered_noise(200.0, 0.5, seed=seed)
    fs = 1000.0
    # A 4th-order Butterworth is -3 dB at 15 Hz, so ~8 % of the power lies just above it.
    assert _power_fraction_below(x, fs, 15.0) > 0.90
    assert _power_fraction_below(x, fs, 30.0) > 0.995


def test_higher_order_sharpens_the_split():
    x = uniform_filtered_noise(200.0, 0.5, order=8, seed=0)
    assert _power_fraction_below(x, 1000.0, 15.0) > 0.95


def test_lower_cutoff_moves_power_down():
    lo = uniform_filtered_noise(200.0, cutoff=5.0, seed=0)
    assert _power_fraction_below(lo, 1000.0, 5.0) > 0.90
    assert _power_fraction_below(lo, 1000.0, 10.0) > 0.995


def test_causal_filter_starts_from_zero_state():
    x = uniform_filtered_noise(5.0, seed=11)
    # The first output sample of a causal Butterworth from rest is tiny.
    assert abs(x[0]) < 1e-3 * 0.5
    # Causality: a longer sequence with the same seed shares its prefix up to scaling.
    y = uniform_filtered_noise(10.0, seed=11)
    ratio = y[:5000] / np.where(x == 0, 1.0, x)
    ratio = ratio[np.abs(x) > 1e-3]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)


def test_hold_time_not_multiple_of_sample_time():
    x = uniform_filtered_noise(2.0, hold_time=0.0155, seed=0)
    assert x.size == 2000 and np.max(np.abs(x)) == 0.5


# --- NoiseSpec ---------------------------------------------------------------------------


def test_noisespec_generate_matches_function():
    spec = NoiseSpec(amplitude=0.4, cutoff=10.0, order=3)
    np.testing.assert_array_equal(
        spec.generate(4.0, seed=9),
        uniform_filtered_noise(4.0, 0.4, cutoff=10.0, order=3, seed=9),
    )


def test_noisespec_defaults_follow_thesis():
    spec = NoiseSpec()
    assert spec.to_dict() == {
        "amplitude": 0.5,
        "sample_time": 1e-3,
        "hold_time": 0.015,
        "cutoff": 15.0,
        "order": 4,
    }


def test_noisespec_is_frozen_and_roundtrips():
    spec = NoiseSpec(amplitude=1, order=np.int64(6))
    assert isinstance(spec.amplitude, float) and type(spec.order) is int
    with pytest.raises(AttributeError):
        spec.amplitude = 2.0  # type: ignore[misc]
    d = spec.to_dict()
    assert NoiseSpec.from_dict(json.loads(json.dumps(d))) == spec


def test_noisespec_from_dict_rejects_unknown_keys():
    with pytest.raises(ValueError, match="unknown"):
        NoiseSpec.from_dict({"amplitude": 0.5, "gain": 2})


def test_noisespec_validates():
    with pytest.raises(ValueError, match="cutoff"):
        NoiseSpec(cutoff=40.0)


# --- argument validation -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"duration": 0.0}, "duration"),
        ({"duration": -1.0}, "duration"),
        ({"duration": float("nan")}, "duration"),
        ({"duration": 1e-5}, "duration"),
        ({"amplitude": -0.1}, "amplitude"),
        ({"amplitude": float("inf")}, "amplitude"),
        ({"sample_time": 0.0}, "sample_time"),
        ({"sample_time": -1e-3}, "sample_time"),
        ({"hold_time": 0.0}, "hold_time"),
        ({"hold_time": 5e-4}, "hold_time"),
        ({"cutoff": 0.0}, "cutoff"),
        ({"cutoff": 33.4}, "cutoff"),
        ({"cutoff": float("inf")}, "cutoff"),
        ({"order": 0}, "order"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_values_raise_value_error_naming_argument(kwargs, name):
    args = {"duration": 1.0, **kwargs}
    with pytest.raises(ValueError, match=name):
        uniform_filtered_noise(**args)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"order": 2.5}, "order"),
        ({"order": True}, "order"),
        ({"seed": 1.5}, "seed"),
        ({"seed": "abc"}, "seed"),
        ({"amplitude": "0.5"}, "amplitude"),
        ({"duration": None}, "duration"),
    ],
)
def test_bad_types_raise_type_error_naming_argument(kwargs, name):
    args = {"duration": 1.0, **kwargs}
    with pytest.raises(TypeError, match=name):
        uniform_filtered_noise(**args)


def test_cutoff_just_below_hold_nyquist_is_accepted():
    x = uniform_filtered_noise(1.0, cutoff=33.0, seed=0)
    assert x.size == 1000
