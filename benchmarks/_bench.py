"""What the benchmark scripts share: their parser, the cores they obtained, best-of timing."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import TypeVar

from preisach.execution import available_cores

R = TypeVar("R")

__all__ = ["available_cores", "best_of", "parser"]


def parser(doc: str | None) -> argparse.ArgumentParser:
    """An argument parser whose ``--help`` prints the script's docstring as written."""
    return argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )


def best_of(
    fn: Callable[[], R], repeats: int, *, before: Callable[[], object] | None = None
) -> tuple[float, R]:
    """Best wall time (s) of ``repeats`` calls of ``fn``, and the last call's result.

    ``before`` runs ahead of each call, outside the timing (e.g. to clear a cache).
    """
    if repeats < 1:
        raise ValueError(f"repeats: need at least 1, got {repeats}")
    best = float("inf")
    for _ in range(repeats):
        if before is not None:
            before()
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
