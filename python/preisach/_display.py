"""Rich display in Jupyter: the HTML of every result a user looks at, built in one place.

Each result class has a one-line ``_repr_html_`` that calls one function here:

* :func:`model_html` - :class:`~preisach.model.PreisachModel`: levels, input and output range,
  a thumbnail of the major loop;
* :func:`rate_model_html` - :class:`~preisach.rate_model.RateDependentPreisachModel`: its rates,
  filter and grid, the major loops at each rate;
* :func:`augmented_model_html` - :class:`~preisach.diagnose.augmented.AugmentedModel`: the chain
  of physics blocks around the Preisach model;
* :func:`identification_html` - :class:`~preisach.identify.report.IdentificationReport`;
* :func:`verification_html` - :class:`~preisach.verify.VerificationTable`, and
  :func:`property_test_html` - the wiping-out and congruency tests of the data
  (:class:`~preisach.verify.WipingOutResult`, :class:`~preisach.verify.CongruencyResult`);
* :func:`sweep_html` - :class:`~preisach.experiments.sweep.SweepResult` (Table 5.1 layout);
* :func:`diagnosis_html` - :class:`~preisach.diagnose.report.DiagnosisReport`.

The functions read the results' attributes only (no import of the classes), so this module sits
below every layer and costs nothing at ``import preisach``. Matplotlib is imported inside
:func:`figure_img`, which draws on a bare :class:`matplotlib.figure.Figure` (no pyplot: a
thumbnail never shows up a second time under ``%matplotlib inline``). A figure that cannot be
drawn is replaced by a one-line note; the tables never depend on it.
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

__all__ = [
    "augmented_model_html",
    "diagnosis_html",
    "figure_img",
    "identification_html",
    "model_html",
    "property_test_html",
    "rate_model_html",
    "sweep_html",
    "verification_html",
]

_BOX = 'style="font-family: var(--jp-content-font-family, sans-serif); line-height: 1.35"'
_WARN = (
    'style="background: #fff3cd; color: #664d03; border-left: 4px solid #e0a800; '
    'padding: 3px 8px; margin: 2px 0"'
)
_GOOD = 'style="color: #146c2e; font-weight: bold"'
_BAD = 'style="color: #a61b1b; font-weight: bold"'
_NUM = 'style="text-align: right; font-variant-numeric: tabular-nums"'


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _g(x: Any, fmt: str = ".4g") -> str:
    """Format a number (``nan`` and ``None`` as an en dash)."""
    if x is None:
        return "&ndash;"
    xf = float(x)
    return "&ndash;" if math.isnan(xf) else format(xf, fmt)


def _table(
    header: Sequence[str],
    rows: Iterable[Sequence[str]],
    *,
    numeric_from: int = 1,
    numeric_to: int | None = None,
    caption: str = "",
    row_styles: Sequence[str] | None = None,
) -> str:
    """HTML table; cells are given as HTML (escape text with :func:`_e` before).

    Columns ``numeric_from`` to ``numeric_to`` (exclusive; ``None``: the last) are right-aligned.
    """
    last = len(header) if numeric_to is None else numeric_to
    cap = f"<caption style='caption-side: top; text-align: left'>{caption}</caption>"
    out = ["<table>", cap if caption else "", "<thead><tr>"]
    out += [f"<th>{h}</th>" for h in header]
    out.append("</tr></thead><tbody>")
    for i, row in enumerate(rows):
        style = row_styles[i] if row_styles is not None and row_styles[i] else ""
        out.append(f"<tr {style}>" if style else "<tr>")
        for j, cell in enumerate(row):
            out.append(
                f"<td {_NUM}>{cell}</td>" if numeric_from <= j < last else f"<td>{cell}</td>"
            )
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _warnings(items: Iterable[str]) -> str:
    return "".join(f"<div {_WARN}>&#9888; {_e(w)}</div>" for w in items)


def _kv(pairs: Iterable[tuple[str, str]]) -> str:
    """Two-column key/value table (values are HTML)."""
    rows = "".join(f"<tr><th style='text-align: left'>{k}</th><td>{v}</td></tr>" for k, v in pairs)
    return f"<table>{rows}</table>"


def figure_img(
    draw: Callable[[Any], Any], *, figsize: tuple[float, float], dpi: int = 72, alt: str = ""
) -> str:
    """Draw on a new bare Figure and return it as an inline base64 PNG ``<img>``.

    Parameters
    ----------
    draw : callable
        ``draw(fig)`` draws on a :class:`matplotlib.figure.Figure`.
    figsize : (float, float)
        Figure size (inches).
    dpi : int
        Resolution of the PNG.
    alt : str
        Alternative text of the image.

    Returns
    -------
    str
        ``<img src="data:image/png;base64,...">``, or a short note when drawing failed.

    """
    try:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize)
        draw(fig)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    except Exception as exc:  # a figure must never hide the tables
        return f"<p><i>(figure not drawn: {_e(type(exc).__name__)}: {_e(exc)})</i></p>"
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{_e(alt)}"/>'


# ------------------------------------------------------------------------------ model
def _draw_major_loop(model: Any, units: tuple[str, str]) -> Callable[[Any], None]:
    def draw(fig: Any) -> None:
        import numpy as np

        up = np.linspace(model.u_min, model.u_max, 200)
        u = np.r_[up, up[::-1]]
        y = model.simulate(u, model.negative_saturation()).output
        ax = fig.add_subplot(1, 1, 1)
        ax.plot(u[:200], y[:200], color="C0", lw=1.2, label="ascending")
        ax.plot(u[200:], y[200:], color="C3", lw=1.2, label="descending")
        ax.set_xlabel(f"input u ({units[0]})", fontsize=8)
        ax.set_ylabel(f"output y ({units[1]})", fontsize=8)
        ax.set_title("major loop", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, frameon=False)

    return draw


def _model_units(model: Any) -> tuple[str, str]:
    md = getattr(model, "metadata", {}) or {}
    return str(md.get("input_units", "V")), str(md.get("output_units", "V"))


def model_html(model: Any, *, thumbnail: bool = True) -> str:
    """HTML of a PreisachModel: name, levels, input and output range, major-loop thumbnail."""
    ui, uo = _model_units(model)
    levels = model.levels
    weights = model.cell_weights()
    negative = int((weights < 0).sum())
    pairs = [
        ("levels", f"{levels.size} (cells {levels.size * (levels.size - 1) // 2})"),
        ("input range", f"[{_g(model.u_min, 'g')}, {_g(model.u_max, 'g')}] {_e(ui)}"),
        ("output range", f"[{_g(model.y_min)}, {_g(model.y_max)}] {_e(uo)}"),
        (
            "cell masses",
            "all &ge; 0 (in M<sub>p</sub>)"
            if negative == 0
            else f"<span {_BAD}>{negative} negative</span> (not in M<sub>p</sub>)",
        ),
        ("out of range", _e(model.out_of_range)),
    ]
    title = f"PreisachModel {_e(repr(model.name)) if model.name else ''}"
    img = (
        figure_img(
            _draw_major_loop(model, (ui, uo)), figsize=(3.2, 2.4), alt="major loop of the model"
        )
        if thumbnail
        else ""
    )
    return (
        f"<div {_BOX}><b>{title}</b>"
        f"<div style='display: flex; gap: 1.5em; align-items: flex-start'>"
        f"<div>{_kv(pairs)}</div><div>{img}</div></div></div>"
    )


def rate_model_html(model: Any, *, thumbnail: bool = True) -> str:
    """HTML of a RateDependentPreisachModel: rates, filter, grid, the major loop at each rate."""
    knots = [float(v) for v in model.knots]
    pairs = [
        ("tables", f"{model.n_tables} at rates {', '.join(format(v, 'g') for v in knots)} V/s"),
        ("rate filter", f"first order, &tau; = {_g(model.tau, 'g')} s"),
        ("levels", str(model.levels.size)),
        ("input range", f"[{_g(model.u_min, 'g')}, {_g(model.u_max, 'g')}] V"),
    ]

    def draw(fig: Any) -> None:
        ax = fig.add_subplot(1, 1, 1)
        for k, v in enumerate(knots):
            m = model.at_rate(v)
            _draw_loop_on(ax, m, f"{v:g} V/s", f"C{k}")
        ax.set_xlabel("input u (V)", fontsize=8)
        ax.set_ylabel("output y (V)", fontsize=8)
        ax.set_title("major loop at each rate", fontsize=9)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, frameon=False)

    img = figure_img(draw, figsize=(3.2, 2.4), alt="major loops per rate") if thumbnail else ""
    title = f"RateDependentPreisachModel {_e(repr(model.name)) if model.name else ''}"
    return (
        f"<div {_BOX}><b>{title}</b>"
        f"<div style='display: flex; gap: 1.5em; align-items: flex-start'>"
        f"<div>{_kv(pairs)}</div><div>{img}</div></div></div>"
    )


def _draw_loop_on(ax: Any, model: Any, label: str, color: str) -> None:
    import numpy as np

    up = np.linspace(model.u_min, model.u_max, 200)
    y = model.simulate(np.r_[up, up[::-1]], model.negative_saturation()).output
    ax.plot(np.r_[up, up[::-1]], y, color=color, lw=1.0, label=label)


def augmented_model_html(model: Any) -> str:
    """HTML of an AugmentedModel: input blocks, the Preisach model, output blocks, in order."""
    rows = [[_e("input"), _e(b.describe())] for b in model.input_blocks]
    core = "Preisach model" + (
        f" with {_e(model.feedback_blocks[-1].describe())}" if model.feedback_blocks else ""
    )
    rows.append(["&rarr;", f"<b>{core}</b> (below)"])
    rows += [[_e("output"), _e(b.describe())] for b in model.output_blocks]
    title = f"AugmentedModel {_e(repr(model.name)) if model.name else ''}"
    return (
        f"<div {_BOX}><b>{title}</b>"
        + _table(["side", "block"], rows, numeric_from=2, caption="the chain, input first")
        + model_html(model.base)
        + "</div>"
    )


# ------------------------------------------------------------------------------ identification
_METHODS = {
    "fod": "Mayergoyz (FOD grid &rarr; Everett table)",
    "surface": "square-root FOD surface (thesis Eq 3.2)",
    "lsq": "least squares on every sample",
}


def _residual_rows(residuals: Iterable[Any]) -> list[list[str]]:
    return [
        [_e(r.name), str(r.n), _g(r.max_error), _g(r.rms_error), _g(r.max_pct, ".3f"),
         _g(r.rms_pct, ".3f")]
        for r in residuals
    ]  # fmt: skip


def identification_html(report: Any) -> str:
    """HTML of an IdentificationReport: model, data, fit, residuals with units, warnings."""
    uo = _e(report.output_units)
    parts = [f"<div {_BOX}><b>Identification: {_METHODS.get(report.method, _e(report.method))}</b>"]
    if report.choice:
        parts.append(f"<div>method chosen automatically: {_e(report.choice)}</div>")
    parts.append(_warnings(report.warnings))
    parts.append(model_html(report.model))
    facts = [
        ("output delay", f"{_g(report.delay, 'g')} samples"),
        ("time", f"{report.elapsed:.3f} s"),
    ]
    if report.fod is not None:
        n = report.fod.levels.size
        measured = int((report.fod.count != 0).sum())
        facts.append(("FOD nodes measured", f"{measured} of {n * (n + 1) // 2}"))
    if report.projection is not None:
        p = report.projection
        facts.append(
            (
                "projection to &mu; &ge; 0",
                f"{p.n_negative} negative cells; moved {_g(p.mass_moved)} {uo} = "
                f"{_g(100 * p.fraction_moved, '.3g')} % of the mass"
                + ("" if p.converged else f" <span {_BAD}>(did not converge)</span>"),
            )
        )
    if report.lsq is not None:
        q = report.lsq
        facts += [
            ("samples fitted", f"{q.n_samples} ({q.n_skipped} burn-in/delay), {q.n_params} masses"),
            ("smoothness &lambda;", f"{_g(q.chosen_lambda, '.3g')} ({q.folds}-fold CV)"),
            ("fit rms", f"{_g(q.fit_rms)} {uo}"),
        ]
    parts.append(_kv(facts))
    if report.data:
        parts.append(
            _table(
                ["data", "samples", "used", "note"],
                [[_e(d.name), str(d.n_samples), str(d.n_used), _e(d.note)] for d in report.data],
                numeric_to=3,
                caption="data used",
            )
        )
    if report.surface_fit is not None:
        sf = report.surface_fit
        parts.append(
            "<div>surface parameters (Table 3.1 layout); fit rms "
            f"{_g(sf.rmse)} {uo}, max {_g(sf.max_error)} {uo} over {sf.n_points} FOD points</div>"
            f"<pre>{_e(sf.table())}</pre>"
        )
    header = ["experiment", "n", f"max ({uo})", f"rms ({uo})", "max %", "rms %"]
    rows = _residual_rows([report.node_residuals] if report.node_residuals else [])
    rows += _residual_rows(report.residuals)
    if rows:
        parts.append(
            _table(header, rows, caption="residuals (model &minus; measurement; % of the range)")
        )
    if report.lsq is not None and len(report.lsq.lambdas):
        q = report.lsq
        cv = [
            [_g(lv, ".3g"), _g(c, ".5g") + (" &larr; chosen" if lv == q.chosen_lambda else "")]
            for lv, c in zip(q.lambdas, q.cv_rms)
        ]
        parts.append(
            f"<details><summary>cross-validation curve</summary>"
            f"{_table(['&lambda;', f'CV rms ({uo})'], cv, numeric_from=0)}</details>"
        )
    parts.append("</div>")
    return "".join(parts)


# ------------------------------------------------------------------------------ verification
def verification_html(table: Any) -> str:
    """HTML of a VerificationTable: one row per experiment, doubtful rows highlighted."""
    header = ["experiment", "samples", "clamped", "max (V)", "rms (V)", "mean (V)", "range (V)",
              "max %", "rms %"]  # fmt: skip
    rows, styles, notes = [], [], []
    for r in table.rows:
        rows.append(
            [_e(r.experiment), str(r.n_samples), str(r.n_out_of_range), _g(r.max_error),
             _g(r.rms_error), _g(r.mean_error, ".3g"), _g(r.output_range), _g(r.max_pct, ".3f"),
             _g(r.rms_pct, ".3f")]
        )  # fmt: skip
        doubtful = (not r.exact_state) or r.n_out_of_range > 0
        styles.append('style="background: #fff3cd"' if doubtful else "")
        if not r.exact_state:
            notes.append(
                f"{r.experiment}: state not exact after the burn-in (offset may be biased)"
            )
        if r.n_out_of_range:
            notes.append(
                f"{r.experiment}: {r.n_out_of_range} input samples outside the model's range "
                "were clamped"
            )
    title = f"Verification of {_e(table.model_name or 'model')}"
    return (
        f"<div {_BOX}><b>{title}</b>"
        + _table(header, rows, row_styles=styles, caption="model &minus; measurement")
        + _warnings(notes)
        + "</div>"
    )


def property_test_html(result: Any) -> str:
    """HTML of a wiping-out or congruent-minor-loop test of recorded data: verdict, comparisons."""
    rng = result.output_range
    if hasattr(result, "pairs"):  # CongruencyResult
        title = (
            f"Congruent minor loops: {result.n_loops} loops, {len(result.pairs)} comparable pairs"
        )
        what = "max shape difference"
        header = ["low (V)", "high (V)", "t<sub>A</sub> (s)", "t<sub>B</sub> (s)", "shift (V)",
                  "shape difference (V)", "% of range"]  # fmt: skip
        rows = [
            [_g(p.low), _g(p.high), _g(p.t_a), _g(p.t_b), _g(p.shift), _g(p.shape_difference),
             _g(100 * p.shape_difference / rng, ".3f")]
            for p in result.pairs
        ]  # fmt: skip
        tested = bool(result.pairs)
    else:  # WipingOutResult
        title = f"Wiping-out: {len(result.comparisons)} returns to a reversal value"
        what = "max |dy|"
        header = ["branch", "level (V)", "t<sub>1</sub> (s)", "t<sub>2</sub> (s)",
                  "y<sub>1</sub> (V)", "y<sub>2</sub> (V)", "dy (V)", "% of range"]  # fmt: skip
        rows = [
            [_e(c.kind), _g(c.level), _g(c.t_first), _g(c.t_return), _g(c.y_first, ".5g"),
             _g(c.y_return, ".5g"), _g(c.difference), _g(100 * c.difference / rng, ".3f")]
            for c in result.comparisons
        ]  # fmt: skip
        tested = bool(result.comparisons)
    if not tested:
        verdict = f"<span {_BAD}>not testable</span> (nothing to compare in this recording)"
    else:
        word = f"<span {_GOOD}>pass</span>" if result.passed else f"<span {_BAD}>fail</span>"
        verdict = (
            f"{word}: {what} {_g(result.max_difference)} V = {_g(result.max_pct, '.3f')} % of "
            f"{_g(rng)} V (tolerance {_g(result.tolerance, 'g')} %)"
        )
    return (
        f"<div {_BOX}><b>{title}</b><div>{verdict}</div>"
        + (_table(header, rows, numeric_from=0) if rows else "")
        + "</div>"
    )


# ------------------------------------------------------------------------------ sweeps
_STATES = {"n": "&psi;<sub>n</sub>", "a": "&psi;<sub>a</sub>", "d": "&psi;<sub>d</sub>"}


def sweep_html(result: Any) -> str:
    """HTML of a SweepResult: mean &plusmn; std per state, Table 5.1, the thesis's claims."""
    import numpy as np

    metric = result.metric
    label = "drift (V)" if metric == "drift" else "n<sub>c</sub> (V)"
    seeds = sorted({r["seed"] for r in result.rows})
    parts = [
        f"<div {_BOX}><b>Regulation sweep: {_e(result.experiment)}</b> &mdash; "
        f"{len(result.rows)} trials, {len(seeds)} seeds, frequencies "
        f"{', '.join(format(f, 'g') for f in result.frequencies)} Hz, "
        f"K<sub>n</sub> {', '.join(format(g, 'g') for g in result.gains)}"
    ]
    rows = []
    for f in result.frequencies:
        for g in result.gains:
            cells = [f"{f:g}", f"{g:g}"]
            for k in result.kinds:
                v = result.values(f, k, g)
                sd = float(np.std(v, ddof=1)) if v.size > 1 else float("nan")
                cells.append(f"{_g(v.mean(), '+.4f')} &plusmn; {_g(sd, '.4f')}" if v.size else "")
            rows.append(cells)
    parts.append(
        _table(
            ["f (Hz)", "K<sub>n</sub>"]
            + [f"{_STATES.get(k, _e(k))} {label}" for k in result.kinds],
            rows,
            numeric_from=0,
            caption=f"{label}: mean &plusmn; std over seeds",
        )
    )
    if result.experiment == "closed-loop" and {"n", "a", "d"} <= set(result.kinds):
        fs = result.frequencies
        head = ["K<sub>n</sub>/max"] + [f"{_STATES['a']} {f:g} Hz" for f in fs]
        head += [f"{_STATES['d']} {f:g} Hz" for f in fs]
        body = [
            [_g(r["normalised_gain"], ".4f")]
            + [_g(r[f"{x}_{f:g}"], ".3f") for x in ("a", "d") for f in fs]
            for r in result.percentage_table()
        ]
        parts.append(
            _table(
                head,
                body,
                numeric_from=0,
                caption="Table 5.1: 100 (n<sub>c</sub>(&psi;<sub>x</sub>) &minus; "
                "n<sub>c</sub>(&psi;<sub>n</sub>)) / n<sub>c</sub>(&psi;<sub>n</sub>) (%)",
            )
        )
    comps = result.comparisons()
    if comps:

        def mark(ok: bool) -> str:
            return f"<span {_GOOD}>yes</span>" if ok else f"<span {_BAD}>no</span>"

        extra = ["a_up", "d_down"] if result.experiment == "drift" else []
        head = ["f (Hz)", "K<sub>n</sub>", "|&psi;<sub>n</sub>| smallest",
                "share |n| &lt; |a|", "share |n| &lt; |d|"]  # fmt: skip
        head += ["drift from &psi;<sub>a</sub> &gt; 0", "drift from &psi;<sub>d</sub> &lt; 0"][
            : len(extra)
        ]
        body = [
            [f"{c['frequency']:g}", f"{c['gain']:g}", mark(c["n_smallest"]),
             _g(c["frac_n_below_a"], ".2f"), _g(c["frac_n_below_d"], ".2f")]
            + [mark(c[x]) for x in extra]
            for c in comps
        ]  # fmt: skip
        parts.append(_table(head, body, numeric_from=0, caption="the thesis's claims, per cell"))
    parts.append("</div>")
    return "".join(parts)


