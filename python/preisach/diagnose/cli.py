"""``preisach diagnose``: the command line of :func:`preisach.diagnose.diagnose`.

``cli.main`` wires :func:`add_parser` in; this module only registers the subcommand.
"""

from __future__ import annotations

import argparse
import os
from typing import TYPE_CHECKING, cast

from .._io import save_figure

if TYPE_CHECKING:  # pragma: no cover
    from ..model import PreisachModel

__all__ = ["add_parser"]


def _model(spec: str) -> PreisachModel:
    from ..model import BUILTIN_MODELS, PreisachModel
    from .augmented import AugmentedModel, load_model

    if spec.lower() in BUILTIN_MODELS:
        return PreisachModel.builtin(spec.lower())
    if not os.path.exists(spec):
        raise OSError(
            f"MODEL: no such file {spec!r} (and not a built-in model: {sorted(BUILTIN_MODELS)})"
        )
    m = load_model(spec)
    if isinstance(m, AugmentedModel):
        raise ValueError(
            f"MODEL: {spec} is an augmented model; diagnose its classical base, or the model it "
            "was diagnosed from"
        )
    return m


def _run(args: argparse.Namespace) -> int:
    from .core import diagnose

    model = _model(args.model)
    cands = [c.strip() for c in args.candidates.split(",")] if args.candidates else None
    report = diagnose(
        model,
        args.recordings,
        identification=(
            args.identification or None
            if not args.no_stored_identification
            else args.identification
        ),
        candidates=cands,
        cv=args.cv,
        max_effects=args.max_effects,
        min_gain=args.min_gain,
        noise_ratio=args.noise_ratio,
        progress=None if args.quiet else print,
    )
    report.to_json(args.json)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        fig = report.plot()
        save_figure(fig, args.plot, dpi=110)
    if args.save_model:
        report.model.save(args.save_model)
    if not args.quiet:
        print(report.summary())
        print(
            f"wrote {args.json}"
            + (f", {args.plot}" if args.plot else "")
            + (f", {args.save_model}" if args.save_model else "")
        )
    return 0


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Register ``preisach diagnose`` on ``subparsers``; returns its parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="find where a model and recordings disagree, name the missing physics, model it",
        description="Simulate every recording through MODEL, analyse the residual (where, when, "
        "which band, what it follows), fit candidate physics blocks (rate dependence, structural "
        "resonance, "
        "creep, delay, sensor drift, non-congruence, calibration) on training "
        "blocks and keep those that lower the held-out error clearly beyond the noise.  Volts and "
        "seconds throughout.",
    )
    p.add_argument(
        "model",
        metavar="MODEL",
        help="model file (.npz from `PreisachModel.save`) or a built-in name (ss15-1hz, ...)",
    )
    p.add_argument(
        "recordings", metavar="REC", nargs="+", help="recordings (.csv or .npz) of the same device"
    )
    p.add_argument("--json", metavar="REPORT", required=True, help="write the report (JSON) here")
    p.add_argument("--plot", metavar="FIG", help="write the diagnosis figure (e.g. diagnosis.png)")
    p.add_argument("--save-model", metavar="OUT", help="write the augmented model (.npz)")
    p.add_argument(
        "--identification",
        metavar="REC",
        action="append",
        default=[],
        help="recording the model was identified from (repeatable); the Preisach weights are then "
        "refitted together with every candidate.  Default: the recordings MODEL carries (stored by "
        "`preisach identify`).  It is training data only: a REC holding the same samples is left "
        "out of the diagnosis with a warning",
    )
    p.add_argument(
        "--no-stored-identification",
        action="store_true",
        help="ignore the identification recordings stored in MODEL (no refit of the weights "
        "unless --identification is given)",
    )
    p.add_argument(
        "--noise-ratio",
        type=float,
        default=2.0,
        help="noise test: the verdict is 'none' only when nothing is kept and the held-out RMSE "
        "is at most this many times the noise estimated from the data; above it 'unexplained' "
        "(default 2)",
    )
    p.add_argument(
        "--candidates",
        help="comma-separated effect names (all their forms) or form keys such as "
        "delay/lagrange (default: all)",
    )
    p.add_argument(
        "--cv",
        choices=("auto", "blocks", "recordings"),
        default="auto",
        help="held-out scheme (default: alternating time blocks)",
    )
    p.add_argument("--max-effects", type=int, default=3, help="most effects kept (default 3)")
    p.add_argument(
        "--min-gain",
        type=float,
        default=0.10,
        help="smallest relative held-out RMSE reduction of a kept effect (default 0.10)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=_run)
    return cast(argparse.ArgumentParser, p)
