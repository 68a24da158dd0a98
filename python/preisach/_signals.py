"""SIGTERM and SIGHUP handled like Ctrl-C: raise :class:`~preisach.errors.StopSignal`.

Python's default for SIGTERM and SIGHUP is to die at once: a trial's sample loop (a C++
thread) dies with the process and the actuator stays at its last voltage, with no ramp, no
``end_status`` and no summary.  Inside :func:`stop_signals` both signals raise
:class:`~preisach.errors.StopSignal` (a :class:`KeyboardInterrupt`) in the main thread, so every
path that handles Ctrl-C - the trial runner's stop request and ramp to 0 V, the atomic writes'
clean-up - handles them too.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

from .errors import StopSignal

__all__ = ["STOP_SIGNALS", "StopSignals", "stop_signals"]

#: The signals treated like Ctrl-C (SIGHUP where the platform has it).
STOP_SIGNALS: tuple[int, ...] = tuple(
    s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)) if s is not None
)


class StopSignals:
    """What :func:`stop_signals` saw: ``received`` is the last stop signal's number, or ``None``."""

    def __init__(self) -> None:
        self.received: int | None = None

    def _raise(self, signum: int, frame: FrameType | None) -> None:
        self.received = signum
        raise StopSignal(signum)


@contextmanager
def stop_signals() -> Iterator[StopSignals]:
    """Within the block, SIGTERM and SIGHUP raise :class:`~preisach.errors.StopSignal`.

    Only signals left at their default action (or at an outer :func:`stop_signals`) are taken
    over (a handler the program installed, or a signal it ignores, is kept), and only in the
    main thread (Python delivers signals there; elsewhere this does nothing).  The previous
    handlers are restored on exit.

    Yields
    ------
    StopSignals
        Its ``received`` names the signal that arrived, if any.

    """
    stops = StopSignals()
    if threading.current_thread() is not threading.main_thread():
        yield stops
        return
    saved: dict[int, Any] = {}
    try:
        for s in STOP_SIGNALS:
            h = signal.getsignal(s)
            if h is signal.SIG_DFL or getattr(h, "__func__", None) is StopSignals._raise:
                saved[s] = signal.signal(s, stops._raise)
        yield stops
    finally:
        for s, old in saved.items():
            signal.signal(s, old)
