"""preisach.plotting: every figure comes back as a Figure whose content is what it claims."""

import re

import numpy as np
import preisach.identify.plots as identify_plots
import preisach.plotting as pp
import pytest
from matplotlib.figure import Figure
from preisach import PreisachModel, Recording
from preisach.experiments import ModelPlant, drift_test, drive_to_state, regulation_sweep
from preisach.neutral import neutral_output
from preisach.plotting import boundary_polyline, plot_boundary, plot_major_loop

UNIT = re.compile(r"\((m|µ|n)?(V|V/s|V/V|V/V\^2|s|Hz|%|1|DAQ V)\)")


@pytest.fixture(scope="module")
def model():
    return PreisachModel.builtin("ss15-1hz", levels=41)


@pytest.fixture(scope="module")
def closed_loop(model):
    return regulation_sweep(
        "closed-loop", {1.0: model}, gains=[0.8, 2.4, 4.0], seeds=range(3), trace=(2.4, None)
    )


def _labels_have_units(fig):
    """Every labelled axis of every axes names a unit in parentheses."""
    for ax in fig.axes:
        labels = [ax.get_xlabel(), ax.get_ylabel()]
        if hasattr(ax, "get_zlabel"):
            labels.append(ax.get_zlabel())
        for text in labels:
            if text:
                assert UNIT.search(text), f"axis label without a unit: {text!r}"


def _line(ax, label):
    found = [ln for ln in ax.lines if ln.get_label() == label]
    assert found, f"no line labelled {label!r} in {[ln.get_label() for ln in ax.lines]}"
    return found[0]


def test_reexports_are_the_same_functions():
    assert pp.plot_kappa is identify_plots.plot_kappa
    assert pp.plot_weights is identify_plots.plot_weights
    assert pp.plot_fod_surface is identify_plots.plot_fod_surface
    assert pp.plot_fod_data is identify_plots.plot_fod_data
    assert pp.plot_verification is identify_plots.plot_verification
    assert pp.plot_identification is identify_plots.plot_report
    for name in pp.__all__:
        assert callable(getattr(pp, name)), name


def test_major_loop_figure(model):
    fig = plot_major_loop(model, n_fod=5)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "input u (V)" and ax.get_ylabel() == "output y (V)"
    assert len(ax.lines) == 6
    loop = _line(ax, "major loop")
    u, y = loop.get_data()
    # the major loop runs from u_min up to u_max and back: its ends are y_min and y_max
    assert u.max() == pytest.approx(100.0) and u[0] == pytest.approx(-100.0)
    assert y.max() == pytest.approx(model.y_max, abs=1e-9)
    assert y[0] == pytest.approx(model.y_min, abs=1e-9)


@pytest.mark.parametrize("coords", ["alpha-beta", "r-s"])
def test_boundary_figure(model, coords):
    for st in (
        model.neutral_state(30.0),
        model.state_from_extrema([60, -40, 20]),
        model.negative_saturation(),
    ):
        fig = plot_boundary(st, coords=coords)
        assert isinstance(fig, Figure)
        _labels_have_units(fig)
    with pytest.raises(ValueError, match="coords"):
        plot_boundary(model.anhysteretic_state(), coords="xy")


def test_boundary_line_is_the_state_in_both_coordinates(model):
    s = model.state_from_extrema([60.0, -40.0, 20.0])
    p = boundary_polyline(s)
    ab = _line(plot_boundary(s).axes[0], "boundary psi").get_xydata()
    np.testing.assert_allclose(ab, p)
    rs = _line(plot_boundary(s, coords="r-s").axes[0], "boundary psi").get_xydata()
    np.testing.assert_allclose(rs[:, 0], (p[:, 0] - p[:, 1]) / 2)
    np.testing.assert_allclose(rs[:, 1], (p[:, 0] + p[:, 1]) / 2)


