"""Rich display in Jupyter: every result a user looks at has a ``_repr_html_`` that is valid HTML
holding its key numbers, and building it does not make ``import preisach`` heavier."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pytest
from preisach import PreisachModel, Recording
from preisach.experiments.sweep import SweepResult
from preisach.identify import identify_lsq
from preisach.verify import VerificationRow, VerificationTable, verify

VOID = {"br", "img", "hr", "meta", "input", "col", "wbr"}
BLOCK = {"div", "table", "tr", "td", "th", "caption", "br", "li", "ul", "pre", "details", "summary"}


class _Checker(HTMLParser):
    """Tag balance, and the text a reader sees (entities resolved)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.text: list[str] = []
        self.images: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag in BLOCK:
            self.text.append(" ")
        if tag == "img":
            self.images.append(dict(attrs).get("src", ""))
        if tag not in VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs).get("src", ""))

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


def _parse(html: str) -> _Checker:
    assert isinstance(html, str) and html.startswith("<div")
    c = _Checker()
    c.feed(html)
    c.close()
    assert not c.errors and not c.stack, (c.errors, c.stack)
    return c


def _text(html: str) -> str:
    return " ".join("".join(_parse(html).text).split())


def _recording(model: PreisachModel, name: str, seed: int = 0, n: int = 3000) -> Recording:
    t = np.arange(n) * 1e-3
    u = 100 * np.sin(2 * np.pi * 1.0 * t) * np.exp(-t / 2.0)
    y = model.simulate(u, model.negative_saturation()).output
    y = y + np.random.default_rng(seed).normal(0, 1e-3, n)
    return Recording.from_arrays(t=t, u=u, y=y, experiment=name)


@pytest.fixture(scope="module")
def model():
    return PreisachModel.builtin("ss15-1hz", levels=21)


def test_model_html_shows_levels_ranges_and_a_thumbnail(model):
    html = model._repr_html_()
    c = _parse(html)
    text = _text(html)
    assert "21 (cells 210)" in text
    assert f"[{model.u_min:g}, {model.u_max:g}] V" in text
    assert f"{model.y_max:.4g}" in text and "in Mp" in text
    assert len(c.images) == 1 and c.images[0].startswith("data:image/png;base64,")
    assert len(c.images[0]) > 1000


def test_model_html_flags_negative_masses():
    w = np.tril(np.ones((5, 5)))
    w[4, 0] = -0.5
    m = PreisachModel.from_weights(np.linspace(-1, 1, 6), w)
    neg = int((m.cell_weights() < 0).sum())
    assert neg > 0
    assert f"{neg} negative" in _text(m._repr_html_())


def test_identification_html_has_residuals_with_units_and_highlighted_warnings(model):
    rep = identify_lsq(_recording(model, "decay <1>"), 11, lambdas=[1e-3, 1e-1])
    rep = dataclasses.replace(rep, warnings=["few reversals & <short>"], output_units="mV")
    html = rep._repr_html_()
    text = _text(html)
    r = rep.residuals[0]
    assert "least squares" in text and "decay <1>" in text  # escaped, shown as written
    assert "max (mV)" in text and "rms (mV)" in text
    assert f"{r.rms_error:.4g}" in text and f"{r.rms_pct:.3f}" in text
    assert f"{rep.lsq.chosen_lambda:.3g} ({rep.lsq.folds}-fold CV)" in text
    assert "chosen" in text and "11 (cells 55)" in text
    assert "&lt;short&gt;" in html and "few reversals & <short>" in text
    warn = html[html.index("few reversals") - 200 : html.index("few reversals")]
    assert "background: #fff3cd" in warn


def test_verification_html_rows_and_doubtful_rows_highlighted(model):
    rec = _recording(model, "decay")
    table = verify(model, [rec])
    text = _text(table._repr_html_())
    row = table.rows[0]
    assert "decay" in text and f"{row.rms_error:.4g}" in text and f"{row.max_pct:.3f}" in text
    assert "max (V)" in text and "rms %" in text
    doubtful = VerificationTable(
        rows=[
            dataclasses.replace(row, experiment="a", exact_state=True, n_out_of_range=0),
            dataclasses.replace(row, experiment="b", exact_state=False, n_out_of_range=7),
        ],
        model_name="m1",
    )
    html = doubtful._repr_html_()
    text = _text(html)
    assert "Verification of m1" in text
    assert "b: state not exact" in text and "b: 7 input samples" in text
    assert html.count('<tr style="background: #fff3cd">') == 1
    assert isinstance(VerificationRow, type)


def _sweep() -> SweepResult:
    rows = []
    nc = {"n": 10.0, "a": 12.0, "d": 11.0}
    for f in (1.0, 2.0):
        for g in (0.8, 1.6):
            for k in ("n", "a", "d"):
                for seed in (0, 1):
                    v = nc[k] * g * f + 0.5 * seed
                    rows.append({"frequency": f, "state": k, "gain": g, "seed": seed, "nc": v})
    return SweepResult(experiment="closed-loop", rows=rows, states=[])


def test_sweep_html_is_table_5_1():
    res = _sweep()
    html = res._repr_html_()
    text = _text(html)
    assert "24 trials, 2 seeds" in text and "1, 2 Hz" in text
    # mean +/- std per cell: psi_n at 1 Hz, K_n = 0.8 -> 8 and 8.5 -> 8.25 +/- 0.3536
    assert "+8.2500 ± 0.3536" in text
    # Table 5.1: 100 (nc_a - nc_n) / nc_n at K_n/max = 0.5, 1 Hz
    pct = 100 * ((12 * 0.8 + 0.25) - (10 * 0.8 + 0.25)) / (10 * 0.8 + 0.25)
    assert f"{pct:.3f}" in text and "0.5000" in text and "Table 5.1" in text
    assert [r["a_1"] for r in res.percentage_table()][0] == pytest.approx(pct)
    assert "yes" in text  # psi_n smallest in every cell


