"""``preisach experiment drift|closed-loop|locus``: the regulation experiments from the shell.

Wire it into the main parser with ``add_parser(subparsers)``; every command writes JSON and can
write a figure.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from .._io import save_figure, write_json
from ..execution import add_scheduler_argument
from ..model import BUILTIN_MODELS, PreisachModel
from ..neutral import check_mp, neutral_locus
from ..noise import NoiseSpec
from .plant import ModelPlant, thesis_sample_time
from .protocol import THESIS_GAINS, ClosedLoopProtocol, DriftProtocol
from .sweep import regulation_sweep, state_slopes

__all__ = ["add_parser"]


def _load_model(spec: str) -> PreisachModel:
    if spec.lower() in BUILTIN_MODELS:
        return PreisachModel.builtin(spec.lower())
    path = Path(spec)
    if not path.exists():
        raise ValueError(
            f"--model {spec!r}: neither a built-in model ({', '.join(sorted(BUILTIN_MODELS))}, "
            "or 'ss15' for all three) nor an existing model file"
        )
    return PreisachModel.load(path)


def _model_frequency(model: PreisachModel) -> float | None:
    key = model.metadata.get("builtin")
    if key in BUILTIN_MODELS:
        return float(BUILTIN_MODELS[key])
    f = (model.metadata.get("surface") or {}).get("frequency")
    if isinstance(f, (int, float)) and math.isfinite(f) and f > 0:
        return float(f)
    return None


def _expand(specs: list[str]) -> list[str]:
    out: list[str] = []
    for s in specs:
        out.extend(
            sorted(BUILTIN_MODELS, key=BUILTIN_MODELS.__getitem__) if s.lower() == "ss15" else [s]
        )
    return out


def _models(args: argparse.Namespace) -> list[tuple[float, PreisachModel, str]]:
    specs = _expand(args.model)
    freqs = args.frequency or []
    if freqs and len(freqs) not in (1, len(specs)):
        raise ValueError(
            f"--frequency: give it once or once per model ({len(specs)}), got {len(freqs)}"
        )
    out = []
    for i, s in enumerate(specs):
        m = _load_model(s)
        f = freqs[0 if len(freqs) == 1 else i] if freqs else _model_frequency(m)
        if f is None:
            raise ValueError(
                f"--model {s!r}: its identification frequency is unknown; give --frequency"
            )
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"--frequency: must be a positive number of Hz, got {f!r}")
        out.append((float(f), m, s))
    fs = [f for f, _, _ in out]
    if len(set(fs)) != len(fs):
        raise ValueError(f"each model needs its own initialisation frequency; got {fs} Hz")
    return out


def _float_list(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from exc
    if not vals:
        raise argparse.ArgumentTypeError("expected at least one number")
    return vals


def _gains(text: str) -> list[float]:
    vals = _float_list(text)
    bad = [v for v in vals if not (math.isfinite(v) and v >= 0)]
    if bad:
        raise argparse.ArgumentTypeError(f"noise gains must be finite and >= 0, got {bad}")
    return vals


def _gain(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"controller gains must be finite and >= 0, got {v:g}")
    return v


def _states(text: str) -> list[str]:
    vals = [v.strip().lower().removeprefix("psi_") for v in text.split(",") if v.strip()]
    bad = [v for v in vals if v not in ("n", "a", "d")]
    if bad or not vals:
        raise argparse.ArgumentTypeError(
            f"expected a comma-separated subset of n,a,d, got {text!r}"
        )
    return vals


def _clean(o: Any) -> Any:
    """Make ``o`` strict JSON: NumPy scalars and arrays to Python, NaN and inf to None."""
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return [_clean(v) for v in o.tolist()]
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def _write_json(path: str, data: dict[str, Any]) -> None:
    write_json(path, _clean(data), indent=1, allow_nan=False)


def _save_figure(fig: Any, path: str | None) -> None:
    if path:
        save_figure(fig, path, dpi=120)


def _run_sweep(args: argparse.Namespace) -> int:
    models = _models(args)
    noise = NoiseSpec(amplitude=args.noise_amplitude)
    if args.command_name == "drift":
        proto: DriftProtocol | ClosedLoopProtocol = DriftProtocol(
            noise=noise, input_gain=args.input_gain
        )
    else:
        proto = ClosedLoopProtocol(
            kp=args.kp,
            ki=args.ki,
            average_window=args.average,
            noise=noise,
            input_gain=args.input_gain,
        )
    plants = {f: ModelPlant(m, args.sample_time or thesis_sample_time(f)) for f, m, _ in models}
    if args.seeds < 1:
        raise ValueError(f"--seeds: need at least 1, got {args.seeds}")
    init_opts = {"cycles": args.cycles, "tolerance": args.tolerance, "thresholds": args.thresholds}
    res = regulation_sweep(
        args.command_name,
        plants,
        states=args.states,
        gains=args.gains,
        seeds=range(args.seed_start, args.seed_start + args.seeds),
        y_d=args.y_d,
        protocol=proto,
        init_options=init_opts,
        scheduler=args.scheduler,
        store=args.store,
        progress=not args.quiet,
    )
    data = res.to_dict()
    data["models"] = {f"{f:g}": spec for f, _, spec in models}
    _write_json(args.json, data)
    if args.csv:
        res.to_csv(args.csv)
    if args.plot:
        _save_figure(res.plot(), args.plot)
    print(
        f"preisach experiment {args.command_name}: {len(res.rows)} trials "
        f"({', '.join(f'{f:g} Hz: {s}' for f, _, s in models)}); mean +/- std over "
        f"{args.seeds} seed(s)"
    )
    print(res.format_summary())
    if args.command_name == "closed-loop" and {"n", "a", "d"} <= set(args.states):
        print("\n(n_c(psi_x) - n_c(psi_n)) / n_c(psi_n) in percent (Table 5.1):")
        print(res.format_percentage_table())
    print(
        f"wrote {args.json}"
        + (f", {args.csv}" if args.csv else "")
        + (f", {args.plot}" if args.plot else "")
    )
    return 0


def _run_locus(args: argparse.Namespace) -> int:
    models = [(_load_model(s), s) for s in _expand(args.model)]
    out: dict[str, Any] = {"y_d": args.y_d, "models": []}
    figs = []
    for m, spec in models:
        loc = neutral_locus(m, points=args.points)
        mp = check_mp(m, args.mp_tolerance)
        entry: dict[str, Any] = {"model": spec, **loc.to_dict(), "mp": mp.to_dict()}
        method = "2.19 (N monotone: inverse)" if loc.monotone else "2.20 (smallest |l|)"
        lo, hi = loc.y_range
        if lo <= args.y_d <= hi:
            l_inv = loc.inverse(args.y_d)
            s = m.neutral_state(l_inv)
            entry.update(
                {
                    "l_inverse": l_inv,
                    "method": method,
                    "solutions": loc.solutions(args.y_d).tolist(),
                    "slopes_at_neutral": state_slopes(m, s),
                }
            )
        else:
            l_inv = None
            entry.update({"l_inverse": None, "method": method, "solutions": []})
        out["models"].append(entry)
        print(
            f"{spec}: N(l) on {len(loc.l)} offsets, "
            f"{'monotone' if loc.monotone else 'NOT monotone'}; {mp}"
        )
        if l_inv is not None:
            sl = entry["slopes_at_neutral"]
            print(
                f"  N_inv({args.y_d:g} V) = {l_inv:.6f} V by Eq {method}; dy/du+ = "
                f"{sl['dy_du_rising']:.5f}, dy/du- = {sl['dy_du_falling']:.5f} V/V"
            )
        else:
            print(f"  y_d = {args.y_d:g} V is outside N's range [{lo:.4g}, {hi:.4g}] V")
        if args.plot:
            figs.append((loc, m, spec, l_inv))
    _write_json(args.json, out)
    if args.plot:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(4.8 * len(figs), 4.2))
        axes = np.atleast_1d(fig.subplots(1, len(figs), squeeze=False)[0])
        for ax, (loc, m, spec, l_inv) in zip(axes, figs):
            pts = {f"psi_n, y_d = {args.y_d:g} V": (l_inv, args.y_d)} if l_inv is not None else None
            loc.plot(ax=ax, model=m, points=pts, title=spec)
        fig.tight_layout()
        _save_figure(fig, args.plot)
    print(f"wrote {args.json}" + (f", {args.plot}" if args.plot else ""))
    return 0


def _common(p: argparse.ArgumentParser, frequency: bool = True) -> None:
    p.add_argument(
        "--model",
        action="append",
        required=True,
        metavar="MODEL",
        help="built-in model (ss15-1hz, ss15-2hz, ss15-4hz; 'ss15' for all three) or a model "
        "file written by PreisachModel.save; repeat for several models",
    )
    if frequency:
        p.add_argument(
            "--frequency",
            action="append",
            type=float,
            metavar="HZ",
            help="initialisation frequency (Hz); default the model's identification "
            "frequency; give once, or once per --model",
        )
    p.add_argument(
        "--y-d", type=float, default=1.0, help="desired output y_d (V) (default: %(default)s)"
    )
    p.add_argument("--json", required=True, metavar="OUT", help="write the results as JSON to OUT")
    p.add_argument(
        "--plot", metavar="FIG", help="write a figure (format from the extension, e.g. .png)"
    )


def _sweep_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--states",
        type=_states,
        default=["n", "a", "d"],
        help="initial states, comma-separated subset of n,a,d (default: all)",
    )
    p.add_argument(
        "--gains",
        type=_gains,
        default=list(THESIS_GAINS),
        help="noise gains K_n, comma-separated (default: 0.8,1.6,...,5.6)",
    )
    p.add_argument(
        "--seeds", type=int, default=20, help="number of noise seeds (default: %(default)s)"
    )
    p.add_argument("--seed-start", type=int, default=0, help="first seed (default: %(default)s)")
    p.add_argument(
        "--sample-time",
        type=float,
        default=None,
        metavar="S",
        help="sample time (s); default 1 ms, 0.5 ms at 4 Hz (thesis §5.1)",
    )
    p.add_argument(
        "--input-gain",
        type=float,
        default=DriftProtocol().input_gain,
        help="model-input volts per DAQ volt for noise and controller (default: %(default)s, "
        "the SS15 amplifier of Eq B.2; 1 states them in model volts)",
    )
    p.add_argument(
        "--noise-amplitude",
        type=float,
        default=0.5,
        help="noise peak at K_n = 1 (DAQ V) (default: %(default)s)",
    )
    p.add_argument(
        "--cycles",
        type=float,
        default=10.0,
        help="periods of the decaying sinusoid that reaches psi_n (default: %(default)s)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=0.03,
        help="landing tolerance around y_d (V) (default: %(default)s, thesis simulation)",
    )
    p.add_argument(
        "--thresholds",
        choices=("simulation", "experiment"),
        default="simulation",
        help="landing windows: y_d +/- tolerance, or Table 4.1 for psi_a/psi_d",
    )
    p.add_argument(
        "--csv", metavar="CSV", help="also write the tidy table (one row per trial) as CSV"
    )
    add_scheduler_argument(p, default="serial")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``experiment`` with its subcommands ``drift``, ``closed-loop`` and ``locus``.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The main parser's subparsers.

    Returns
    -------
    argparse.ArgumentParser
        The ``experiment`` parser.

    """
    exp = subparsers.add_parser(
        "experiment",
        help="regulation experiments of chapters 4-5 (drift, closed loop, neutral locus)",
        description="Run the thesis's regulation experiments on a Preisach model: the open-loop "
        "drift test (§4.2), the closed-loop PI test (§5.1) over noise gains, initial states "
        "psi_n/psi_a/psi_d and seeds, or the neutral locus N(l) (§2.8). Volts in, volts out.",
    )
    sub = exp.add_subparsers(dest="command_name", metavar="EXPERIMENT", required=True)
    d = sub.add_parser(
        "drift",
        help="open-loop drift test: ybar(8,10) - ybar(0,2) under input noise",
        description="Open-loop drift test (thesis §4.2): from psi_n, psi_a, psi_d with output "
        "y_d, hold 2 s, then 8 s of noise scaled by K_n.",
    )
    _common(d)
    _sweep_options(d)
    d.set_defaults(func=_run_sweep)
    c = sub.add_parser(
        "closed-loop",
        help="closed-loop PI test: control effort n_c (Eq 5.3)",
        description="Closed-loop PI test (thesis §5.1): controller on at t1+1 s, noise from "
        "t1+2 to t1+10 s, end at t1+12 s; n_c = ||u_cn - ubar_c||_2.",
    )
    _common(c)
    _sweep_options(c)
    c.add_argument("--kp", type=_gain, default=1.5, help="proportional gain (default: %(default)s)")
    c.add_argument("--ki", type=_gain, default=30.0, help="integral gain (default: %(default)s)")
    c.add_argument(
        "--average",
        type=float,
        default=0.0,
        metavar="S",
        help="average the error over the last S seconds (thesis experiments: 0.025; "
        "default: %(default)s, none)",
    )
    c.set_defaults(func=_run_sweep)
    loc = sub.add_parser(
        "locus",
        help="neutral locus N(l), N_inv(y_d) and the Mp check",
        description="The neutral locus N(l) (Eq 2.18) from the exact neutral boundary, "
        "N_inv(y_d) (Eq 2.19/2.20), the slopes at psi_n and whether mu is in Mp.",
    )
    _common(loc, frequency=False)
    loc.add_argument(
        "--points",
        type=int,
        default=None,
        help="offsets on the grid (default: 2 x table levels - 1)",
    )
    loc.add_argument(
        "--mp-tolerance",
        type=float,
        default=0.0,
        help="cell masses down to -TOL (V) count as non-negative (default: %(default)s)",
    )
    loc.set_defaults(func=_run_locus)
    __import__("preisach.compensate.cli", fromlist=["cli"]).add_tracking_parser(sub)
    return exp