def test_boundary_polyline_follows_the_state(model):
    s = model.state_from_extrema([60.0, -40.0, 20.0])
    p = boundary_polyline(s)
    # Staircase corners of the reduced memory sequence, ending on the diagonal at u.
    assert (60.0, -100.0) in map(tuple, p) and (60.0, -40.0) in map(tuple, p)
    assert tuple(p[-1]) == (20.0, 20.0)
    n = boundary_polyline(model.neutral_state(30.0), points_per_piece=11)
    slope = n[-12:-1]
    np.testing.assert_allclose(slope[:, 0] + slope[:, 1], 60.0)  # alpha + beta = 2 l


@pytest.mark.parametrize("coords", ["alpha-beta", "r-s"])
def test_everett_surface_spans_zero_to_half_the_output_range(model, coords):
    fig = pp.plot_everett(model, coords=coords, resolution=21)
    ax = fig.axes[0]
    _labels_have_units(fig)
    assert ax.get_zlabel() == "Everett function E (V)"
    z = ax.zz_dataLim.intervalx
    assert z[0] == pytest.approx(0.0, abs=1e-12)  # E(u, u) = 0 on the diagonal
    assert z[1] == pytest.approx((model.y_max - model.y_min) / 2)  # 2 E(u_max, u_min)
    x, y = ax.xy_dataLim.intervalx, ax.xy_dataLim.intervaly
    if coords == "r-s":
        np.testing.assert_allclose([x[0], x[1], y[0], y[1]], [0.0, 100.0, -100.0, 100.0])
    else:
        np.testing.assert_allclose([x[0], x[1], y[0], y[1]], [-100.0, 100.0, -100.0, 100.0])
    with pytest.raises(ValueError, match="coords"):
        pp.plot_everett(model, coords="ab")


def test_identification_plots_reexported_have_units(model):
    for fig in (
        pp.plot_weights(model, coords="r-s"),
        pp.plot_kappa(model),
        pp.plot_fod_surface(model),
    ):
        _labels_have_units(fig)
    kappa = pp.plot_kappa(model).axes[0].lines[0].get_ydata()
    assert kappa.size == model.levels.size - 1 and np.all(kappa >= 0)  # 1 Hz model is in Mp


def test_neutral_locus_with_the_three_initial_states(model):
    fig = pp.plot_neutral_locus(model, y_d=1.0)
    ax = fig.axes[0]
    _labels_have_units(fig)
    offsets, n = _line(ax, "neutral locus N(l)").get_data()
    np.testing.assert_allclose(n, neutral_output(model, offsets), atol=1e-12)
    pts = {}
    for ln in ax.lines:
        m = re.match(r"(psi_[nad]): u = ", str(ln.get_label()))
        if m:
            pts[m.group(1)] = (ln.get_xdata()[0], ln.get_ydata()[0])
    assert set(pts) == {"psi_n", "psi_a", "psi_d"}
    for _u, y in pts.values():
        assert abs(y - 1.0) <= 0.03  # every state lands on y_d within the thesis tolerance
    # psi_a is reached rising (needs more input), psi_d falling (less): Figs 4.6-4.8
    assert pts["psi_d"][0] < pts["psi_n"][0] < pts["psi_a"][0]
    assert _line(ax, "y_d = 1 V").get_ydata()[0] == 1.0
    # the same picture from states found elsewhere
    plant = ModelPlant(model, 1e-3)
    inits = [drive_to_state(plant, k, 0.5, 1.0) for k in "nad"]
    ax2 = pp.plot_neutral_locus(model, states=inits).axes[0]
    assert sum(str(ln.get_label()).startswith("psi_") for ln in ax2.lines) == 3
    assert _line(ax2, "y_d = 0.5 V")
    # on given axes of a larger figure, everything lands on those axes
    fig3 = Figure()
    axes = fig3.subplots(1, 2)
    pp.plot_neutral_locus(model, states=inits, ax=axes[1])
    assert not axes[0].lines
    assert _line(axes[1], "y_d = 0.5 V") and _line(axes[1], "neutral locus N(l)")


