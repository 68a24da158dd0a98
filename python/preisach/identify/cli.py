"""``preisach identify`` and ``preisach verify``: identification and verification from the shell.

::

    preisach identify REC [REC ...] -o MODEL [--method auto|fod|surface|lsq] [--levels N] ...
    preisach identify FILE.forc -o MODEL                 (a MicroMag FORC measurement)
    preisach verify MODEL REC [REC ...] [--delay D] [--properties] ...

Recordings are read with :meth:`preisach.Recording.load` (``.csv`` or ``.npz``); the model is
written with :meth:`preisach.PreisachModel.save` and read with :meth:`PreisachModel.load`.
Both commands print a report, can write it as JSON (``--json``) and a figure (``--plot``).
Bad input raises ValueError/OSError, which ``preisach`` turns into "preisach CMD: error: ..."
and exit status 1.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._io import save_figure, write_json
from .identifiers import MAX_FOD_LEVELS

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..recording import Recording

__all__ = ["add_parser"]

_POLICIES = ("burn-in", "negative", "positive", "anhysteretic")


def _load_recordings(paths: list[str]) -> list[Recording]:
    from ..recording import Recording

    recs = []
    for p in paths:
        rec = Recording.load(p)
        if len(rec.u) < 2:
            raise ValueError(f"{p}: a recording needs at least 2 samples, got {len(rec.u)}")
        if "experiment" not in rec.metadata or not str(rec.metadata["experiment"]):
            rec.metadata["experiment"] = Path(p).stem
        recs.append(rec)
    return recs


def _write_json(path: str | None, obj: dict[str, Any]) -> None:
    if path:
        write_json(path, obj, indent=2, default=float)
        print(f"wrote {path}")


def _save_figure(path: str | None, fig: Figure) -> None:
    if path:
        save_figure(fig, path, dpi=110)
        print(f"wrote {path}")


def _delay_arg(text: str) -> float | str:
    """``--delay``: ``auto`` or a number of samples >= 0 (fractional allowed)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        d = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'auto' or a number of samples >= 0, got {text!r}"
        ) from None
    if not d >= 0.0 or d == float("inf"):
        raise argparse.ArgumentTypeError(f"need a number of samples >= 0, got {text!r}")
    return int(d) if d == int(d) else d


def _delay_number(text: str) -> float:
    """``verify --delay``: a number of samples >= 0."""
    d = _delay_arg(text)
    if isinstance(d, str):
        raise argparse.ArgumentTypeError("give the delay in samples (verify does not estimate it)")
    return float(d)


def _identify(args: argparse.Namespace) -> int:
    from .auto import identify

    if args.levels is not None and args.levels < 3:
        raise ValueError(f"--levels: need at least 3 levels, got {args.levels}")
    if args.y_min_source is not None and args.method != "surface":
        raise ValueError("--y-min-source applies to --method surface only")
    if args.method == "rate":  # the rate-dependent model (identify/rate.py) has no delay
        from .rate import run_cli

        if args.delay == "auto":
            args.delay = 0
        return run_cli(args, _load_recordings(args.recordings), _write_json)
    if args.project and args.method not in ("fod", "auto"):
        raise ValueError("--project applies to --method fod only (lsq imposes mu >= 0 itself)")
    forc = [p for p in args.recordings if Path(p).suffix.lower() == ".forc"]
    if forc:
        if len(forc) != len(args.recordings) or len(forc) > 1:
            raise ValueError("a FORC file (.forc) is identified on its own: give one file")
        from .forc_identify import identify_forc

        report = identify_forc(
            forc[0],
            method=args.method,
            levels=args.levels,
            name=args.name,
            project=args.project,
            delay=args.delay,
            folds=args.folds,
            solver=args.solver,
        )
    else:
        recs = _load_recordings(args.recordings)
        report = identify(
            recs,
            args.method,
            args.levels,
            delay=args.delay,
            initial_state=args.initial_state,
            name=args.name,
            project=args.project,
            folds=args.folds,
            solver=args.solver,
            y_min_source=args.y_min_source or "column_mean",
            progress=not args.quiet,
            interpolation=args.interpolation,
        )
    model = report.model
    out = Path(args.output)
    if out.parent and not out.parent.exists():
        raise OSError(f"{out.parent}: output folder does not exist")
    if not forc:  # diagnosis refits the weights on them by default (not on FORC moments)
        model.identification = list(recs)
    model.save(out)
    print(report.summary())
    print(f"wrote {out}")
    _write_json(args.json, report.to_dict())
    if args.plot:
        _save_figure(args.plot, report.plot())
    return 0


