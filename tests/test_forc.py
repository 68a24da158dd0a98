"""preisach.forc: MicroMag FORC files read, drift-corrected and found by the FORC finder."""

import numpy as np
import pytest
from _paths import PMAGPY_FORC
from preisach import PreisachModel
from preisach.errors import RecordingFormatError
from preisach.forc import read_forc
from preisach.identify.fod_finder import find_forc_curves

LEVELS = np.linspace(-100.0, 100.0, 11)
HEADER = """MicroMag 2900/3900 Data File (Series 0015)
First-order reversal curves
Configuration   :  AGM
Units of measure:  Hybrid SI
04/13/2016  13:20
""

HCal           = +1.000000E+02
NCrv           = {n}
Elapsed time   = +1.000000E+02
NData          = {ndata}

"""


def synthetic_file(path, gains):
    """FORCs of the built-in model from positive saturation, one per level below the top.

    ``gains[k]`` scales curve k and its calibration point (an instrument gain drift).
    Returns the exact output grid ``y[i, j]`` at alpha = LEVELS[i] after beta = LEVELS[j], and
    ``y[n-1, n-1]`` at positive saturation (the finder's layout).
    """
    m = PreisachModel.builtin("ss15-1hz")
    n = LEVELS.size
    grid = np.full((n, n), np.nan)
    blocks = []
    for j, beta in enumerate(LEVELS[:-1][::-1]):  # reversal fields falling, as measured
        jj = n - 2 - j
        sim = m.simulator(m.positive_saturation())
        y_cal = sim.step(100.0)
        sim.step(beta)
        ys = [sim.step(a) for a in LEVELS[jj:]]
        grid[jj:, jj] = ys
        grid[-1, -1] = y_cal
        g = gains[j]
        blocks.append(f"+1.000000E+02,{g * y_cal:+.15E}")
        blocks.append("\n".join(f"{a:+.15E},{g * v:+.15E}" for a, v in zip(LEVELS[jj:], ys)))
    ndata = sum(b.count("\n") + 1 for b in blocks)
    text = HEADER.format(n=n - 1, ndata=ndata) + "\n\n".join(blocks)
    path.write_text(text + "\n\nMicroMag 2900/3900 Data File ends\n")
    return grid


def test_read_correct_and_find_every_curve(tmp_path):
    f = tmp_path / "x.forc"
    gains = np.linspace(1.0, 0.97, LEVELS.size - 1)  # the calibration moment drifts by -3 %
    grid = synthetic_file(f, gains)
    meas = read_forc(f)
    assert len(meas.curves) == LEVELS.size - 1 and meas.calibration.shape == (10, 2)
    assert meas.header["NCrv"] == 10.0 and meas.header["Units of measure"] == "Hybrid SI"
    np.testing.assert_allclose(meas.reversal_fields, LEVELS[:-1][::-1])
    np.testing.assert_allclose(meas.drift()[-1], -0.03, rtol=1e-12)
    fixed = meas.drift_corrected()
    np.testing.assert_allclose(fixed.calibration[:, 1], meas.calibration[0, 1])
    rec = fixed.to_recording()
    assert len(rec) == meas.header["NData"]
    assert rec.metadata["input_units"] == "T" and rec.metadata["output_units"] == "A m^2"
    np.testing.assert_allclose(np.diff(rec.t), 100.0 / len(rec))  # spread over Elapsed time
    found = find_forc_curves(rec.t, rec.u, rec.y, LEVELS)
    assert "10 used, 0 rejected" in found.report()
    np.testing.assert_allclose(found.y_grid, grid, rtol=0, atol=1e-12, equal_nan=True)
    # given the recording, the finder reports in its units (tesla in, A m^2 out), not volts
    assert (found.input_units, found.output_units) == ("V", "V")  # bare arrays: volts
    named = find_forc_curves(rec, levels=LEVELS)
    assert (named.input_units, named.output_units) == ("T", "A m^2")
    text = named.report()
    assert "input range -100 T .. 100 T" in text and "turn [T]" in text
    assert "A m^2\n" in text and " V" not in text  # max spread, an output value
    # without the drift correction the grid is off by the drift
    raw = find_forc_curves(*(lambda r: (r.t, r.u, r.y))(meas.to_recording()), LEVELS)
    assert np.nanmax(np.abs(raw.y_grid - grid)) > 0.01


def test_malformed_files_name_the_line(tmp_path):
    f = tmp_path / "bad.forc"
    synthetic_file(f, np.ones(10))
    lines = f.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("-2.0"))
    lines[k] = "-2.0E+01;3.0"
    f.write_text("\n".join(lines))
    with pytest.raises(RecordingFormatError, match=rf"bad.forc, line {k + 1}: expected"):
        read_forc(f)
    f.write_text(HEADER.format(n=0, ndata=0) + "1.0,2.0\n3.0,4.0\n")  # a curve, no calibration
    with pytest.raises(RecordingFormatError, match="no first-order reversal curve"):
        read_forc(f)
    f.write_text(HEADER.format(n=1, ndata=3) + "1.0,2.0\n3.0,4.0\n\n1.0,2.0\n")
    with pytest.raises(RecordingFormatError, match="alternating"):
        read_forc(f)


@pytest.mark.skipif(not PMAGPY_FORC.exists(), reason=f"{PMAGPY_FORC} is not available")
def test_pmagpy_forc_measurement():
    meas = read_forc(PMAGPY_FORC)
    assert len(meas.curves) == meas.header["NCrv"] == 120
    assert sum(len(c) for c in meas.curves) + len(meas.curves) == meas.header["NData"]
    # each curve two points longer than the one before until they reach the top field
    growth = np.diff([len(c) for c in meas.curves])
    assert np.all(growth[:40] == 2) and np.all(growth >= 0)
    assert np.all(np.diff(meas.reversal_fields) < 0)
    assert -0.02 < meas.drift()[-1] < -0.005  # the calibration moment fell by about 1.3 %
    rec = meas.drift_corrected().to_recording()
    levels = np.r_[np.sort(meas.reversal_fields), rec.u.max()]
    found = find_forc_curves(rec.t, rec.u, rec.y, levels)
    assert "120 used, 0 rejected" in found.report()
    assert np.isfinite(found.y_grid).sum() > 7000
