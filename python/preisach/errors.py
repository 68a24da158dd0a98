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
]


class PreisachError(Exception):
    """Base class of every exception raised by :mod:`preisach`."""


class RecordingFormatError(PreisachError, ValueError):
    """A recording file is malformed; the message names the file, line and column."""


class ConvergenceError(PreisachError, RuntimeError):
    """A numerical search (an input offset, a root of N(l)) did not reach its tolerance."""


class DeviceError(PreisachError, OSError):
    """A DAQ device cannot be opened or used (missing device file, driver call failed)."""


class TrialFileError(PreisachError, ValueError):
    """A trial file is invalid; the message lists every error found, one per line."""


class TrialInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a DAQ trial; the recording was finished first (``.result`` says how).

    A :class:`KeyboardInterrupt`, so scripts stop as usual; ``result`` is the
    :class:`preisach.daq.TrialResult` of the interrupted trial (``end_status == "interrupted"``).
    """

    def __init__(self, message: str = "", result: object = None) -> None:
        super().__init__(message)
        self.result = result


class PreisachWarning(UserWarning):
    """Base class of the warnings :mod:`preisach` emits."""
