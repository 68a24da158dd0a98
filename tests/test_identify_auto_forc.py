"""``method="auto"``, the CLI defaults, and FORC files end to end (issue 16)."""

from __future__ import annotations

import numpy as np
import pytest
from _paths import PMAGPY_FORC
from preisach import PreisachModel, Recording
from preisach.cli import main
from preisach.identify.auto import identify, mirror_model
from preisach.noise import uniform_filtered_noise
from preisach.waveforms import fod_sweep

needs_forc = pytest.mark.skipif(not PMAGPY_FORC.exists(), reason=f"{PMAGPY_FORC} is absent")


@pytest.fixture(scope="module")
def truth() -> PreisachModel:
    return PreisachModel.builtin("ss15-1hz")


def _rec(truth, u, seed, **meta):
    y = truth.simulate(u, truth.negative_saturation()).output
    y = y + np.random.default_rng(seed).normal(0.0, 2e-3, y.size)
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3, **meta)


def test_auto_picks_mayergoyz_for_an_fod_sweep_and_least_squares_otherwise(truth):
    rep = identify(_rec(truth, fod_sweep().u, 1))
    assert rep.method == "fod" and "FOD curves measuring 231 of 231" in rep.choice
    assert rep.delay == 0.0
    noise = np.clip(uniform_filtered_noise(8.0, 100.0, seed=3, cutoff=3.0), -100, 100)
    rep = identify(_rec(truth, noise, 2), levels=21)
    assert rep.method == "lsq" and "least squares" in rep.choice
    assert "method chosen automatically" in rep.summary()


def test_mirror_model_is_the_mirrored_system(truth):
    m = mirror_model(truth)
    u = np.clip(uniform_filtered_noise(2.0, 90.0, seed=4, cutoff=5.0), -100, 100)
    y = truth.simulate(u, truth.negative_saturation()).output
    ym = m.simulate(-u, m.positive_saturation()).output
    np.testing.assert_allclose(ym, -y, atol=1e-12)


def test_cli_help_has_no_literal_double_percent(capsys):
    for cmd in ("identify", "verify", "forc"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        out = capsys.readouterr().out
        assert "%%" not in out and "usage" in out


def test_cli_delay_is_honoured_by_fod(truth, tmp_path, capsys):
    rec = _rec(truth, fod_sweep().u, 5, experiment="sweep")
    f = tmp_path / "sweep.csv"
    rec.save(f)
    models = {}
    for d in ("0", "2"):
        out = tmp_path / f"m{d}.npz"
        assert main(["identify", str(f), "-o", str(out), "--method", "fod", "--delay", d]) == 0
        models[d] = PreisachModel.load(out)
    text = capsys.readouterr().out
    assert "output delay: 2 samples" in text
    assert not np.array_equal(models["0"].table.values, models["2"].table.values)
    # verify uses the delay stored in the model file unless --delay says otherwise
    assert main(["verify", str(tmp_path / "m2.npz"), str(f)]) == 0
    assert "output delay 2 samples (stored in" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["identify", str(f), "-o", str(tmp_path / "x.npz"), "--delay", "soon"])
    assert exc.value.code == 2


@needs_forc
def test_identify_a_forc_file_keeps_its_units_and_corrects_drift(tmp_path, capsys):
    out = tmp_path / "forc.npz"
    js = tmp_path / "r.json"
    assert main(["identify", str(PMAGPY_FORC), "-o", str(out), "--json", str(js)]) == 0
    text = capsys.readouterr().out
    assert "120 reversal curves, drift-corrected" in text
    assert "rms (A m^2)" in text and " T;" in text
    model = PreisachModel.load(out)
    assert model.levels.size == 121
    import json

    rep = json.loads(js.read_text())
    assert rep["output_units"] == "A m^2" and rep["input_units"] == "T"
    # the model reproduces the measured curves it was read from (FOD nodes of the mirror)
    assert rep["node_residuals"]["rms_pct"] < 0.01
    assert rep["residuals"][0]["rms_pct"] < 1.0


@needs_forc
def test_forc_diagram_cli_and_agreement_with_pyforc(tmp_path, capsys):
    from preisach.identify.forc_identify import forc_diagram

    fig = tmp_path / "forc.png"
    assert main(["forc", str(PMAGPY_FORC), "--sf", "3", "--plot", str(fig)]) == 0
    assert fig.stat().st_size > 10_000
    out = capsys.readouterr().out
    assert "none outside the measured band" in out
    # the peak away from the band's edge: single-domain-like, H_c about 8.5 mT, H_u about 0
    mine_sf3 = forc_diagram(PMAGPY_FORC, 3)
    full = np.where(mine_sf3.full_window, mine_sf3.rho, -np.inf)
    k = np.unravel_index(int(np.argmax(full)), full.shape)
    assert 0.005 < mine_sf3.h_c[k] < 0.012 and abs(mine_sf3.h_u[k]) < 0.003
    assert f"H_c = {mine_sf3.h_c[k]:.4g} T" in out
    mine = forc_diagram(PMAGPY_FORC, 3, drift=False)
    assert np.all(np.isnan(mine.rho[np.isnan(mine.moment)]))  # nothing outside the band
    pyforc = pytest.importorskip("pyforc")
    from pyforc.core import ops
    from pyforc.core.config import Config
    from pyforc.core.forc import Forc
    from pyforc.core.ingester import PMCIngester
    from scipy.interpolate import RegularGridInterpolator

    assert pyforc is not None
    ref = Forc(
        PMCIngester,
        Config(
            file_name=str(PMAGPY_FORC),
            interpolation="linear",
            pipeline=[ops.interpolate, ops.compute_forc_distribution],
            smoothing_factor=3,
        ),
    ).data
    at = RegularGridInterpolator(
        (mine.h_r, mine.h), mine.rho, bounds_error=False, fill_value=np.nan
    )(np.c_[ref.hr.ravel(), ref.h.ravel()]).reshape(ref.h.shape)
    ok = np.isfinite(at) & np.isfinite(ref.rho)
    a, b = at[ok], ref.rho[ok]
    assert ok.sum() > 6000
    # measured: correlation 0.99995, RMS difference 1.2 % of pyforc's RMS, peaks within 1 %
    assert np.corrcoef(a, b)[0, 1] > 0.999
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.03 * np.sqrt(np.mean(b**2))
    assert abs(a.max() / b.max() - 1.0) < 0.02


@needs_forc
def test_forc_report_plot_is_labelled_in_the_file_units():
    from preisach.identify import identify_forc

    fig = identify_forc(PMAGPY_FORC).plot()
    labels = " ".join(a.get_xlabel() + a.get_ylabel() for a in fig.axes)
    assert "(T)" in labels and "A m^2" in labels and "(V)" not in labels


def test_verification_table_in_the_recording_units(truth):
    from preisach.verify import verify

    rec = _rec(truth, fod_sweep().u[:3000], 6, output_units="um")
    text = verify(truth, rec).table()
    assert "rms (um)" in text and "(V)" not in text
