"""Diagnosis end to end: report schema, figure, augmented model, CLI, residual analysis, errors."""

from __future__ import annotations

import argparse
import importlib
import json
import math
from types import SimpleNamespace

import numpy as np
import preisach
import pytest
from preisach import PreisachModel, Recording, SimulationResult
from preisach.diagnose import (
    AugmentedModel,
    DiagnosisReport,
    FirstOrderInputLag,
    FirstOrderOutputLag,
    SecondOrderMode,
    analyse_residuals,
    diagnose,
    load_model,
)
from preisach.diagnose.cli import add_parser
from preisach.diagnose.data import prepare_recordings
from preisach.diagnose.scoring import Score, nameable_rms
from preisach.studies.diagnosis_cases import make_case
from scipy import signal


@pytest.fixture(scope="module")
def delay_case():
    return make_case("delay", seed=21, scale=0.3, effect_size=4.0)


@pytest.fixture(scope="module")
def delay_report(delay_case):
    model = (
        delay_case.identify()
    )  # a few candidates keep this quick; test_diagnose_proof runs them all
    return diagnose(
        model,
        delay_case.recordings,
        identification=delay_case.identification,
        candidates=["delay", "creep", "gain_offset", "sensor_drift"],
    )


def test_package_exports():
    assert preisach.diagnose is diagnose
    assert preisach.load_model is load_model
    assert preisach.AugmentedModel is AugmentedModel and preisach.DiagnosisReport is DiagnosisReport


def test_json_has_exactly_the_issue_schema(delay_report, tmp_path):
    text = delay_report.to_json(tmp_path / "r.json")
    d = json.loads((tmp_path / "r.json").read_text())
    assert d == json.loads(text)
    assert set(d) == {
        "verdict",
        "effects",
        "rmse_before",
        "rmse_after",
        "noise_sigma",
        "noise_test",
        "unexplained",
        "base_grid",
        "candidates",
    }
    # the step table: every fit of every step, the kept one the first effect's form
    rows = d["candidates"]
    assert {r["step"] for r in rows} == set(range(1, max(r["step"] for r in rows) + 1))
    kept = [r for r in rows if r["kept"]]
    assert len(kept) == len(d["effects"]) and kept[0]["name"].split("/")[0] == "delay"
    assert kept[0]["heldout_rmse"] < kept[0]["baseline_rmse"] and kept[0]["p_value"] < 0.01
    assert all(r["decision"] for r in rows if not r["kept"])
    assert set(d["noise_test"]) == {
        "ratio",
        "threshold",
        "classical",
        "holds",
        "loops_beside",
        "consistent",
        "nameable",
    }
    assert set(d["noise_test"]["nameable"]) == {"rms", "ratio", "statement"}
    assert "further effect" in d["noise_test"]["nameable"]["statement"]  # one was kept
    assert d["noise_test"]["holds"] is None  # an effect was kept: no hold test
    beside = d["noise_test"]["loops_beside"]  # an effect was kept: the loops read beside it
    assert beside is not None and "non_congruence" not in [e["name"] for e in d["effects"]]
    assert beside["found_by"] == [] and isinstance(beside["moves"], bool), beside
    assert d["noise_test"]["classical"] is None  # an effect was kept: no resolution check
    assert d["verdict"] == "delay"
    for e in d["effects"]:
        assert set(e) - {"holds"} == {
            "name",
            "evidence",
            "where",
            "parameters",
            "heldout_rmse_before",
            "heldout_rmse_after",
        }
        assert e["heldout_rmse_after"] < e["heldout_rmse_before"]
        for p in e["parameters"].values():
            assert {"value", "std", "unit"} <= set(p)
    first = d["effects"][0]
    # the case's delay is a first-order lag (studies.diagnosis_cases): the form that names it
    assert first["name"] == "delay" and "first-order filter" in first["evidence"]
    assert set(first["where"]) >= {"recordings", "direction", "near_reversals", "band_Hz"}
    assert d["rmse_after"] < d["rmse_before"]


def test_report_statement_parameters_and_uncertainty(delay_case, delay_report):
    e = delay_report.effects[0]
    tau = e.parameters["tau"]
    assert tau["unit"] == "s" and tau["std"] > 0
    assert tau["value"] == pytest.approx(delay_case.truth["strength"], rel=0.2)
    import re

    stated = re.search(r"time constant ([0-9.]+) ± ([0-9.]+) ms", e.statement)
    assert stated is not None
    assert float(stated.group(1)) == pytest.approx(1e3 * tau["value"], abs=float(stated.group(2)))
    text = delay_report.summary()
    assert "verdict: delay" in text and "candidates" in text and "residual RMS" in text
    kept = next(c for c in delay_report.candidates if c["kept"])  # table in mV, like the rest
    assert f"{1e3 * kept['heldout_rmse']:8.4g} mV" in text
    det = delay_report.details()
    json.dumps(det)  # everything is JSON-serialisable
    assert det["candidates"] and det["before"]["covariates"]


def test_plot_returns_a_labelled_figure(delay_report):
    from matplotlib.figure import Figure

    fig = delay_report.plot()
    assert isinstance(fig, Figure)
    axes = [a for a in fig.axes if a.get_visible()]
    assert len(axes) >= 6
    for ax in axes:
        assert ax.get_ylabel()
    units = " ".join(a.get_xlabel() + a.get_ylabel() for a in axes)
    for u in ("(s)", "(mV)", "(Hz)", "(V)"):
        assert u in units


