"""``preisach trial run|check``: the command line of scripted trials."""

from __future__ import annotations

import argparse
import signal
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
    from ..cli import EXIT_FAILED, exit_code

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
            why = (
                "interrupted"
                if exc.signum is None
                else f"stopped by {signal.Signals(exc.signum).name}"
            )
            print(
                f"preisach trial: {why}; the output was ramped to 0 V; recordings and "
                f"{out.summary_file} are complete up to the stop",
                file=sys.stderr,
            )
        return exit_code(exc)
    except KeyboardInterrupt as exc:  # between steps, or before the device was opened
        if bar is not None:
            bar.close()
        why = str(exc) if getattr(exc, "signum", None) else "interrupted (Ctrl-C)"
        print(
            f"preisach trial: {why}; the output was ramped to 0 V; the recordings and "
            f"summary.json written to {args.output} are complete up to the stop",
            file=sys.stderr,
        )
        return exit_code(exc)
    except BaseException:
        if bar is not None:
            bar.close()
        raise
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
        return EXIT_FAILED
    return 0


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
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
        description="Run a trial file; exits 3 with the reason when a step aborts or a "
        "recording cannot be written, 130 on Ctrl-C, 129/143 on SIGHUP/SIGTERM (the output is "
        "ramped to 0 V and the files are complete either way), 1 for a bad file or folder.",
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
    from ..cli import run_command

    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(prog="preisach")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    add_parser(sub)
    args = parser.parse_args(["trial", *(a for a in argv if a != "--debug")])
    args.debug = "--debug" in argv
    return run_command("trial", args.func, args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(_main())
