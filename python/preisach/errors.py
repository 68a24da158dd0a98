"""Exceptions and warnings of :mod:`preisach`.

Every exception subclasses a builtin, so ``except ValueError`` keeps working for callers
that do not know this package.
"""

from __future__ import annotations

__all__ = ["PreisachError", "RecordingFormatError", "PreisachWarning"]


class PreisachError(Exception):
    """Base class of every exception raised by :mod:`preisach`."""


class RecordingFormatError(PreisachError, ValueError):
    """A recording file is malformed; the message names the file, line and column."""


class PreisachWarning(UserWarning):
    """Base class of the warnings :mod:`preisach` emits."""
