"""``preisach identify`` and ``preisach verify``: identification and verification from the shell.

::

    preisach identify REC [REC ...] -o MODEL [--method fod|surface|lsq] [--levels N] ...
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
from typing import Any

from .._io import save_figure, write_json
from .identifiers import MAX_FOD_LEVELS

__all__ = ["add_parser"]

_POLICIES = ("burn-in", "negative", "positive", "anhysteretic")


def _load_recordings(paths: list[str]) -> list[Any]:
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


def _save_figure(path: str | None, fig: Any) -> None:
    if path:
        save_figure(fig, path, dpi=110)
        print(f"wrote {path}")


def _identify(args: argparse.Namespace) -> int:
    from .identifiers import identify_fod, identify_lsq, identify_surface

    if args.levels is not None and args.levels < 3:
        raise ValueError(f"--levels: need at least 3 levels, got {args.levels}")
    if args.y_min_source is not None and args.method != "surface":
        raise ValueError("--y-min-source applies to --method surface only")
    if args.delay < 0:
        raise ValueError(f"--delay: need a number of samples >= 0, got {args.delay}")
    recs = _load_recordings(args.recordings)
    if args.method == "rate":
        from .rate import run_cli

        return run_cli(args, recs, _write_json)
    common = {"name": args.name, "initial_state": args.initial_state, "delay": args.delay}
    if args.method == "fod":
        model, report = identify_fod(recs, args.levels, project=args.project, **common)
    elif args.method == "surface":
        if args.project:
            raise ValueError("--project applies to --method fod only")
        model, report = identify_surface(
            recs, args.levels, y_min_source=args.y_min_source or "column_mean", **common
        )
    else:
        if args.project:
            raise ValueError("--project applies to --method fod only (lsq imposes mu >= 0 itself)")
        model, report = identify_lsq(
            recs, 41 if args.levels is None else args.levels, folds=args.folds, **common
        )
    out = Path(args.output)
    if out.parent and not out.parent.exists():
        raise OSError(f"{out.parent}: output folder does not exist")
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

    if args.delay < 0:
        raise ValueError(f"--delay: need a number of samples >= 0, got {args.delay}")
    model = PreisachModel.load(args.model)
    if not model.name:
        model.name = Path(args.model).stem
    recs = _load_recordings(args.recordings)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = verify(
            model,
            recs,
            initial_state=args.initial_state,
            delay=args.delay,
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


def add_parser(subparsers: Any) -> None:
    """Register ``identify`` and ``verify`` on the ``preisach`` command's subparsers."""
    p = subparsers.add_parser(
        "identify",
        help="identify a Preisach model from recordings (Mayergoyz, sqrt surface, least squares)",
        description="Identify a Preisach model from recordings (CSV/NPZ with t, u, y in s, V, V), "
        "write it to MODEL (read by PreisachModel.load and every later command) and print the "
        "report: data used, residuals (V and % of the output range), warnings.",
    )
    p.add_argument("recordings", nargs="+", metavar="REC", help="recording files (.csv or .npz)")
    p.add_argument(
        "-o", "--output", required=True, metavar="MODEL", help="model file to write (.npz)"
    )
    p.add_argument(
        "--method",
        choices=("fod", "surface", "lsq", "rate"),
        default="fod",
        help="fod: Mayergoyz from FOD curves (default); surface: the thesis's square-root "
        "FOD surface; lsq: least squares on every sample of any excitation; rate: a "
        "rate-dependent model from recordings at two or more rates",
    )
    p.add_argument(
        "--levels",
        type=int,
        default=None,
        metavar="N",
        help="grid levels: FOD grid for fod/surface (default: inferred from the turning "
        f"values; at most {MAX_FOD_LEVELS}), table levels for lsq (default 41)",
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
        "--delay",
        type=int,
        default=0,
        metavar="D",
        help="output delay in samples: y[k+D] answers u[k] (default 0)",
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
    p.set_defaults(func=_identify)

    v = subparsers.add_parser(
        "verify",
        help="simulate recordings through a model and print max/RMS errors per experiment",
        description="Simulate each recording's input through MODEL and print the maximum and RMS "
        "error in volts and in % of the output range per experiment; --properties also tests "
        "the recordings for the wiping-out and congruent-minor-loop properties.",
    )
    v.add_argument("model", metavar="MODEL", help="model file written by `preisach identify`")
    v.add_argument("recordings", nargs="+", metavar="REC", help="recording files (.csv or .npz)")
    v.add_argument(
        "--delay", type=int, default=0, metavar="D", help="output delay in samples (default 0)"
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
