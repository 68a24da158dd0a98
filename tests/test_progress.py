"""Progress bars (preisach._progress, on tqdm): drawn in place on a terminal, as plain lines in
a log, never for a call that ends before ``delay``; off with ``progress=False`` or ``-q``."""

from __future__ import annotations

import io
import json
import subprocess
import sys

import numpy as np
import preisach._progress as pp
from preisach import PreisachModel, Recording


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_off_a_terminal_the_bar_is_plain_lines_ending_at_the_total():
    out = io.StringIO()
    with pp.progress_bar(5, "work", unit="trial", file=out, delay=0.0) as bar:
        for _ in range(5):
            bar.update(1)
    text = out.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert lines[0].startswith("work:   0%") and lines[-1].startswith("work: 100%")
    assert "5/5" in lines[-1] and "trial" in lines[-1]


def test_on_a_terminal_the_bar_is_redrawn_in_place():
    out = Tty()
    with pp.progress_bar(4, "work", file=out, delay=0.0, log_interval=0.0) as bar:
        bar.update(4)
    text = out.getvalue()
    assert text.startswith("\rwork:") and text.count("\n") == 1 and "4/4" in text


def test_disabled_or_quick_bars_draw_nothing():
    out = Tty()
    with pp.progress_bar(3, "off", file=out, enabled=False, delay=0.0) as bar:
        bar.update(3)
        bar.set_postfix_str("still fine")
    with pp.progress_bar(3, "quick", file=out) as bar:  # ends before the 2 s delay
        bar.update(3)
    assert out.getvalue() == ""


def test_line_progress_passes_callables_through_and_counts_lines(monkeypatch):
    seen: list[str] = []
    cb, bar = pp.line_progress(seen.append, "x")
    cb("one")
    assert seen == ["one"] and bar.disable
    assert pp.line_progress(False, "x")[0] is None and pp.line_progress(None, "x")[0] is None
    out = io.StringIO()
    monkeypatch.setattr(pp, "progress_bar", _eager(pp.progress_bar, out))
    cb, bar = pp.line_progress(True, "diagnose")
    cb("  delay: held-out RMSE 1.2 mV   (0.1 s)")
    cb("verdict: delay")
    bar.close()
    last = out.getvalue().splitlines()[-1]
    assert last.startswith("diagnose: 2") and "verdict: delay" in last


def _eager(factory, out, calls=None):
    """``progress_bar`` drawing at once into ``out`` (and recording its keyword arguments)."""

    def make(*args, **kwargs):
        if calls is not None:
            calls.append(dict(kwargs, args=args))
        kwargs.update(file=out, delay=0.0)
        bar = factory(*args, **kwargs)
        if calls is not None:
            calls[-1]["bar"] = bar
        return bar

    return make


def test_regulation_sweep_counts_its_trials_and_progress_false_is_silent(monkeypatch):
    import preisach.execution as execution
    import preisach.experiments.sweep as sweep_mod

    model = PreisachModel.builtin("ss15-1hz", levels=21)
    for enabled in (True, False):
        out = io.StringIO()
        monkeypatch.setattr(execution, "progress_bar", _eager(pp.progress_bar, out))
        sweep_mod.regulation_sweep(
            "drift",
            {1.0: model},
            states=["n"],
            gains=[0.8, 1.6],
            seeds=[0, 1],
            trace=None,
            progress=enabled,
        )
        if enabled:
            last = out.getvalue().splitlines()[-1]
            # one task per (frequency, state, gain), each over the seeds
            assert last.startswith("drift sweep: 100%") and "2/2" in last and "task" in last
        else:
            assert out.getvalue() == ""


def test_identify_lsq_shows_its_cross_validation(monkeypatch):
    import preisach.identify.lsq as lsq_mod
    from preisach.identify import identify_lsq

    m = PreisachModel.builtin("ss15-1hz", levels=21)
    t = np.arange(3000) * 1e-3
    u = 100 * np.sin(2 * np.pi * t) * np.exp(-t / 2)
    rec = Recording.from_arrays(t=t, u=u, y=m.simulate(u, m.negative_saturation()).output)
    calls: list[dict] = []
    out = io.StringIO()
    monkeypatch.setattr(lsq_mod, "progress_bar", _eager(pp.progress_bar, out, calls))
    identify_lsq(rec, 9, lambdas=[1e-3, 1e-1], folds=3)
    assert calls[-1]["args"][0] == 1 + 3 * 2 + 1  # the sums, 2 lambdas x 3 folds, the final fit
    bar = calls[-1]["bar"]
    assert bar.n == bar.total == 8 and "least squares" in out.getvalue()
    identify_lsq(rec, 9, lambdas=[1e-3, 1e-1], folds=3, progress=False)
    assert calls[-1]["enabled"] is False


def test_diagnose_progress_true_draws_a_bar_and_false_nothing(monkeypatch, capsys):
    from preisach.diagnose import diagnose

    m = PreisachModel.builtin("ss15-1hz", levels=21)
    t = np.arange(3000) * 1e-3
    u = -100 + 100 * (1 - np.cos(2 * np.pi * t)) * 0.7
    y = m.simulate(u, m.negative_saturation()).output
    y = y + np.random.default_rng(1).normal(0, 1e-3, t.size)
    rec = Recording.from_arrays(t=t, u=u, y=y, experiment="r0")
    out = io.StringIO()
    monkeypatch.setattr(pp, "progress_bar", _eager(pp.progress_bar, out))
    diagnose(m, [rec], candidates=["gain_offset"])
    lines = out.getvalue().splitlines()
    assert lines[-1].startswith("diagnose:") and "verdict:" in lines[-1]
    out.truncate(0)
    out.seek(0)
    diagnose(m, [rec], candidates=["gain_offset"], progress=False)
    assert out.getvalue() == ""
    assert capsys.readouterr().err == ""


def test_cli_quiet_turns_the_sweep_bar_off(monkeypatch, tmp_path):
    import preisach.execution as execution
    from preisach.cli import main

    calls: list[dict] = []
    monkeypatch.setattr(execution, "progress_bar", _eager(pp.progress_bar, io.StringIO(), calls))
    base = ["experiment", "drift", "--model", "ss15-1hz", "--gains", "0.8", "--seeds", "1"]
    base += ["--states", "n", "--json", str(tmp_path / "d.json")]
    assert main(base) == 0
    assert main([*base, "-q"]) == 0
    assert [c["enabled"] for c in calls] == [True, False]


def test_demo_stages_print_their_lines_with_or_without_a_bar():
    from preisach.demo import _Stages

    for progress in (True, False):
        out = io.StringIO()
        st = _Stages(out, progress=progress)
        for k in range(5):
            with st.stage(f"stage {k}") as s:
                s.detail = f"detail {k}"
        lines = out.getvalue().splitlines()
        assert [ln.split(" ...")[0] for ln in lines] == [f"[{k + 1}/5] stage {k}" for k in range(5)]
        assert lines[2].startswith("[3/5] stage 2 ... detail 2 (") and lines[2].endswith(" s)")
        assert list(st.times) == [f"stage {k}" for k in range(5)]


def test_import_preisach_loads_no_tqdm():
    code = "import sys, json, preisach, preisach.model\nprint(json.dumps('tqdm' in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) is False