def _verify(args: argparse.Namespace) -> int:
    from ..model import PreisachModel
    from ..verify import congruency_metric, verify, wiping_out_metric
    from .delay import shift_output

    model = PreisachModel.load(args.model)
    if not model.name:
        model.name = Path(args.model).stem
    recs = _load_recordings(args.recordings)
    delay = args.delay
    if delay is None:  # the delay the model was identified with (0 for older model files)
        stored = model.metadata.get("delay", 0)
        delay = float(stored) if isinstance(stored, (int, float)) else 0.0
        if delay:
            print(f"output delay {delay:g} samples (stored in {args.model}; --delay overrides)")
    if delay != int(delay):  # fractional: pair the samples by shifting the recordings
        recs = [shift_output(r, delay) for r in recs]
        delay = 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = verify(
            model,
            recs,
            initial_state=args.initial_state,
            delay=int(delay),
            output_range=args.output_range,
        )
    for w in caught:  # e.g. inputs outside the model's range (the "clamped" column)
        print(f"preisach verify: warning: {w.message}", file=sys.stderr)
    print(table.table())
    result: dict[str, Any] = table.to_dict()
    if args.properties:
        props = []
        for rec in recs:
            name = str(rec.metadata["experiment"])
            wo = wiping_out_metric(rec, tolerance=args.tolerance, output_range=args.output_range)
            cml = congruency_metric(rec, tolerance=args.tolerance, output_range=args.output_range)
            print(f"\n{name}:\n{wo.table()}\n{cml.table()}")
            props.append(
                {"experiment": name, "wiping_out": wo.to_dict(), "congruency": cml.to_dict()}
            )
        result["properties"] = props
    _write_json(args.json, result)
    if args.plot:
        _save_figure(args.plot, table.plot())
    return 0


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``identify`` and ``verify`` on the ``preisach`` command's subparsers."""
    p = subparsers.add_parser(
        "identify",
        help="identify a Preisach model from recordings (Mayergoyz, sqrt surface, least squares)",
        description="Identify a Preisach model from recordings (CSV/NPZ with t, u, y in s, V, V), "
        "write it to MODEL (read by PreisachModel.load and every later command) and print the "
        "report: method chosen and why, output delay, data used, residuals (in the recording's "
        "units and % of the output range), warnings.  A MicroMag FORC file (.forc) is read with "
        "its units and drift-corrected from its calibration points.",
    )
    p.add_argument("recordings", nargs="+", metavar="REC", help="recording files (.csv or .npz)")
    p.add_argument(
        "-o", "--output", required=True, metavar="MODEL", help="model file to write (.npz)"
    )
    p.add_argument(
        "--method",
        choices=("auto", "fod", "surface", "lsq", "rate"),
        default="auto",
        help="auto (default): fod when the recordings hold FOD (or FORC) curves measuring at "
        "least 90%% of their grid, lsq otherwise, and the report says why; fod: Mayergoyz from "
        "FOD curves; surface: the thesis's square-root FOD surface; lsq: least squares on "
        "every sample of any excitation; rate: a rate-dependent model from recordings at two "
        "or more rates",
    )
    p.add_argument(
        "--levels",
        type=int,
        default=None,
        metavar="N",
        help="grid levels: FOD grid for fod/surface (default: inferred from the turning "
        f"values; at most {MAX_FOD_LEVELS}), table levels for lsq (default 41; at most 401)",
    )
    p.add_argument(
        "--solver",
        choices=("auto", "dense", "sparse"),
        default="auto",
        help="lsq: dense (exact mu >= 0, up to 81 levels) or sparse (conjugate gradients on "
        "the Everett nodes, fine tables); auto (default): dense up to 41 levels",
    )
    p.add_argument(
        "--project",
        action="store_true",
        help="fod: project the table to the nearest one with mu >= 0",
    )
    p.add_argument(
        "--y-min-source",
        choices=("column_mean", "corner"),
        default=None,
        help="surface: y_min of Eq 3.1 from the measured corner y(u_hat, -u_hat) ('corner', "
        "as the thesis states) or the mean of every FOD curve's end point ('column_mean', the "
        "default: the same output measured n times, less noise)",
    )
    p.add_argument("--folds", type=int, default=5, help="lsq: cross-validation folds (default 5)")
    p.add_argument(
        "--interpolation",
        choices=("auto", "bilinear", "cubic"),
        default="auto",
        help="fod: the Everett table's interpolation between the nodes (auto, the default: "
        "cubic when it leaves 10 %% less residual on the recordings than bilinear)",
    )
    p.add_argument(
        "--delay",
        type=_delay_arg,
        default="auto",
        metavar="D",
        help="output delay in samples, y[k+D] answers u[k], applied by every method; "
        "fractional allowed; auto (default): estimated and reported (whole samples scored by "
        "the Mayergoyz model's own residual for FOD/FORC data, cross-validated otherwise)",
    )
    p.add_argument(
        "--initial-state",
        choices=_POLICIES,
        default="burn-in",
        help="initial state of the recordings (default burn-in: skip samples until the "
        "state is known)",
    )
    p.add_argument("--name", default="", help="model name stored in the file")
    p.add_argument("--json", metavar="PATH", help="also write the report as JSON")
    p.add_argument("--plot", metavar="PNG", help="also write the report figure")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_identify)

    v = subparsers.add_parser(
        "verify",
        help="simulate recordings through a model and print max/RMS errors per experiment",
        description="Simulate each recording's input through MODEL and print the maximum and RMS "
        "error in the recording's units and in % of the output range per experiment; "
        "--properties also tests the recordings for the wiping-out and congruent-minor-loop "
        "properties.",
    )
    v.add_argument("model", metavar="MODEL", help="model file written by `preisach identify`")
    v.add_argument("recordings", nargs="+", metavar="REC", help="recording files (.csv or .npz)")
    v.add_argument(
        "--delay",
        type=_delay_number,
        default=None,
        metavar="D",
        help="output delay in samples, fractional allowed (default: the delay stored in MODEL "
        "by `preisach identify`, 0 for older files)",
    )
    v.add_argument(
        "--initial-state",
        choices=_POLICIES,
        default="burn-in",
        help="initial state (default burn-in: score samples once the state is known)",
    )
    v.add_argument(
        "--output-range",
        type=float,
        default=None,
        metavar="V",
        help="output range (V) for the percentages (default: each recording's)",
    )
    v.add_argument(
        "--properties",
        action="store_true",
        help="also run the wiping-out and congruent-minor-loop tests on the recordings",
    )
    v.add_argument(
        "--tolerance",
        type=float,
        default=5.0,
        metavar="PCT",
        help="pass/fail threshold of the property tests, %% of the output range "
        "(default 5, the thesis's)",
    )
    v.add_argument("--json", metavar="PATH", help="also write the table as JSON")
    v.add_argument("--plot", metavar="PNG", help="also write a figure of outputs and errors")
    v.set_defaults(func=_verify)

    f = subparsers.add_parser(
        "forc",
        help="FORC diagram of a MicroMag FORC file (local polynomial regression, smoothing SF)",
        description="Compute the FORC distribution rho = -1/2 d2M/(dHr dH) of a MicroMag .forc "
        "file by local second-order polynomial regression over (2 SF + 1)^2 points (Pike et al. "
        "1999), after drift correction from the calibration points, and draw it in "
        "(H_c, H_u) in the file's units.  Outside the measured band (H < H_r) nothing is "
        "extrapolated: windows at the edge use their measured points only and rho is not drawn "
        "there.",
    )
    f.add_argument("file", metavar="FILE", help="MicroMag FORC file (.forc)")
    f.add_argument("--sf", type=int, default=3, metavar="SF", help="smoothing factor (default 3)")
    f.add_argument(
        "--no-drift", action="store_true", help="do not correct the drift (calibration points)"
    )
    f.add_argument("--plot", metavar="PNG", help="write the FORC diagram figure")
    f.add_argument("--json", metavar="PATH", help="also write the diagram's summary as JSON")
    f.set_defaults(func=_forc)