def test_effort_summaries_show_the_sweep(closed_loop):
    fig = pp.plot_effort_summary(closed_loop)
    _labels_have_units(fig)
    assert "n_c" in fig.axes[0].get_ylabel()
    with pytest.raises(ValueError, match="drift"):
        pp.plot_drift_summary(closed_loop)
    fig = pp.plot_effort_increase(closed_loop)
    ax = fig.axes[0]
    _labels_have_units(fig)
    table = closed_loop.percentage_table()
    for kind in "ad":
        x, y = _line(ax, f"psi_{kind}, f = 1 Hz").get_data()
        np.testing.assert_allclose(x, [r["normalised_gain"] for r in table])
        np.testing.assert_allclose(y, [r[f"{kind}_1"] for r in table])
    traces = pp.plot_sweep_traces(closed_loop)
    assert {ln.get_label() for ln in traces.axes[0].lines} == {"psi_n", "psi_a", "psi_d"}
    assert pp.plot_paired_differences(closed_loop).axes[0].get_ylabel().endswith("(DAQ V)")
    assert len(pp.plot_initial_states(closed_loop).axes) == 1


def test_drift_summary_and_one_trial(model):
    res = regulation_sweep("drift", {1.0: model}, gains=[1.6, 4.0], seeds=range(2))
    fig = pp.plot_drift_summary(res)
    _labels_have_units(fig)
    assert fig.axes[0].get_ylabel().startswith("differential drift")
    with pytest.raises(ValueError, match="closed-loop"):
        pp.plot_effort_increase(res)
    plant = ModelPlant(model, 1e-3)
    trial = drift_test(plant, drive_to_state(plant, "a", 1.0, 1.0), gain=1.6, seed=0)
    fig = pp.plot_trial(trial)
    _labels_have_units(fig)
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), trial.output)


def _recording(model, y_shift=0.0, lag=0):
    t = np.arange(8000) * 1e-3
    u = 80.0 * np.sin(2 * np.pi * 1.0 * t) * np.minimum(1.0, 0.2 + t / 4)
    y = model.simulate(u, model.anhysteretic_state()).output
    if lag:
        y = np.r_[np.full(lag, y[0]), y[:-lag]]
    return Recording.from_arrays(t=t, u=u, y=y + y_shift, experiment="sine")


def test_residual_map_of_an_offset_is_flat(model):
    rec = _recording(model, y_shift=0.01)
    fig = pp.plot_residual_map(model, rec, initial_state="anhysteretic")
    _labels_have_units(fig)
    mean = fig.axes[0].collections[0].get_array()
    assert mean.count() > 20
    np.testing.assert_allclose(mean.compressed(), 10.0, atol=1e-9)  # mV


def test_residual_map_of_a_lag_changes_sign_with_the_input_direction(model):
    rec = _recording(model, lag=5)
    fig = pp.plot_residual_map(model, [rec], initial_state="anhysteretic", bins=(10, 6))
    mesh = fig.axes[0].collections[0]
    mean = mesh.get_array().reshape(6, 10)
    # rows are du/dt bins from negative to positive: a lagging output is below the model while
    # the input rises and above it while the input falls
    assert np.nanmean(mean.filled(np.nan)[:3]) > 0 > np.nanmean(mean.filled(np.nan)[3:])
    with pytest.raises(ValueError, match="recordings"):
        pp.plot_residual_map(model, [])


def test_diagnosis_figure_is_the_reports():
    from preisach.diagnose import diagnose
    from preisach.studies.diagnosis_cases import make_case

    case = make_case("delay", seed=21, scale=0.3, effect_size=4.0)
    rep = diagnose(case.identify(), case.recordings[:3], candidates=["delay"])
    fig = pp.plot_diagnosis(rep)
    assert isinstance(fig, Figure)
    titles = [ax.get_title() for ax in fig.axes]
    assert any("residual map" in t for t in titles)
    assert any(f"verdict: {rep.verdict}" in t for t in titles)