def test_augmented_model_round_trip_and_simulation(delay_report, delay_case, tmp_path):
    aug = delay_report.model
    assert any(isinstance(b, FirstOrderOutputLag) for b in aug.blocks)  # the case's lag
    path = tmp_path / "aug.npz"
    aug.save(path)
    back = load_model(path)
    assert isinstance(back, AugmentedModel) and back == aug
    u = delay_case.recordings[0].u
    r1 = aug.simulate(u, aug.negative_saturation())
    r2 = back.simulate(u, back.negative_saturation())
    assert isinstance(r1, SimulationResult)
    np.testing.assert_array_equal(r1.output, r2.output)
    t, y = r1
    assert t.shape == y.shape == u.shape
    with pytest.raises(ValueError, match="not a preisach model"):
        PreisachModel.load(path)


def test_augmented_model_is_the_chain():
    base = PreisachModel.builtin("ss15-1hz", levels=41)
    lag = FirstOrderInputLag(1e-3, tau=2e-3)
    mode = SecondOrderMode(1e-3, f_n=40.0, zeta=0.05, participation=0.3)
    aug = AugmentedModel(base, [mode, lag])
    u = 80 * np.sin(np.linspace(0, 20, 4000))
    s0 = base.negative_saturation()
    got = aug.simulate(u, s0)
    lag.reset(s0.input)
    x = lag.run(u)
    yp = base.simulate(x, s0).output
    mode.reset(base.readout(s0))
    np.testing.assert_allclose(got.output, mode.run(yp), atol=1e-12)
    np.testing.assert_allclose(got.extra["preisach_output"], yp, atol=1e-12)
    # same physics at another sample time
    half = aug.simulate(u[::2], s0, sample_time=2e-3)
    assert (
        np.max(np.abs(half.output[200:] - got.output[::2][200:])) < 0.02
    )  # after the start-up step
    with pytest.raises(ValueError, match="outside the model range"):
        aug.simulate([0.0, 150.0], s0, out_of_range="raise")
    with pytest.raises(ValueError, match=r"u\[1\] is not finite"):
        aug.simulate([0.0, np.nan], s0)


def test_load_model_reads_both_kinds(tmp_path):
    m = PreisachModel.builtin("ss15-2hz", levels=21)
    m.save(tmp_path / "m.npz")
    assert load_model(tmp_path / "m.npz") == m
    (tmp_path / "junk.npz").write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not a readable model file"):
        load_model(tmp_path / "junk.npz")


def test_cli_writes_report_figure_and_model(delay_case, tmp_path, capsys):
    delay_case.save(tmp_path / "case")
    model = delay_case.identify()
    model.save(tmp_path / "model.npz")
    parser = argparse.ArgumentParser(prog="preisach")
    add_parser(parser.add_subparsers(dest="command"))
    recs = [
        str(p) for p in sorted((tmp_path / "case").glob("*.npz")) if p.name != "identification.npz"
    ]
    args = parser.parse_args(
        [
            "diagnose",
            str(tmp_path / "model.npz"),
            *recs,
            "--json",
            str(tmp_path / "r.json"),
            "--candidates",
            "delay,creep",
            "--plot",
            str(tmp_path / "r.png"),
            "--save-model",
            str(tmp_path / "aug.npz"),
            "--identification",
            str(tmp_path / "case" / "identification.npz"),
            "-q",
        ]
    )
    assert args.func(args) == 0
    assert json.loads((tmp_path / "r.json").read_text())["verdict"] == "delay"
    assert (tmp_path / "r.png").stat().st_size > 10_000
    assert isinstance(load_model(tmp_path / "aug.npz"), AugmentedModel)
    assert capsys.readouterr().out == ""
    bad = parser.parse_args(
        ["diagnose", str(tmp_path / "nope.npz"), recs[0], "--json", str(tmp_path / "x.json")]
    )
    with pytest.raises(OSError, match="no such file"):
        bad.func(bad)


def _recs_with(effect: str, seed: int = 3):
    """Recordings of a built-in model with one planted residual (for the residual analysis)."""
    m = PreisachModel.builtin("ss15-1hz", levels=41)
    rng = np.random.default_rng(seed)
    recs = []
    for k in range(3):
        t = np.arange(6000) * 1e-3
        u = -100 + 100 * (1 - np.cos(2 * np.pi * (0.7 + 0.3 * k) * t)) * (0.6 + 0.1 * k)
        y = m.simulate(u, m.negative_saturation()).output
        if effect == "delay":
            y = np.interp(t - 4e-3, t, y)
        elif effect == "ringing":
            y = y + 3e-3 * np.sin(2 * np.pi * 43.0 * t)
        elif effect == "drift":
            y = y + 5e-3 * t / t[-1]
        y = y + rng.normal(0, 1e-3, t.size)
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"r{k}"))
    return m, recs


def _analysis(effect: str):
    m, recs = _recs_with(effect)
    prep = prepare_recordings(m, recs)
    pred = [m.simulate(r.u, r.state0).output for r in prep]
    res = [r.y - p for r, p in zip(prep, pred)]
    return analyse_residuals(prep, res, pred, 1e-3, u_span=200.0)


