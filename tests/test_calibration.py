from __future__ import annotations

import json
import math

import numpy as np
import pytest
from preisach.daq.calibration import (
    SS15_CHANNEL_A,
    SS15_CHANNEL_B,
    TABLE_B1,
    TABLE_B2,
    LinearCalibration,
    fit_linear_calibration,
)

# --- Table B.2 and Eq. (B.1a)/(B.1b) -----------------------------------------------------


def test_table_b2_shape_and_layout():
    assert TABLE_B2.v_in.shape == TABLE_B2.v_a_out.shape == TABLE_B2.v_b_out.shape == (22,)
    np.testing.assert_array_equal(TABLE_B2.v_in[:11], np.arange(0, 11))
    np.testing.assert_array_equal(TABLE_B2.v_in[11:], np.arange(-10, 1))
    # The 0 V row is printed in both blocks with identical readings.
    assert TABLE_B2.v_a_out[0] == TABLE_B2.v_a_out[21] == -0.45
    assert TABLE_B2.v_b_out[0] == TABLE_B2.v_b_out[21] == -0.34
    # Spot checks against the printed table.
    assert TABLE_B2.v_a_out[10] == -141.48 and TABLE_B2.v_b_out[10] == -141.05
    assert TABLE_B2.v_a_out[11] == 141.30 and TABLE_B2.v_b_out[11] == 141.06
    assert TABLE_B2.v_a_out[20] == 14.40 and TABLE_B2.v_b_out[20] == 14.44


def test_tables_are_read_only():
    with pytest.raises(ValueError):
        TABLE_B2.v_a_out[0] = 0.0
    with pytest.raises(ValueError):
        TABLE_B1.ch1[0] = 0.0


def test_fit_reproduces_eq_b1a_channel_a():
    cal = fit_linear_calibration(TABLE_B2.v_in, TABLE_B2.v_a_out)
    assert round(cal.gain, 2) == SS15_CHANNEL_A.gain == -14.16
    assert round(cal.offset, 2) == SS15_CHANNEL_A.offset == -0.12
    assert round(cal.rms_residual, 2) == SS15_CHANNEL_A.rms_residual == 0.20
    assert cal.rms_residual == pytest.approx(0.19853, abs=1e-5)
    assert cal.max_residual == pytest.approx(SS15_CHANNEL_A.max_residual, abs=0.005)
    assert cal.n_points == 22


def test_fit_reproduces_eq_b1b_channel_b():
    cal = fit_linear_calibration(TABLE_B2.v_in, TABLE_B2.v_b_out)
    assert round(cal.gain, 2) == SS15_CHANNEL_B.gain == -14.12
    assert round(cal.offset, 2) == SS15_CHANNEL_B.offset == -0.02
    assert round(cal.rms_residual, 2) == SS15_CHANNEL_B.rms_residual == 0.19
    assert cal.rms_residual == pytest.approx(0.18781, abs=1e-5)
    assert cal.max_residual == pytest.approx(SS15_CHANNEL_B.max_residual, abs=0.005)
    assert cal.n_points == 22


def test_dropping_duplicate_zero_row_does_not_reproduce_thesis():
    # Documented in the module: the thesis fitted all 22 printed rows.
    x, ya, yb = TABLE_B2.v_in[:21], TABLE_B2.v_a_out[:21], TABLE_B2.v_b_out[:21]
    a = fit_linear_calibration(x, ya)
    b = fit_linear_calibration(x, yb)
    assert round(a.gain, 2) == -14.16 and round(b.gain, 2) == -14.12
    assert round(a.offset, 2) != -0.12 and round(b.offset, 2) != -0.02
    assert round(a.rms_residual, 2) != 0.20 and round(b.rms_residual, 2) != 0.19


@pytest.mark.parametrize("column", ["v_a_out", "v_b_out"])
def test_residual_is_polarity_offset_not_noise(column):
    y = getattr(TABLE_B2, column)
    x = TABLE_B2.v_in
    pos = fit_linear_calibration(x[:11], y[:11])  # inputs 0..10 V
    neg = fit_linear_calibration(x[11:21], y[11:21])  # inputs -10..-1 V
    assert pos.rms_residual < 0.02 and neg.rms_residual < 0.02
    assert 0.6 < neg.offset - pos.offset < 0.9


def test_printed_equations_fit_table_as_claimed():
    for cal, y in ((SS15_CHANNEL_A, TABLE_B2.v_a_out), (SS15_CHANNEL_B, TABLE_B2.v_b_out)):
        r = y - cal(TABLE_B2.v_in)
        assert math.sqrt(np.mean(r**2)) == pytest.approx(cal.rms_residual, abs=0.01)
        assert np.max(np.abs(r)) < 0.4


def test_channel_b_is_eq_b2():
    # Eq. (B.2): V_in = -14.12 * V_bin - 0.02; 7 V on the Flexmorph needs about -0.5 V at the DAC.
    assert SS15_CHANNEL_B(-0.5) == pytest.approx(7.04)
    assert SS15_CHANNEL_B.inverse(7.04) == pytest.approx(-0.5)


# --- Table B.1 (ADC) ---------------------------------------------------------------------


