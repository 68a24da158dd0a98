"""The ``preisach`` command line.

``preisach demo`` runs the main job on the built-in virtual SS15 (no hardware needed).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

__all__ = ["main"]


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="preisach",
        description="Preisach hysteresis models for piezoceramic actuators: identify, simulate, "
        "regulate, run rig trials and diagnose (inputs in volts, outputs in volts).",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    from . import demo, trials
    from .diagnose import cli as diagnose_cli
    from .experiments import cli as experiments_cli
    from .identify import cli as identify_cli

    for module in (demo, identify_cli, experiments_cli, trials, diagnose_cli):
        module.add_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = _build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args))
    except (ValueError, OSError) as exc:
        print(f"preisach {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