def test_drift_sweep_html_has_no_table_5_1():
    rows = [
        {"frequency": 1.0, "state": k, "gain": 1.6, "seed": s, "drift": d + 0.01 * s}
        for k, d in (("n", 0.001), ("a", 0.05), ("d", -0.04))
        for s in range(3)
    ]
    text = _text(SweepResult(experiment="drift", rows=rows, states=[])._repr_html_())
    assert "Table 5.1" not in text and "drift (V)" in text and "+0.0110 ± 0.0100" in text
    assert "drift from ψa > 0" in text


@pytest.fixture(scope="module")
def diagnosis():
    from preisach.diagnose import diagnose

    m = PreisachModel.builtin("ss15-1hz", levels=21)
    rng = np.random.default_rng(3)
    recs = []
    for k in range(2):
        t = np.arange(4000) * 1e-3
        u = -100 + 100 * (1 - np.cos(2 * np.pi * (0.7 + 0.3 * k) * t)) * (0.6 + 0.1 * k)
        y = m.simulate(u, m.negative_saturation()).output
        y = np.interp(t - 4e-3, t, y) + rng.normal(0, 1e-3, t.size)
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"r{k}"))
    return diagnose(m, recs, candidates=["delay", "gain_offset"])


def test_diagnosis_html_verdict_effects_uncertainties_and_figure(diagnosis):
    rep = diagnosis
    assert rep.verdict == "delay"
    html = rep._repr_html_()
    c = _parse(html)
    text = _text(html)
    assert "verdict: delay" in text
    assert f"{1e3 * rep.rmse_before:.4g} mV (given model)" in text
    assert f"{1e3 * rep.rmse_after:.4g} mV (augmented, held-out)" in text
    e = rep.effects[0]
    name, p = next(iter(e.parameters.items()))
    assert f"{name} = {p['value']:.4g} ± {p['std']:.2g}" in text
    assert f"{1e3 * e.heldout_rmse_before:.4g} → {1e3 * e.heldout_rmse_after:.4g}" in text
    assert "gain_offset" in text  # the candidate table
    assert len(c.images) == 1 and c.images[0].startswith("data:image/png;base64,")


def test_display_loads_no_matplotlib_until_a_figure_is_drawn():
    code = (
        "import sys, json\n"
        "import preisach, preisach._display, preisach.model, preisach.verify\n"
        "from preisach._display import verification_html\n"
        "from preisach.verify import VerificationRow, VerificationTable\n"
        "row = VerificationRow('x', 10, 0, 1.0, 0.5, 0.0, 2.0)\n"
        "html = verification_html(VerificationTable([row]))\n"
        "print(json.dumps([m for m in sys.modules if m.startswith('matplotlib')]))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert json.loads(out.stdout) == []


def test_a_figure_that_fails_leaves_a_note_not_an_exception():
    from preisach._display import figure_img

    def broken(fig):
        raise RuntimeError("no data <here>")

    html = figure_img(broken, figsize=(2, 2))
    assert "figure not drawn: RuntimeError: no data &lt;here&gt;" in html


def test_rate_model_html_shows_its_rates_and_loops():
    from preisach.rate_model import RateDependentPreisachModel

    m = RateDependentPreisachModel.builtin(levels=21)
    html = m._repr_html_()
    c = _parse(html)
    text = _text(html)
    knots = ", ".join(f"{v:g}" for v in m.knots)
    assert f"{m.n_tables} at rates {knots} V/s" in text
    assert f"τ = {m.tau:g} s" in text and f"[{m.u_min:g}, {m.u_max:g}] V" in text
    assert len(c.images) == 1 and c.images[0].startswith("data:image/png;base64,")


def test_augmented_model_html_lists_the_chain(diagnosis):
    aug = diagnosis.model
    text = _text(aug._repr_html_())
    for b in aug.input_blocks + aug.output_blocks:
        assert b.describe() in text
    assert "Preisach model" in text and "21 (cells 210)" in text


def test_property_test_html_pass_fail_and_not_testable(model):
    from preisach.verify import congruency_metric, wiping_out_metric
    from preisach.waveforms import cml_input, wiping_out_input

    def rec(u, extra=0.0):
        y = model.simulate(u, model.negative_saturation()).output + extra
        return Recording.from_arrays(u=u, y=y, sample_time=1e-3)

    u = wiping_out_input(1.0).u
    ok = wiping_out_metric(rec(u), branches="ascending")
    text = _text(ok._repr_html_())
    assert "Wiping-out: 3 returns" in text and "pass: max |dy|" in text
    assert f"{ok.max_pct:.3f} %" in text and "100" in text
    drifting = wiping_out_metric(rec(u, np.arange(u.size) / u.size), branches="ascending")
    assert "fail: max |dy|" in _text(drifting._repr_html_())
    flat = wiping_out_metric(
        Recording.from_arrays(u=np.linspace(0, 1, 50), y=np.linspace(0, 2, 50), sample_time=1e-3)
    )
    assert "not testable" in _text(flat._repr_html_())
    cml = congruency_metric(rec(cml_input(frequency=1.0).u))
    text = _text(cml._repr_html_())
    assert f"Congruent minor loops: {cml.n_loops} loops, {len(cml.pairs)} comparable" in text
    assert ("pass" if cml.passed else "fail") in text