def _forc(args: argparse.Namespace) -> int:
    import numpy as np

    from .forc_identify import forc_diagram

    if args.sf < 1:
        raise ValueError(f"--sf: need a smoothing factor >= 1, got {args.sf}")
    d = forc_diagram(args.file, args.sf, drift=not args.no_drift)
    ok = np.isfinite(d.rho)
    full = ok & d.full_window  # the peak where the whole window was measured
    k = np.unravel_index(int(np.argmax(np.where(full, d.rho, -np.inf))), d.rho.shape)
    fu, mu = d.field_units, d.moment_units
    summary = {
        "curves": int(d.h_r.size),
        "smoothing_factor": d.smoothing_factor,
        "field_units": fu,
        "moment_units": mu,
        "points_defined": int(ok.sum()),
        "points_measured": int(np.isfinite(d.moment).sum()),
        "points_full_window": int(full.sum()),
        "peak_rho": float(d.rho[k]),
        "peak_h_c": float(d.h_c[k]),
        "peak_h_u": float(d.h_u[k]),
    }
    print(
        f"FORC diagram of {args.file}: {summary['curves']} curves, SF = {d.smoothing_factor}, "
        f"rho defined at {summary['points_defined']} of {summary['points_measured']} measured "
        f"points (none outside the measured band H >= H_r)"
    )
    print(
        f"peak rho {summary['peak_rho']:.4g} {mu}/{fu}^2 at H_c = {summary['peak_h_c']:.4g} {fu}, "
        f"H_u = {summary['peak_h_u']:.4g} {fu} (over the {summary['points_full_window']} points "
        "whose whole window was measured)"
    )
    _write_json(args.json, summary)
    if args.plot:
        _save_figure(args.plot, d.plot())
    return 0
