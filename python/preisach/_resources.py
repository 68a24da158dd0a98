"""Memory estimates before large allocations: refuse with a clear message instead of dying.

A dense array sized by the data (a drift basis of samples x knots, a regressor matrix) can
need far more memory than the machine has; numpy then fails after minutes of work, or the
kernel's OOM killer ends the process without a word.  :func:`check_allocation` compares the
estimate with a budget first and raises :class:`~preisach.errors.ResourceLimitError` naming
what was to be allocated, its size and the way out.
"""

from __future__ import annotations

import os

from .errors import ResourceLimitError

__all__ = ["available_memory", "check_allocation", "memory_budget"]

_GIB = float(1 << 30)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), if known."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def memory_budget() -> int:
    """Largest single allocation allowed: ``PREISACH_MEMORY_LIMIT`` (GiB) or half the free memory.

    Without either (an unknown platform), 8 GiB.
    """
    env = os.environ.get("PREISACH_MEMORY_LIMIT")
    if env:
        try:
            return int(float(env) * _GIB)
        except ValueError:
            raise ResourceLimitError(
                f"PREISACH_MEMORY_LIMIT={env!r}: expected a number of GiB"
            ) from None
    free = available_memory()
    return int(free // 2) if free else int(8 * _GIB)


def check_allocation(nbytes: float, what: str, hint: str = "") -> None:
    """Raise :class:`~preisach.errors.ResourceLimitError` if ``nbytes`` exceed the budget.

    Parameters
    ----------
    nbytes : float
        Estimated size of the allocation (bytes).
    what : str
        What it is, for the message (e.g. ``"the drift basis of recording 0 (6400000 x 643)"``).
    hint : str
        What the user can do about it, appended to the message.

    """
    budget = memory_budget()
    if nbytes > budget:
        raise ResourceLimitError(
            f"{what} would need {_size(nbytes)}, more than the {_size(budget)} allowed (half "
            "the free memory, or PREISACH_MEMORY_LIMIT in GiB)" + (f"; {hint}" if hint else "")
        )


def _size(nbytes: float) -> str:
    for unit, scale in (("GiB", _GIB), ("MiB", float(1 << 20)), ("KiB", 1024.0)):
        if nbytes >= scale:
            return f"{nbytes / scale:.1f} {unit}"
    return f"{nbytes:.0f} bytes"