def test_locate_finds_what_the_residual_follows():
    a = _analysis("delay")
    strongest = a.strongest(1)[0]
    assert (
        strongest.name in ("model output rate dy/dt", "input rate du/dt") and strongest.eta2 > 0.5
    )
    b = _analysis("ringing")
    assert b.spectrum["peaks"] and abs(b.spectrum["peaks"][0]["f"] - 43.0) < 1.0
    c = _analysis("drift")
    assert c.covariates["time"].p_value < 0.01 and c.covariates["time"].eta2 > 0.5
    n = _analysis("none")
    assert n.rms == pytest.approx(1e-3, rel=0.1)
    assert all(cv.eta2 < 0.05 for cv in n.covariates.values())
    assert "residual RMS" in n.summary()[0]


def test_noise_alone_gives_verdict_none():
    m, recs = _recs_with("none")
    rep = diagnose(m, recs, candidates=["delay", "gain_offset", "creep"])
    assert rep.verdict == "none" and rep.effects == []
    assert rep.rmse_after == pytest.approx(rep.rmse_before)


def test_report_states_amounts_in_the_recordings_output_unit():
    """A magnetometer's moment (A m^2) is reported in A m^2, never in mV; volts in mV."""
    from preisach._display import diagnosis_html

    m, recs = _recs_with("none")
    moment = [
        Recording.from_arrays(t=r.t, u=r.u, y=1.05 * r.y + 0.02, output_units="A m^2") for r in recs
    ]
    lines: list[str] = []  # the progress lines printed while it runs, in the unit too
    rep = diagnose(m, moment, candidates=["gain_offset"], progress=lines.append)
    assert rep.verdict == "gain_offset" and rep.unit == "A m^2"
    assert not [s for s in lines if "mV" in s], lines
    assert [s for s in lines if "gain_offset: held-out RMSE" in s and "A m^2 (" in s], lines
    text, html = rep.summary(), diagnosis_html(rep, figure=False)
    assert "A m^2 from the model's" in rep.effects[0].statement  # the offset, in its unit
    assert "mV" not in text and "mV" not in html, text
    assert f"{rep.rmse_before:.4g} A m^2 (given model)" in text
    assert "held-out RMSE (A m^2)" in html
    assert rep.details()["unit"] == "A m^2"
    volts = [Recording.from_arrays(t=r.t, u=r.u, y=r.y) for r in moment]
    assert "mV (given model)" in diagnose(m, volts[:1], candidates=["gain_offset"]).summary()
    with pytest.raises(ValueError, match="different units"):
        diagnose(m, [moment[0], volts[1]], candidates=["gain_offset"])


def test_effect_outside_every_candidate_is_unexplained_not_none():
    """A 37 Hz square-wave pickup (5 x the noise) that no candidate offered can fit."""
    m, recs = _recs_with("none")
    for r in recs:
        r.y[:] = r.y + 5e-3 * np.sign(np.sin(2 * np.pi * 37.0 * r.t))
    rep = diagnose(m, recs, candidates=["delay", "gain_offset", "creep"])
    assert rep.effects == [] and rep.verdict == "unexplained"
    assert rep.noise_test["ratio"] > 3 and not rep.noise_test["consistent"]
    un = rep.unexplained
    assert un is not None and un["ratio"] == rep.noise_test["ratio"]
    assert un["where"]["peak_Hz"] == pytest.approx(37.0, abs=2.0)
    assert "x the noise" in un["statement"] and "Hz" in un["statement"]
    assert json.loads(rep.to_json())["verdict"] == "unexplained"
    # the same recordings without the pickup: consistent with the noise
    m, clean = _recs_with("none")
    rep0 = diagnose(m, clean, candidates=["delay", "gain_offset", "creep"])
    assert rep0.verdict == "none" and rep0.noise_test["consistent"] and rep0.unexplained is None


def test_a_verdict_without_effects_says_the_smallest_effect_it_could_name():
    """The limit is the selection's own gain and noise bars, read back from the candidate table.

    A 37 Hz pickup of 5 x the noise that no candidate offered can fit: ``unexplained``.  Every
    candidate of the last step explained a part ``sqrt(baseline^2 - heldout^2)`` of the
    held-out residual; exactly those whose part reaches ``noise_test.nameable.rms`` passed
    both bars.  Fails when the limit or its note is dropped, or drifts from the bars.
    """
    m, recs = _recs_with("none")
    for r in recs:
        r.y[:] = r.y + 5e-3 * np.sign(np.sin(2 * np.pi * 37.0 * r.t))
    rep = diagnose(m, recs, candidates=["delay", "gain_offset", "creep"], progress=False)
    assert rep.verdict == "unexplained"
    nt = rep.noise_test
    lim = nt["nameable"]
    assert lim["rms"] == pytest.approx(math.sqrt(1 - 0.9**2) * rep.rmse_after, rel=1e-9)
    assert lim["ratio"] == pytest.approx(lim["rms"] / rep.noise_sigma)
    assert lim["ratio"] > 1.5  # the gain bar, not the noise bar, sets it here
    assert lim["statement"] in rep.notes and "is not excluded" in lim["statement"]
    last = max(row["step"] for row in rep.candidates)
    rows = [row for row in rep.candidates if row["step"] == last]
    assert rows and all(row["baseline_rmse"] == pytest.approx(rep.rmse_after) for row in rows)
    for row in rows:
        part = math.sqrt(max(row["baseline_rmse"] ** 2 - row["heldout_rmse"] ** 2, 0.0))
        passed = row["gain"] >= 0.10 and row["explained_noise_variances"] >= 1.0
        assert (part >= lim["rms"]) == passed, row
    # a residual within one noise variance of nothing: no effect could pass
    assert nameable_rms(0.9e-3, 1e-3, 0.10, 1.0) == pytest.approx(1e-3)
    assert nameable_rms(10e-3, 1e-3, 0.10, 1.0) == pytest.approx(10e-3 * math.sqrt(0.19))
    assert json.loads(rep.to_json())["noise_test"]["nameable"]["rms"] == pytest.approx(lim["rms"])


