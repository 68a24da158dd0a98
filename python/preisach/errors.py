"""Exceptions and warnings of :mod:`preisach`.

Every exception subclasses a builtin, so ``except ValueError`` keeps working for callers
that do not know this package.
"""

from __future__ import annotations

__all__ = [
    "PreisachError",
    "RecordingFormatError",
    "PreisachWarning",
    "ConvergenceError",
    "DeviceError",
    "TrialFileError",
    "TrialInterrupted",
    "StopSignal",
    "ResourceLimitError",
]


class PreisachError(Exception):
    """Base class of every exception raised by :mod:`preisach`."""


class RecordingFormatError(PreisachError, ValueError):
    """A recording file is malformed; the message names the file, line and column."""


class ConvergenceError(PreisachError, RuntimeError):
    """A numerical search (an input offset, a root of N(l)) did not reach its tolerance."""


class DeviceError(PreisachError, OSError):
    """A DAQ device cannot be opened or used (missing device file, driver call failed)."""


class ResourceLimitError(PreisachError, MemoryError):
    """An array the data asks for would exceed the memory budget; refused before allocating."""


class TrialFileError(PreisachError, ValueError):
    """A trial file is invalid; the message lists every error found, one per line."""


class TrialInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a DAQ trial; the recording was finished first (``.result`` says how).

    A :class:`KeyboardInterrupt`, so scripts stop as usual; ``result`` is the
    :class:`preisach.daq.TrialResult` of the interrupted trial (``end_status == "interrupted"``).
    """

    def __init__(self, message: str = "", result: object = None, signum: int | None = None) -> None:
        super().__init__(message)
        self.result = result
        #: The signal (SIGTERM, SIGHUP) that stopped the trial; ``None`` for Ctrl-C.
        self.signum = signum


class StopSignal(KeyboardInterrupt):
    """SIGTERM or SIGHUP asked the process to stop; handled exactly like Ctrl-C.

    Raised in the main thread by the handlers of :func:`preisach._signals.stop_signals`
    (installed by ``preisach`` commands and by :func:`preisach.trials.run_trial_file`), so a
    running trial stops, ramps its output to 0 V and finishes its files.  ``signum`` is the
    signal's number; the command line exits with ``128 + signum``.
    """

    def __init__(self, signum: int) -> None:
        import signal

        self.signum = int(signum)
        self.signame = signal.Signals(signum).name
        super().__init__(f"stopped by {self.signame}")


class PreisachWarning(UserWarning):
    """Base class of the warnings :mod:`preisach` emits."""
