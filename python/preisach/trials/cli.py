"""``preisach trial run|check``: the command line of scripted trials."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from .._progress import progress_bar
from ..errors import TrialInterrupted
from .plan import check_trial, step_waveform
from .run import TrialOutcome, run_trial_file
from .schema import PlannedStep


# ------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------
class _ProgressBar:
    """One progress bar per trial step (:func:`preisach._progress.progress_bar`, on stderr).

    Called as ``bar(done, planned, step, number, total)`` by :func:`run_trial_file`; redrawn in
    place on a terminal, plain lines in a log; ``close()`` ends the current step's bar.
    """

    def __init__(self, stream: Any = None) -> None:
        self.stream = stream
        self.number = -1
        self.bar: Any = None

    def close(self) -> None:
        """End the current step's bar (also one that stopped before 100 %)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __call__(self, done: int, planned: int, step: PlannedStep, number: int, total: int) -> None:
        if number != self.number:
            self.close()
            self.number = number
            self.bar = progress_bar(
                planned, f"step {number}/{total} {step.name}", unit="sample", file=self.stream,
                delay=0.0,
            )  # fmt: skip
        self.bar.update(done - self.bar.n)


def _cmd_check(args: argparse.Namespace) -> int:
    plan = check_trial(args.file)
    print(
        f"{plan.path}: OK - {plan.name!r}, {len(plan.steps)} step(s) on "
        f"{plan.device['kind']}, sample time {plan.sample_time:g} s"
    )
    u_now = 0.0
    for step in plan.steps:
        u, _ = step_waveform(plan, step, u_now)
        u_now = float(u[-1])
        print(
            f"  {step.index + 1:2d}. {step.kind:<11} {step.name:<16} "
            f"{u.size * plan.sample_time:8.3f} s "
            f"input {u.min():8.2f} .. {u.max():7.2f} V"
        )
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    bar = None if args.quiet else _ProgressBar()
    try:
        outcome = run_trial_file(
            args.file,
            args.output,
            device=args.device,
            realtime=args.realtime,
            overwrite=args.overwrite,
            priority=args.priority,
            progress=bar,
        )
    except TrialInterrupted as exc:
        if bar is not None:
            bar.close()
        out = exc.result
        if isinstance(out, TrialOutcome):
            print(
                f"preisach trial: interrupted; recordings and {out.summary_file} are complete "
                "up to the interrupt",
                file=sys.stderr,
            )
        return 130
    except KeyboardInterrupt:  # between steps, or before the device was opened
        if bar is not None:
            bar.close()
        print(
            f"preisach trial: interrupted (Ctrl-C); the recordings and summary.json written "
            f"to {args.output} are complete up to the interrupt",
            file=sys.stderr,
        )
        return 130
    if bar is not None:
        bar.close()
    for s in outcome.steps:
        r = s.result
        print(
            f"{s.file}: {r.end_status}, {r.samples} samples"
            + (f" (+{r.ramp_samples} ramp)" if r.ramp_samples else "")
            + (
                f", {r.missed_deadlines} missed deadlines, max lateness "
                f"{r.max_lateness * 1e6:.0f} us"
                if r.realtime
                else ""
            )
        )
    print(f"summary: {outcome.summary_file}")
    if not outcome.complete:
        last = outcome.steps[-1]
        print(
            f"preisach trial: error: step {last.index + 1} ({last.name}) {outcome.end_status}",
            file=sys.stderr,
        )
        return 1
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``preisach trial run|check`` on an argparse subparsers object."""
    p = subparsers.add_parser(
        "trial",
        help="run or check a scripted rig trial (TOML)",
        description="Scripted rig trials on the virtual SS15 or a Comedi card: one recording "
        "per step plus summary.json.",
    )
    sub = p.add_subparsers(dest="trial_command", metavar="ACTION", required=True)
    r = sub.add_parser(
        "run",
        help="run a trial file",
        description="Run a trial file; exits 1 with the reason when a step "
        "aborts, 130 when interrupted (the files are complete either way).",
    )
    r.add_argument("file", help="trial file (TOML)")
    r.add_argument("-o", "--output", required=True, help="output folder")
    r.add_argument(
        "--device",
        default=None,
        help="'sim' or 'comedi:/dev/comediN' (default: the file's [device] kind)",
    )
    r.add_argument(
        "--realtime",
        action="store_true",
        help="pace a simulated device in real time (a real one always is)",
    )
    r.add_argument("--overwrite", action="store_true", help="replace existing recordings")
    r.add_argument(
        "--priority",
        type=int,
        default=0,
        help="request SCHED_FIFO at this priority for the sample loop (default: no)",
    )
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_run)
    c = sub.add_parser(
        "check",
        help="validate a trial file without running it",
        description="Validate a trial file and its planned waveforms; names every error.",
    )
    c.add_argument("file", help="trial file (TOML)")
    c.set_defaults(func=_cmd_check)
    return p


def _main(argv: Sequence[str] | None = None) -> int:
    """``python -m preisach.trials run|check ...`` (the same as ``preisach trial``)."""
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_parser(sub)
    args = parser.parse_args(["trial", *(argv if argv is not None else sys.argv[1:])])
    try:
        return int(args.func(args))
    except (ValueError, OSError) as exc:
        print(f"preisach trial: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(_main())