def test_a_score_measures_the_three_bars_against_another():
    """Gain, noise variances explained and sign-flip p: one helper for every comparison.

    Ten held-out blocks of 100 samples each; the fit lowers every block's SSE from 4 to 1
    (sigma 0.1): RMSE 0.2 -> 0.1 (50 %), MSE 0.04 -> 0.01 (3 noise variances), and a
    sign-flip p as small as ten blocks allow (1/1024, within the Monte Carlo count).  The
    reverse comparison gains -100 % at p near 1.
    """
    n = np.full(10, 100)

    def score(sse: float) -> Score:
        return Score(np.full(10, sse), n, [], [])

    base, fit = score(4.0), score(1.0)
    gain, expl, p = fit.improvement(base, 0.1)
    assert gain == pytest.approx(0.5) and expl == pytest.approx(3.0)
    assert p < 0.01
    gain, expl, p = base.improvement(fit, 0.1)
    assert gain == pytest.approx(-1.0) and expl == pytest.approx(-3.0) and p > 0.99


def test_unexplained_names_the_nearest_fit_and_why_it_was_not_named():
    """A 120 ms after-effect of 1 % of every move: the creep bank predicts it, but not as creep.

    The sensor (or a viscous layer) relaxes by 1 % of each output move with a 120 ms time
    constant - over long before a second, so not creep.  Fails when the unexplained
    verdict stops telling what predicted the residual and why it was not named.
    """
    m, recs = _recs_with("none")
    a = np.exp(-1e-3 / 0.12)
    for r in recs:
        p = m.simulate(r.u, m.negative_saturation()).output
        lag = signal.lfilter([1 - a], [1, -a], p, zi=[a * p[0]])[0]
        r.y[:] = r.y + 0.01 * (lag - p)
    rep = diagnose(m, recs, candidates=["creep"], progress=False)
    assert rep.verdict == "unexplained", rep.summary()
    near = rep.unexplained["nearest"]
    assert [o["effect"] for o in near] == ["creep"] and near[0]["gain"] > 0.3, near
    assert "over within a second" in near[0]["why_not"], near
    assert "nearest, not named: creep (" in rep.unexplained["statement"]
    assert json.loads(rep.to_json())["unexplained"]["nearest"][0]["effect"] == "creep"


def test_model_file_carries_its_identification(tmp_path):
    """Round trip of the identification recordings; files without them stay version 1."""
    m, recs = _recs_with("none")
    plain = tmp_path / "plain.npz"
    m.save(plain)
    with np.load(plain) as z:
        assert int(z["version"]) == 1 and "ident_meta" not in z.files
    assert PreisachModel.load(plain).identification == []
    m.identification = recs[:2]
    full = tmp_path / "full.npz"
    m.save(full)
    with np.load(full) as z:
        assert int(z["version"]) == 2
    back = PreisachModel.load(full)
    assert back == m and len(back.identification) == 2
    for a, b in zip(back.identification, recs[:2]):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.u, b.u)
        np.testing.assert_array_equal(a.y, b.y)
        assert a.metadata == b.metadata
    # diagnose uses them by default (training only), and not when told not to
    lines: list[str] = []
    diagnose(back, recs[2:], candidates=["gain_offset"], progress=lines.append)
    assert lines[0].startswith("1 recordings (2 for identification)")
    lines.clear()
    diagnose(back, recs[2:], identification=[], candidates=["gain_offset"], progress=lines.append)
    assert lines[0].startswith("1 recordings (0 for identification)")


def test_identify_cli_stores_the_recordings_and_diagnose_uses_them(tmp_path, capsys):
    from preisach.cli import main

    m, recs = _recs_with("none")
    paths = []
    for k, r in enumerate(recs):
        paths.append(str(tmp_path / f"r{k}.csv"))
        r.save(paths[-1])
    model = str(tmp_path / "m.npz")
    assert main(["identify", paths[0], "-o", model, "--method", "lsq", "--levels", "11"]) == 0
    stored = PreisachModel.load(model).identification
    assert len(stored) == 1 and np.allclose(stored[0].y, recs[0].y)
    out = str(tmp_path / "r.json")
    argv = ["diagnose", model, *paths[1:], "--json", out, "--candidates", "gain_offset"]
    assert main(argv) == 0
    assert "2 recordings (1 for identification)" in capsys.readouterr().out
    assert main([*argv, "--no-stored-identification"]) == 0
    assert "2 recordings (0 for identification)" in capsys.readouterr().out


def test_argument_errors():
    m, recs = _recs_with("none")
    with pytest.raises(ValueError, match="unknown candidate 'telepathy'"):
        diagnose(m, recs, candidates=["telepathy"])
    with pytest.raises(ValueError, match="alpha"):
        diagnose(m, recs, alpha=2.0)
    with pytest.raises(ValueError, match="at least one recording"):
        diagnose(m, [])
    with pytest.raises(TypeError, match="PreisachModel"):
        diagnose("ss15-1hz", recs)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="initial_states: expected 3"):
        diagnose(m, recs, initial_states=["unknown"])
    with pytest.raises(ValueError, match="cv"):
        diagnose(m, recs, cv="folds")


