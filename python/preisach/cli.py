"""The ``preisach`` command line.

``preisach demo`` runs the main job on the built-in virtual SS15 (no hardware needed).
"""

from __future__ import annotations

import argparse
import errno
import sys
import traceback
from collections.abc import Callable, Sequence

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERNAL",
    "EXIT_INTERRUPTED",
    "EXIT_USAGE",
    "exit_code",
    "main",
]


def _version() -> str:
    from . import __version__

    return str(__version__)


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="preisach",
        description="Preisach hysteresis models for piezoceramic actuators: identify, simulate, "
        "regulate, run rig trials and diagnose (inputs in volts, outputs in volts).",
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument(
        "--debug", action="store_true", help="print the traceback of an error (for bug reports)"
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    from . import demo, trials
    from .compensate import cli as compensate_cli
    from .diagnose import cli as diagnose_cli
    from .experiments import cli as experiments_cli
    from .identify import cli as identify_cli

    for module in (demo, identify_cli, experiments_cli, trials, diagnose_cli, compensate_cli):
        module.add_parser(sub)
    return p


#: Exit codes of every ``preisach`` command (docs/RELIABILITY.md).
EXIT_OK = 0
EXIT_BAD_INPUT = 1  # bad input: an option's value, an input file, an output path refused
EXIT_USAGE = 2  # the command line itself (argparse): unknown option, missing argument
EXIT_FAILED = 3  # the command ran but could not finish: a trial step aborted, a write failed
EXIT_INTERNAL = 70  # a bug: an unexpected exception (sysexits EX_SOFTWARE; --debug: traceback)
EXIT_INTERRUPTED = 130  # Ctrl-C; SIGHUP and SIGTERM give 128 + the signal number (129, 143)

#: errno values that mean the environment failed (not the user's input): exit EXIT_FAILED.
_IO_FAILURES = frozenset(
    getattr(errno, name)
    for name in ("ENOSPC", "EIO", "EDQUOT", "EFBIG", "EROFS", "ENOMEM", "EPIPE", "ENXIO")
    if hasattr(errno, name)
)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text


def exit_code(exc: BaseException) -> int:
    """Return the exit code for an exception that ended a command (see :data:`EXIT_BAD_INPUT`)."""
    from .errors import DeviceError

    if isinstance(exc, KeyboardInterrupt):
        signum = getattr(exc, "signum", None)
        return 128 + signum if signum else EXIT_INTERRUPTED
    if isinstance(exc, (DeviceError, MemoryError)):
        return EXIT_FAILED
    if isinstance(exc, OSError):
        return EXIT_FAILED if exc.errno in _IO_FAILURES else EXIT_BAD_INPUT
    if isinstance(exc, ValueError):  # incl. TrialFileError, RecordingFormatError
        return EXIT_BAD_INPUT
    return EXIT_INTERNAL


def run_command(
    name: str, func: Callable[[argparse.Namespace], int], args: argparse.Namespace
) -> int:
    """Run one command: its exit status, or one line on stderr and a distinct code on error.

    With ``args.debug`` the traceback is printed as well.  SIGTERM and SIGHUP are handled like
    Ctrl-C for the command's duration (:func:`preisach._signals.stop_signals`).
    """
    from ._signals import stop_signals

    debug = bool(getattr(args, "debug", False))
    try:
        with stop_signals():
            return int(func(args))
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - every failure becomes one line and a code
        code = exit_code(exc)
        if debug:
            traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
        if isinstance(exc, KeyboardInterrupt):
            why = str(exc) if getattr(exc, "signum", None) else "interrupted (Ctrl-C)"
            msg = f"preisach {name}: {why}; files written so far are complete"
        elif code == EXIT_INTERNAL:
            msg = (
                f"preisach {name}: internal error: {type(exc).__name__}: {_one_line(exc)} "
                "(a bug: please report it; --debug shows the traceback)"
            )
        else:
            msg = f"preisach {name}: error: {_one_line(exc)}"
        # A bad input file may list several problems, one per line; anything else is one line.
        print(msg if code == EXIT_BAD_INPUT else " ".join(msg.split()), file=sys.stderr)
        return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (see :data:`EXIT_BAD_INPUT` and friends)."""
    from ._signals import stop_signals

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv  # accepted anywhere: preisach diagnose ... --debug
    try:
        with stop_signals():  # building the parser imports every command: seconds on a busy box
            parser = _build_parser()
            args = parser.parse_args([a for a in argv if a != "--debug"])
    except KeyboardInterrupt as exc:
        why = str(exc) if getattr(exc, "signum", None) else "interrupted (Ctrl-C)"
        print(f"preisach: {why} before the command started; nothing was written", file=sys.stderr)
        return exit_code(exc)
    args.debug = debug
    if not getattr(args, "command", None):
        parser.print_usage(sys.stderr)
        print(
            "preisach: error: a command is required (preisach --help lists them)", file=sys.stderr
        )
        return EXIT_USAGE
    return run_command(args.command, args.func, args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
