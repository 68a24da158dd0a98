"""``preisach compensate``: the feedforward drive that makes a model follow a reference.

::

    preisach compensate MODEL REF.csv -o DRIVE.csv [--state negative|positive|anhysteretic]

``REF.csv`` is a recording-format CSV (``# key: value`` metadata lines, a header row, data
rows) with at least the columns ``t`` (s, strictly increasing) and ``y`` (the desired output,
V); other columns are ignored.  ``DRIVE.csv`` is a recording with ``t``, ``u`` (the drive, V),
``y`` (the model's predicted output, V), ``y_ref`` and ``reached`` (1 where the target was
reachable), written atomically.  Bad input exits with status 1 and a one-line message.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from .reference import read_reference

__all__ = ["add_parser", "add_tracking_parser"]

_STATES = ("negative", "positive", "anhysteretic")


def _start_state(model: Any, name: str) -> Any:
    if name == "negative":
        return model.negative_saturation()
    if name == "positive":
        return model.positive_saturation()
    return model.anhysteretic_state()


def _compensate(args: argparse.Namespace) -> int:
    from ..model import PreisachModel
    from ..recording import Recording

    model = PreisachModel.load(args.model)
    t, y_ref, meta = read_reference(args.reference)
    result = model.inverse(y_ref, _start_state(model, args.state), t, nonmonotone=args.nonmonotone)
    out = Path(args.output)
    if out.suffix.lower() not in (".csv", ".npz"):
        raise ValueError(f"{args.output}: the drive must be a .csv or .npz recording")
    rec = Recording(
        t=t,
        u=result.input,
        y=result.output,
        columns={"y_ref": y_ref, "reached": result.reached.astype(np.float64)},
        metadata={
            "experiment": "compensate",
            "model": Path(args.model).name,
            "initial_state": args.state,
            "nonmonotone": args.nonmonotone,
            "unreachable": result.unreachable,
            "input_units": "V",
            "output_units": "V",
            **({"reference": meta["experiment"]} if "experiment" in meta else {}),
        },
    )
    rec.save(out)
    span = max(model.y_max - model.y_min, 1e-300)
    print(
        f"wrote {out}: {len(t)} samples, drive in [{result.input.min():.4g}, "
        f"{result.input.max():.4g}] V, {result.unreachable} unreachable targets, "
        f"max |y - y_ref| = {result.max_error:.3g} V ({100 * result.max_error / span:.3g} % of "
        f"the output range)"
    )
    return 0


def add_parser(sub: Any) -> None:
    """Add ``compensate`` to the ``preisach`` sub-commands."""
    p = sub.add_parser(
        "compensate",
        help="feedforward drive (inverse model) for a reference output",
        description=__doc__.split("::")[0].strip(),
    )
    p.add_argument("model", help="model file (.npz, PreisachModel.save)")
    p.add_argument("reference", help="reference CSV with columns t (s) and y (V)")
    p.add_argument("-o", "--output", required=True, help="drive recording to write (t,u,y)")
    p.add_argument(
        "--state",
        choices=_STATES,
        default="anhysteretic",
        help="model state at the first sample (default anhysteretic)",
    )
    p.add_argument(
        "--nonmonotone",
        choices=("as_is", "project"),
        default="as_is",
        help="models with negative weights: invert as is (smallest excursion) or projected",
    )
    p.set_defaults(func=_compensate)


# ---------------------------------------------------------------------------- tracking
def _float_list(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from exc
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers, got {text!r}")
    return values


def _load_any_model(name: str) -> Any:
    from ..model import BUILTIN_MODELS, PreisachModel

    if name.lower() in BUILTIN_MODELS:
        return PreisachModel.builtin(name.lower())
    return PreisachModel.load(name)


def _tracking(args: argparse.Namespace) -> int:
    from .. import daq
    from .._io import save_figure, write_json
    from .rig import identify_from_device
    from .tracking import MODES, device_loop, run_tracking, tracking_references

    ts = float(args.sample_time)
    if not ts > 0:
        raise ValueError(f"--sample-time: must be positive, got {ts}")
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    bad = [m for m in modes if m not in MODES]
    if bad:
        raise ValueError(f"--modes: unknown mode {bad[0]!r}; choose from {', '.join(MODES)}")
    realtime = False
    device: Any
    if args.device == "sim":
        truth = _load_any_model(args.truth)
        device = daq.virtual_ss15(truth, "anhysteretic", sample_time=ts, seed=args.seed)
        where = f"virtual SS15 rig (truth {args.truth})"
    elif args.device.startswith("comedi:"):
        device = daq.comedi_device(args.device.split(":", 1)[1])
        realtime = True
        where = args.device
    else:
        raise ValueError(f"--device: expected 'sim' or 'comedi:/dev/comediN', got {args.device!r}")
    if args.model == "rig-sweep":
        model, _ = identify_from_device(device, sample_time=ts)
        model_desc = "identified from the device's own FOD sweep (21 levels, projected)"
    else:
        model = _load_any_model(args.model)
        model_desc = args.model
    refs = tracking_references(
        (model.y_min, model.y_max), sample_time=ts, frequencies=args.frequencies, seed=args.seed
    )
    loop = device_loop(device, ts, record_dir=args.record_dir, realtime=realtime)
    result = run_tracking(model, loop, refs, modes=modes)
    result.settings.update({"device": where, "model": model_desc})
    print(f"tracking on {where}; model {model_desc}; stroke {result.stroke:.4g} V")
    print(result.table())
    write_json(args.json, result.to_dict(), indent=2, default=float)
    print(f"wrote {args.json}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        save_figure(result.plot(), args.plot, dpi=100)
        print(f"wrote {args.plot}")
    return 0


def add_tracking_parser(sub: Any) -> None:
    """Add ``tracking`` to the ``preisach experiment`` sub-commands."""
    p = sub.add_parser(
        "tracking",
        help="tracking error: uncompensated, feedforward (inverse model), PI, PI + feedforward",
        description="Run references (sines, a triangle, random reversals, the FOD pattern) "
        "four ways on a device and report the max and RMS tracking error in % of the "
        "stroke and the PI control effort (Eq 5.3).",
    )
    p.add_argument(
        "--model",
        required=True,
        help="model for the feedforward: a built-in name, a model file, or 'rig-sweep' to "
        "identify one from the device's own recorded FOD sweep",
    )
    p.add_argument(
        "--device",
        default="sim",
        help="'sim' (the virtual SS15 rig) or 'comedi:/dev/comediN' (default: %(default)s)",
    )
    p.add_argument(
        "--truth", default="ss15-1hz", help="the virtual rig's model (default: %(default)s)"
    )
    p.add_argument(
        "--frequencies",
        type=_float_list,
        default=[0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0],
        help="sine frequencies (Hz), comma-separated (default: 0.1,0.5,1,2,5,10,20,50)",
    )
    p.add_argument(
        "--modes",
        default="uncompensated,feedforward,pi,pi+feedforward",
        help="comma-separated subset of the four modes (default: all)",
    )
    p.add_argument("--sample-time", type=float, default=1e-3, help="seconds (default: 1e-3)")
    p.add_argument("--seed", type=int, default=0, help="rig noise and random reference seed")
    p.add_argument("--record-dir", help="keep every run's recording in this folder")
    p.add_argument("--json", required=True, metavar="OUT", help="write the results as JSON")
    p.add_argument("--plot", metavar="FIG", help="write the figure (format from the extension)")
    p.set_defaults(func=_tracking)