def test_identification_recording_is_not_diagnosed_twice():
    """A recording that is also identification data is left out of the diagnosed set."""
    m, recs = _recs_with("none")
    lines: list[str] = []
    copy = Recording.from_arrays(t=recs[0].t, u=recs[0].u.copy(), y=recs[0].y.copy())
    with pytest.warns(UserWarning, match="same samples as an identification recording") as w:
        rep = diagnose(
            m, recs, identification=copy, candidates=["gain_offset"], progress=lines.append
        )
    assert w[0].filename == __file__  # the warning points at the caller
    assert lines[0].startswith("2 recordings (1 for identification)")
    assert rep.verdict == "none"
    with (
        pytest.raises(ValueError, match="every recording is also an identification recording"),
        pytest.warns(UserWarning, match="same samples"),
    ):
        diagnose(m, recs[:1], identification=copy)


def test_diagnosis_limits_blas_to_one_thread(monkeypatch):
    """Thousands of small solves between multi-threaded C++ loops: BLAS threads only compete."""

    from threadpoolctl import threadpool_info, threadpool_limits

    core = importlib.import_module("preisach.diagnose.core")
    seen: list[list[int]] = []
    real = core.run_selection

    def spy(*args, **kwargs):
        seen.append([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"])
        return real(*args, **kwargs)

    monkeypatch.setattr(core, "run_selection", spy)
    m, recs = _recs_with("none")
    with threadpool_limits(limits=2, user_api="blas"):
        before = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
        diagnose(m, recs, candidates=["gain_offset"])
        after = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    assert seen and seen[0] and set(seen[0]) == {1}
    assert after == before  # the caller's setting is back afterwards


def test_own_generator_shapes_are_not_the_candidates():
    """The own truths' rate smoothing and feedback centre are random, not the candidates'."""
    from preisach.studies.diagnosis_cases import _truth_params

    m = PreisachModel.builtin("ss15-1hz", levels=41)
    lo, span = m.y_min, m.y_max - m.y_min
    nc = [_truth_params("non_congruence", np.random.default_rng(s), m) for s in range(40)]
    share = np.array([(p["y_c"] - lo) / span for p in nc])
    assert np.all((share >= 0.25) & (share <= 0.75)) and np.ptp(share) > 0.3
    assert np.all(np.abs(share - 0.5) > 1e-6)
    assert {p["sign"] for p in nc} == {-1.0, 1.0}
    tau = np.array(
        [
            _truth_params("rate_dependence", np.random.default_rng(s), m)["rho_tau"]
            for s in range(40)
        ]
    )
    assert np.all((tau >= 5e-3) & (tau <= 0.1)) and tau.max() / tau.min() > 5


def test_candidate_blocks_are_not_shared_between_threads():
    """The per-recording threads of a fit must not run one block's state at once."""
    from concurrent.futures import ThreadPoolExecutor

    from preisach.diagnose.candidates import CreepCandidate
    from preisach.diagnose.context import Context

    m, recs = _recs_with("none")
    ctx = Context(m, prepare_recordings(m, recs))
    cand = CreepCandidate()
    cand.prepare(ctx)
    x = np.full(len(cand.specs(ctx)), 0.01)
    here = cand.block(x, 1e-3)
    assert cand.block(x, 1e-3) is here  # cached within a thread
    with ThreadPoolExecutor(2) as ex:
        there = ex.submit(cand.block, x, 1e-3).result()
    assert there is not here and type(there) is type(here)


def test_unknown_initial_state_is_a_nuisance_not_a_mask():
    """A recording that never visits both extremes is diagnosed whole, from the right history."""
    m = PreisachModel.builtin("ss15-1hz", levels=41)
    t = np.arange(3000) * 1e-3
    u = -20 + 40 * np.sin(2 * np.pi * 1.0 * t)  # mid-range, never near the range ends
    came_from_above = m.simulate(np.array([m.u_max, u[0]]), m.positive_saturation()).final_state
    y = m.simulate(u, came_from_above).output + np.random.default_rng(1).normal(0, 1e-3, t.size)
    rec = Recording.from_arrays(t=t, u=u, y=y, experiment="mid")
    (prep,) = prepare_recordings(m, [rec])
    assert prep.usable.all()
    assert prep.start.startswith("unknown: fell from positive saturation")
    (old,) = prepare_recordings(m, [rec], initial_states=["anhysteretic"])
    assert old.start == "anhysteretic"


def test_start_up_ring_is_evidence_not_masked():
    """A recording that starts with a step from 0 V to a range end rings on the rig's mode.

    As in issue 13's stack recording (5 kHz, a ~1 kHz ring for ~10 ms after the first step):
    every sample is scored, and the ring is named or localised at the start - not masked
    (verdict ``none``) and not called a drift.
    """
    from preisach.daq.blocks import BlockChain, make_block, preisach_stage

    m = PreisachModel.builtin("ss15-1hz", levels=41)
    dt = 2e-4
    t = np.arange(2000) * dt
    u = np.interp(t, [0, dt, 0.1, 0.25, 0.4], [0.0, -100.0, -100.0, 100.0, -100.0])
    chain = BlockChain(
        [
            preisach_stage(m, m.anhysteretic_state(), dt, 0.0),
            make_block({"kind": "structural_mode", "frequency": 1000.0, "damping": 0.02}, dt),
        ]
    )
    chain.reset(0.0)
    y = np.asarray(chain.run(u)) + np.random.default_rng(4).normal(0, 1e-3, t.size)
    rec = Recording.from_arrays(t=t, u=u, y=y, experiment="step_start")
    (prep,) = prepare_recordings(m, [rec])
    assert prep.start.startswith("unknown") and prep.usable.all()
    rep = diagnose(
        m, [rec], candidates=["structural_resonance", "sensor_drift", "creep"], progress=False
    )
    assert rep.verdict in ("structural_resonance", "unexplained"), rep.summary()
    if rep.verdict == "unexplained":
        assert rep.unexplained is not None
        when = rep.unexplained["where"]["time_s"]
        assert when["at_start"] and when["to"] < 0.05, rep.unexplained["statement"]


def test_drift_that_follows_the_steps_is_not_a_drift():
    """The drift test: a slow response to the output's moves is creep-like, a ramp is not."""
    from preisach.diagnose.context import Chain, Context, signal_lag

    m = PreisachModel.builtin("ss15-1hz", levels=41)
    t = np.arange(8000) * 1e-3
    u = np.repeat([-90.0, 40.0, -30.0, 80.0, -60.0, 20.0, -80.0, 60.0], 1000)
    p = m.simulate(u, m.negative_saturation()).output
    noise = np.random.default_rng(2).normal(0, 1e-3, t.size)
    creep = 0.03 * (signal_lag(p, np.exp(-1e-3 / 0.5)) - p)
    shares = {}
    for name, extra in (("creep", creep), ("ramp", 0.02 * t / t[-1])):
        rec = Recording.from_arrays(t=t, u=u, y=p + extra + noise, experiment=name)
        ctx = Context(m, prepare_recordings(m, [rec]))
        shares[name] = ctx.drift_step_share(Chain(ctx.given))
    assert shares["creep"] > 0.5 > shares["ramp"]


def test_a_mode_that_does_not_ring_is_not_a_resonance():
    from types import SimpleNamespace

    from preisach.diagnose.candidates import DelayCandidate, ModeCandidate

    ctx = SimpleNamespace(dt_min=1e-3, max_delay=0.05, noise_sigma=0.0, y_span=1.0)
    mode = ModeCandidate()
    assert "does not ring" in mode.implausible(np.array([49.0, 0.49, 1.0]), ctx)
    assert mode.implausible(np.array([49.0, 0.05, 1.0]), ctx) is None
    assert "bound" in DelayCandidate().implausible(np.array([0.05]), ctx)
    assert DelayCandidate().implausible(np.array([0.003]), ctx) is None


def test_a_general_block_that_shows_nothing_does_not_refuse_a_mode():
    """A mode is refused when the general linear block shows a delay or a lag, not nothing.

    The equation-error block can miss a lightly damped pole pair in noisy outputs (blind
    seed 49's case 008, 32 Hz at damping ratio 0.0055, and seed 51's case 013, two modes at
    31 and 88 Hz: the mode forms gained 50-64 % and were refused, "no linear dynamics").
    """
    from types import SimpleNamespace

    from preisach.diagnose.candidates import ModeCandidate
    from preisach.diagnose.linear_block import Classification

    def cls(kind: str, reason: str) -> Classification:
        nan = float("nan")
        return Classification(kind, 0.0, nan, nan, nan, nan, reason)

    ctx = SimpleNamespace(dt_min=1e-3, max_delay=0.05, noise_sigma=0.0, y_span=1.0)
    mode = ModeCandidate()
    x = np.array([32.0, 0.01, 1.0])
    mode._classes = [cls("none", "no linear dynamics")] * 2
    assert mode.implausible(x, ctx) is None
    mode._classes = [cls("none", "no linear dynamics"), cls("lag", "a first-order lag")]
    assert "a first-order lag" in mode.implausible(x, ctx)


def test_a_mode_whose_ring_stays_below_the_noise_is_not_a_resonance():
    """A step across the output span must ring above the noise for a mode to be named.

    Blind seed 56's null 003 was named a 2.43 Hz mode (damping ratio 0.0035, participation
    0.00062 and reaction -0.00061 to the acceleration, so 0.0000097 of a step rings: 0.13 mV
    over its 13.5 V span, 0.08 x the noise) beside a general block that showed nothing.
    Seed 49's case 008, a true 32 Hz mode behind the same block, rings by 85 x the noise.
    """
    from types import SimpleNamespace

    from preisach.diagnose.candidates import ModeCandidate, ModeReactionCandidate
    from preisach.diagnose.linear_block import Classification

    nan = float("nan")
    shows_nothing = Classification("none", 0.0, nan, nan, nan, nan, "no linear dynamics")
    ctx = SimpleNamespace(
        dt_min=1e-3, max_delay=0.05, noise_sigma=1.6e-3, y_span=13.5, output_unit="V"
    )
    react = ModeReactionCandidate()
    react._classes = [shows_nothing] * 2
    why = react.implausible(np.array([2.43, 0.0035, 0.00062, -0.00061]), ctx)
    assert why is not None and "rings visibly" in why and "0.084 x the noise" in why
    assert react.implausible(np.array([32.4, 0.0055, 0.181, -0.165]), ctx) is None
    # the participation alone: 0.3 mV of a 13.5 V step is 2.5 x the noise, 0.5 mV is 4.2 x
    mode = ModeCandidate()
    mode._classes = [shows_nothing] * 2
    assert "2.5 x the noise" in str(mode.implausible(np.array([32.0, 0.01, 0.0003]), ctx))
    assert mode.implausible(np.array([32.0, 0.01, 0.0005]), ctx) is None
    # the noise not yet known: no check
    ctx.noise_sigma = 0.0
    assert mode.implausible(np.array([32.0, 0.01, 0.0003]), ctx) is None


def _session_recs():
    """Two recordings of one session: the second starts where the first left the relays.

    The first goes up to 90 V (beyond the second's range), the second stays within
    -60..40 V, so for its whole length it keeps what the first left above 40 V.
    """
    m = PreisachModel.builtin("ss15-1hz", levels=41)
    rng = np.random.default_rng(7)
    t = np.arange(3000) * 1e-3
    u1 = np.interp(t, [0, 0.5, 1.5, 2.2, 3.0], [0.0, 90.0, -95.0, 60.0, 0.0])
    u2 = -10.0 + 50.0 * np.sin(2 * np.pi * 1.3 * t) * np.exp(-0.2 * t)
    first = m.simulate(u1, m.anhysteretic_state())
    left = m.simulate(np.array([u2[0]]), first.final_state).final_state
    second = m.simulate(u2, left)
    recs = [
        Recording.from_arrays(t=t, u=u, y=y + rng.normal(0, 1e-3, t.size), experiment=name)
        for name, u, y in (("a", u1, first.output), ("b", u2, second.output))
    ]
    return m, recs


def test_session_history_is_the_state_the_previous_recording_left():
    """The second recording of a session starts from what the first left: no free offset."""
    m, recs = _session_recs()
    a, b = prepare_recordings(m, recs)
    assert b.session is not None and b.start == "unknown: left by 'a'"
    sim = m.simulate(b.u, b.state0).output
    assert np.sqrt(np.mean((b.y - sim) ** 2)) < 1.5e-3  # the noise: the state is right
    # alone (no earlier recording) no history of the choice gives that state
    (alone,) = prepare_recordings(m, recs[1:])
    assert alone.session is None and "left by" not in alone.start
    sim = m.simulate(alone.u, alone.state0).output
    assert np.sqrt(np.mean((alone.y - sim) ** 2)) > 5e-3
    # another history still wins when it fits better: after a recording that left the
    # anhysteretic state, "left by" is the wrong state for the second recording
    t = recs[0].t
    y0 = m.simulate(np.zeros_like(t), m.anhysteretic_state()).output
    quiet = Recording.from_arrays(t=t, u=np.zeros_like(t), y=y0, experiment="quiet")
    _, b2 = prepare_recordings(m, [quiet, recs[1]])
    assert "left by" not in b2.start, b2.start


def test_refit_base_is_chosen_when_the_model_grid_fails():
    """A 21-level refit that leaves far more than the noise is replaced, and said so.

    A device with a fine Preisach density (161 levels) identified by a 21-level model; the
    least-squares refit of the 21 levels with the default ridge predicts held-out blocks at
    ~20 x the noise (weakly constrained weights); the firmer base is chosen, the verdict is
    ``none`` (no physical effect) and the JSON says which base was used and why.
    """
    dev = PreisachModel.builtin("ss15-1hz", levels=161)
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    rng = np.random.default_rng(0)
    lo, hi = m.u_min, m.u_max

    def rec(u, name):
        t = np.arange(u.size) * 1e-3
        y = dev.simulate(u, dev.negative_saturation()).output + rng.normal(0, 1e-3, u.size)
        return Recording.from_arrays(t=t, u=u, y=y, experiment=name)

    pts = [lo]
    for a in np.linspace(1, 0.1, 10):
        pts += [lo + a * (hi - lo), lo]
    ident = rec(
        np.concatenate([np.linspace(pts[k], pts[k + 1], 300) for k in range(len(pts) - 1)]), "id"
    )
    t = np.arange(4000) * 1e-3
    exps = [
        rec(
            lo
            + (hi - lo)
            * 0.5
            * (1 - np.cos(2 * np.pi * f * t))
            * (0.35 + 0.3 * np.abs(np.sin(2 * np.pi * 0.23 * t + k))),
            f"e{k}",
        )
        for k, f in enumerate((1.3, 2.1))
    ]
    rep = diagnose(m, exps, identification=[ident], candidates=["gain_offset"], progress=False)
    g = rep.base_grid
    assert g is not None and g["changed"] and g["p_value"] < 0.01, g
    assert g["ratio"]["model grid"] > 5 and rep.noise_test["ratio"] < 2, g
    assert rep.verdict == "none" and rep.unexplained is None
    assert g["statement"] in rep.notes
    assert json.loads(rep.to_json())["base_grid"]["levels"] == g["levels"]


def test_unknown_starts_are_named_when_non_congruence_is_not_found():
    """The report says when non-congruence was tried on recordings of unknown initial state.

    Fails when the note goes missing although non-congruence was tried and not kept on
    recordings that start from an unknown state, or appears when their states are known,
    non-congruence was kept, or it was not tried.
    """
    from types import SimpleNamespace

    from preisach.diagnose.core import _unknown_start_note

    def ctx(*histories):
        recs = [SimpleNamespace(history=h) for h in histories]
        return SimpleNamespace(recs=recs, diag=list(range(len(recs))))

    tried = [SimpleNamespace(scores={"non_congruence": None, "delay": None})]
    note = _unknown_start_note(ctx("unknown", None, "unknown"), tried, ["delay"])
    assert note is not None and note.startswith("2 of 3 recordings start from an unknown")
    assert "saturation" in note
    assert _unknown_start_note(ctx(None, None), tried, []) is None  # known states
    assert _unknown_start_note(ctx("unknown"), tried, ["non_congruence"]) is None  # kept
    untried = [SimpleNamespace(scores={"delay": None})]
    assert _unknown_start_note(ctx("unknown"), untried, []) is None


def test_a_rival_name_is_said_with_the_experiment_that_separates_them():
    """The kept effect's evidence names the best other name and how to tell the two apart.

    A qualifying rival not significantly worse over the held-out blocks makes the choice
    AMBIGUOUS (with the report's entry); one significantly worse but with most of the gain is
    nearly as good - blind seed 38's slow creep 014 was named ``sensor_drift`` with creep
    at 32 % against 35 %, and the evidence named no experiment.  Another form of the kept
    name is no rival, and a weak other name is not mentioned.
    """
    core = importlib.import_module("preisach.diagnose.core")
    rng = np.random.default_rng(3)
    kept = rng.uniform(1.0, 2.0, 40)
    names = {"sensor_drift": "sensor_drift", "creep": "creep", "creep/other": "creep"}

    def step(creep_blocks, creep_gain, qualifies=True):
        scores = {
            "sensor_drift": SimpleNamespace(sse_blocks=kept),
            "creep": SimpleNamespace(sse_blocks=creep_blocks),
            "creep/other": SimpleNamespace(sse_blocks=kept + 5.0),
        }
        return SimpleNamespace(
            scores=scores,
            gains={"sensor_drift": 0.35, "creep": creep_gain, "creep/other": 0.01},
            qualifies={"sensor_drift": True, "creep": qualifies, "creep/other": False},
            n_params={"sensor_drift": 30.5, "creep": 5.0, "creep/other": 3.0},
        )

    worse = kept + 0.5  # every block worse: significantly
    text, amb = core.rival_statement(step(worse, 0.32), "sensor_drift", names)
    assert amb is None
    assert text.startswith("; also nearly as good: creep (32 % lower, 5 parameters)"), text
    assert "to separate sensor_drift from creep: a step-and-hold longer than" in text, text

    tied = kept + rng.normal(0.0, 0.3, kept.size)
    text, amb = core.rival_statement(step(tied, 0.34), "sensor_drift", names)
    assert "AMBIGUOUS: creep explains the data equally well" in text, text
    assert amb == {
        "effect": "sensor_drift",
        "rival": "creep",
        "experiment": core.separating_experiment("creep", "sensor_drift"),
    }
    # a fit refused at this step is neither a rival nor nearly as good (blind seed 42's 011
    # read "also nearly as good: sensor_drift" for a drift refused there); with half the gain
    # a qualifying one is not mentioned
    assert core.rival_statement(step(tied, 0.34, qualifies=False), "sensor_drift", names) == (
        "",
        None,
    )
    assert core.rival_statement(step(worse, 0.17), "sensor_drift", names) == ("", None)
    # the creep as the kept effect: the drift with all of its gain is nearly as good
    text, _ = core.rival_statement(step(worse + 1.0, 0.32), "creep", names)
    assert "sensor_drift" in text and "creep/other" not in text, text


def test_the_nearest_fits_are_those_refused_for_their_name_or_for_significance_alone():
    """``unexplained.nearest``: implausible fits, and fits that met the gain bars in few blocks.

    Blind seed 42's two-mode case 000 was `unexplained` with no nearest fit, although a mode
    lowered the held-out error by 27 % at p 0.07.  Fails when such a fit is left out, or when a
    fit that missed a gain bar or gained nothing is put in.
    """
    from preisach.diagnose.report import nearest_rejected
    from preisach.diagnose.selection import IMPLAUSIBLE, NOT_SIGNIFICANT

    reasons = {
        "structural_resonance/reaction": f"{NOT_SIGNIFICANT} (p = 0.0667 >= 0.01)",
        "structural_resonance": f"{NOT_SIGNIFICANT} (p = 0.176 >= 0.01)",
        "creep": f"{IMPLAUSIBLE}the fitted after-effect is over within a second",
        "delay": f"held-out RMSE lower by only 3 % (< 10 %); {NOT_SIGNIFICANT} (p = 0.2 >= 0.01)",
        "sensor_drift": f"{NOT_SIGNIFICANT} (p = 0.5 >= 0.01)",
    }
    gains = {
        "structural_resonance/reaction": 0.272,
        "structural_resonance": 0.267,
        "creep": 0.16,
        "delay": 0.03,
        "sensor_drift": -0.01,
    }
    near = nearest_rejected(SimpleNamespace(reasons=reasons, gains=gains), n=3)
    assert [(o["effect"], o["form"]) for o in near] == [
        ("structural_resonance", "structural_resonance/reaction"),
        ("creep", "creep"),
    ]
    assert near[0]["why_not"].startswith(NOT_SIGNIFICANT)
    assert near[1]["why_not"] == "the fitted after-effect is over within a second"