# ------------------------------------------------------------------------------ diagnosis
def _param(p: dict[str, Any]) -> str:
    unit = f" {_e(p.get('unit', ''))}" if p.get("unit") else ""
    return f"{_g(p['value'])} &plusmn; {_g(p.get('std'), '.2g')}{unit}"


def diagnosis_html(report: Any, *, figure: bool = True) -> str:
    """HTML of a DiagnosisReport: verdict, effects with uncertainties, held-out RMSE, the figure."""
    mv, unit = report.display_unit()  # volts are shown in mV
    verdict_style = _GOOD if report.verdict == "none" else _BAD
    parts = [
        f"<div {_BOX}><div style='font-size: 1.15em'>verdict: "
        f"<span {verdict_style}>{_e(report.verdict)}</span></div>",
        f"<div>RMSE {_g(mv * report.rmse_before)} {_e(unit)} (given model) &rarr; "
        f"{_g(mv * report.rmse_after)} {_e(unit)} (augmented, held-out); noise "
        f"{_g(mv * report.noise_sigma, '.3g')} {_e(unit)}; {report.seconds:.1f} s</div>",
        _warnings(report.notes),
    ]
    if report.effects:
        rows = []
        for k, e in enumerate(report.effects, 1):
            params = "<br>".join(f"{_e(n)} = {_param(p)}" for n, p in e.parameters.items())
            rows.append(
                [f"{k}. <b>{_e(e.name)}</b>", _e(e.statement), params,
                 f"{_g(mv * e.heldout_rmse_before)} &rarr; {_g(mv * e.heldout_rmse_after)}"]
            )  # fmt: skip
        parts.append(
            _table(
                [
                    "effect",
                    "what it does",
                    "parameters (value &plusmn; std)",
                    f"held-out RMSE ({_e(unit)})",
                ],
                rows,
                numeric_from=3,
                caption="kept effects, most important first",
            )  # fmt: skip
        )
        parts.append(
            "<details><summary>evidence</summary><ul>"
            + "".join(f"<li><b>{_e(e.name)}</b>: {_e(e.evidence)}</li>" for e in report.effects)
            + "</ul></details>"
        )
    else:
        parts.append("<div>no effect lowered the held-out error beyond the noise.</div>")
    if report.candidates:
        rows = [
            [str(c["step"]), _e(c["name"]), _g(mv * c["heldout_rmse"]),
             _g(100 * c["gain"], ".1f"), _g(c["p_value"], ".3g"), str(c["n_params"]),
             "<b>kept</b>" if c["kept"] else _e(c["decision"])]
            for c in report.candidates
        ]  # fmt: skip
        parts.append(
            "<details><summary>candidates (held-out RMSE per selection step)</summary>"
            + _table(
                [
                    "step",
                    "candidate",
                    f"held-out RMSE ({_e(unit)})",
                    "gain %",
                    "p",
                    "k",
                    "decision",
                ],
                rows,
                numeric_from=2,
            )
            + "</details>"
        )
    if figure and report._recs:
        parts.append(
            "<details open><summary>residuals before/after (held-out)</summary>"
            + figure_img(
                lambda fig: report.plot(fig=fig), figsize=(14, 12), dpi=50, alt="diagnosis figure"
            )  # fmt: skip
            + "</details>"
        )
    parts.append("</div>")
    return "".join(parts)