@pytest.mark.parametrize("channel", ["ch0", "ch1", "ch2", "ch3"])
def test_adc_is_nearly_identity(channel):
    cal = fit_linear_calibration(getattr(TABLE_B1, channel), TABLE_B1.supply)
    assert cal.gain == pytest.approx(1.0, abs=0.005)
    assert abs(cal.offset) < 0.01
    assert cal.rms_residual < 0.015
    assert cal.n_points == 11


# --- LinearCalibration -------------------------------------------------------------------


def test_call_and_inverse_scalar_and_array():
    cal = LinearCalibration(gain=-14.12, offset=-0.02)
    y = cal(1.0)
    assert isinstance(y, float) and y == pytest.approx(-14.14)
    assert isinstance(cal.inverse(y), float) and cal.inverse(y) == pytest.approx(1.0)
    x = np.linspace(-10, 10, 7)
    np.testing.assert_allclose(cal(x), -14.12 * x - 0.02)
    np.testing.assert_allclose(cal.inverse(cal(x)), x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cal([1, 2]), [-14.14, -28.26])


def test_defaults_and_coercion():
    cal = LinearCalibration(gain=2, offset=np.float32(0.5))
    assert type(cal.gain) is float and type(cal.offset) is float
    assert math.isnan(cal.rms_residual) and math.isnan(cal.max_residual)
    assert cal.n_points == 0


def test_frozen():
    with pytest.raises(AttributeError):
        SS15_CHANNEL_A.gain = 1.0  # type: ignore[misc]


def test_to_from_dict_roundtrip_via_json():
    d = SS15_CHANNEL_B.to_dict()
    assert d == {
        "gain": -14.12,
        "offset": -0.02,
        "rms_residual": 0.19,
        "max_residual": 0.34,
        "n_points": 22,
    }
    assert LinearCalibration.from_dict(json.loads(json.dumps(d))) == SS15_CHANNEL_B
    assert LinearCalibration.from_dict({"gain": 3.0, "offset": 1.0}).gain == 3.0


@pytest.mark.parametrize(
    ("data", "match"),
    [({"gain": 1.0}, "offset"), ({"gain": 1.0, "offset": 0.0, "slope": 2}, "slope")],
)
def test_from_dict_errors(data, match):
    with pytest.raises(ValueError, match=match):
        LinearCalibration.from_dict(data)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gain": 0.0, "offset": 0.0}, "gain"),
        ({"gain": float("nan"), "offset": 0.0}, "gain"),
        ({"gain": 1.0, "offset": float("inf")}, "offset"),
        ({"gain": 1.0, "offset": 0.0, "rms_residual": -1.0}, "rms_residual"),
        ({"gain": 1.0, "offset": 0.0, "max_residual": float("inf")}, "max_residual"),
        ({"gain": 1.0, "offset": 0.0, "n_points": -1}, "n_points"),
    ],
)
def test_invalid_calibration_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LinearCalibration(**kwargs)


def test_invalid_calibration_types():
    with pytest.raises(TypeError, match="gain"):
        LinearCalibration(gain="1", offset=0.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="n_points"):
        LinearCalibration(gain=1.0, offset=0.0, n_points=2.0)  # type: ignore[arg-type]


# --- fit_linear_calibration --------------------------------------------------------------


def test_fit_exact_line():
    x = np.array([-3.0, -1.0, 0.5, 2.0, 7.0])
    cal = fit_linear_calibration(x, 2.5 * x - 1.25)
    assert cal.gain == pytest.approx(2.5)
    assert cal.offset == pytest.approx(-1.25)
    assert cal.rms_residual == pytest.approx(0.0, abs=1e-12)
    assert cal.max_residual == pytest.approx(0.0, abs=1e-12)
    assert cal.n_points == 5


def test_fit_matches_polyfit_on_noisy_data():
    rng = np.random.default_rng(0)
    x = np.linspace(-10, 10, 50)
    y = -14.0 * x + 0.3 + rng.normal(0, 0.2, x.size)
    cal = fit_linear_calibration(x, y)
    gain, offset = np.polyfit(x, y, 1)
    assert cal.gain == pytest.approx(gain, rel=1e-12)
    assert cal.offset == pytest.approx(offset, rel=1e-10)
    r = y - np.polyval([gain, offset], x)
    assert cal.rms_residual == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-10)


def test_fit_two_points_is_exact():
    cal = fit_linear_calibration([0.0, 1.0], [1.0, 3.0])
    assert (cal.gain, cal.offset, cal.rms_residual) == pytest.approx((2.0, 1.0, 0.0))


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ([1.0], [2.0], "at least 2"),
        ([], [], "at least 2"),
        ([1.0, 2.0, 3.0], [1.0, 2.0], "same length"),
        ([1.0, np.nan, 3.0], [1.0, 2.0, 3.0], "x contains NaN"),
        ([1.0, 2.0, 3.0], [1.0, 2.0, np.inf], "y contains NaN"),
        ([2.0, 2.0, 2.0], [1.0, 2.0, 3.0], "x values are equal"),
        ([1.0, 2.0, 3.0], [5.0, 5.0, 5.0], "gain is zero"),
        ([[1.0, 2.0], [3.0, 4.0]], [[1.0, 2.0], [3.0, 4.0]], "1-D"),
    ],
)
def test_fit_errors(x, y, match):
    with pytest.raises(ValueError, match=match):
        fit_linear_calibration(x, y)
