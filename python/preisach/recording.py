"""Recordings: the one on-disk format for measured and simulated input/output data.

A :class:`Recording` holds, sample by sample, the time ``t`` (seconds), the actuator
input ``u`` (volts) and the measured or simulated output ``y`` (volts), any number of
extra columns (float64, units are the caller's business) and a metadata dict.

Two file formats are supported, chosen by the file suffix.

CSV (``.csv``)
--------------
UTF-8 text, one sample per line::

    # sample_time: 0.001
    # input_units: V
    # output_units: V
    # experiment: fod_sweep
    t,u,y,u_cmd
    0.0,0.0,-1.25,0.0
    0.001,0.5,-1.2,0.5
    # end_status: complete

* Optional leading metadata lines ``# key: value``.  Keys are names made of letters,
  digits, ``_``, ``.`` and ``-`` (not starting with a digit or ``-``/``.``).  Values that
  look like numbers are read back as ``int`` or ``float`` (``nan``/``inf`` included);
  everything else is a ``str``.  Strings that would not read back unchanged (numeric-looking
  strings such as ``"007"``, strings with leading/trailing spaces, line breaks or a leading
  double quote) are written as JSON string literals (``"007"``) and decoded on reading, so
  metadata written by this module always reads back exactly.
* Then one header row naming the columns; ``t``, ``u`` and ``y`` are required (in any
  order), extra columns are kept in file order.
* Then the data rows: exactly one field per column, each a finite decimal number.  Floats
  are written with :func:`repr`, the shortest text that reads back to the identical
  float64, so a save/load round trip is bit-exact.  ``t`` must be strictly increasing.
* Optional trailing ``# key: value`` lines after the last data row (the streaming
  :class:`RecordingWriter` writes ``# end_status: ...`` there).  They are merged into the
  metadata, overriding a leading line with the same key.  A comment or blank line
  *between* data rows is an error: rows are never silently skipped.
* Blank lines are allowed only before the header row and after the last data row.
* **Truncated last line.**  Every complete line ends with a newline.  If the very last
  line of the file has no newline (the writing process was killed in the middle of a
  write) it cannot be trusted -- a cut-off ``0.4,1.25,3.1`` still parses -- so it is
  dropped and a :class:`~preisach.errors.PreisachWarning` names it.  No other line is
  ever dropped: any other malformed line raises
  :class:`~preisach.errors.RecordingFormatError` naming the file, the line and the column.

NPZ (``.npz``)
--------------
A NumPy archive (:func:`numpy.savez`) with one 1-D numeric entry per column (``t``,
``u``, ``y`` and the extra columns, in order) and an entry ``__metadata__`` holding the
metadata dict as a JSON string.  An archive without ``__metadata__`` loads with empty
metadata.

Conventional metadata keys: ``sample_time`` (seconds), ``input_units`` and
``output_units`` (``"V"``), ``experiment`` (a name), ``end_status`` (written by
:meth:`RecordingWriter.close`).  Metadata values must be ``str``, ``int`` or ``float``.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from array import array
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol, Union, cast, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._io import atomic_write, check_target, npz_load_error
from .errors import PreisachWarning, RecordingFormatError

__all__ = [
    "LABEL_KEYS",
    "REQUIRED_COLUMNS",
    "Recording",
    "RecordingLike",
    "RecordingWriter",
    "RecordingsInput",
    "SampledData",
    "as_recordings",
    "recording_label",
    "recording_labels",
]

#: Columns every recording has: time (s), input (V), output (V).
REQUIRED_COLUMNS: tuple[str, str, str] = ("t", "u", "y")

MetaValue = Union[str, int, float]

_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*\Z")
_INT_RE = re.compile(r"[+-]?[0-9]+\Z")
_FLOAT_RE = re.compile(
    r"[+-]?(?:[0-9]+\.?[0-9]*(?:e[+-]?[0-9]+)?|\.[0-9]+(?:e[+-]?[0-9]+)?|nan|inf|infinity)\Z",
    re.IGNORECASE,
)
_COMMENT_RE = re.compile(r"#\s*([^:]*?)\s*:(.*)\Z", re.DOTALL)
_NPZ_METADATA = "__metadata__"


# --------------------------------------------------------------------------------------
# metadata helpers
# --------------------------------------------------------------------------------------


def _valid_name(name: object) -> bool:
    return isinstance(name, str) and _NAME_RE.match(name) is not None


def _check_column_name(name: object) -> str:
    if not _valid_name(name) or str(name).startswith("__"):
        raise ValueError(
            f"invalid column name {name!r}: use letters, digits, '_', '.' and '-', starting "
            "with a letter or '_' (names starting with '__' are reserved)"
        )
    return str(name)


def _check_metadata(metadata: Mapping[str, Any] | None) -> dict[str, MetaValue]:
    """Validate metadata and convert NumPy scalars to plain Python values."""
    out: dict[str, MetaValue] = {}
    for key, value in (metadata or {}).items():
        if not _valid_name(key):
            raise ValueError(
                f"invalid metadata key {key!r}: use letters, digits, '_', '.' and '-', "
                "starting with a letter or '_'"
            )
        if isinstance(value, (bool, np.bool_)):
            raise TypeError(
                f"metadata {key!r}: bool values are not supported (they would not read back "
                "as bool); store an int or a str"
            )
        if isinstance(value, str):
            out[key] = str(value)
        elif isinstance(value, (int, np.integer)):
            out[key] = int(value)
        elif isinstance(value, (float, np.floating)):
            out[key] = float(value)
        else:
            raise TypeError(
                f"metadata {key!r}: values must be str, int or float, got {type(value).__name__}"
            )
    return out


def _parse_meta_value(text: str) -> MetaValue:
    """Decode a ``# key: value`` value: JSON string literal, int, float or plain str."""
    v = text.strip()
    if len(v) >= 2 and v[0] == '"' and v[-1] == '"':
        try:
            decoded = json.loads(v)
        except ValueError:
            return v
        return decoded if isinstance(decoded, str) else v
    try:
        if _INT_RE.match(v):
            return int(v)
        if _FLOAT_RE.match(v):
            return float(v)
    except ValueError:  # e.g. an int with more digits than Python allows
        pass
    return v


def _format_meta_value(value: MetaValue) -> str:
    """Encode a metadata value so that :func:`_parse_meta_value` returns it unchanged."""
    if isinstance(value, str):
        plain = (
            value == value.strip()
            and value.isprintable()
            and not value.startswith('"')
            and _parse_meta_value(value) == value
        )
        return value if plain else json.dumps(value)
    if isinstance(value, int):
        return str(value)
    return repr(float(value))


def _meta_lines(metadata: Mapping[str, MetaValue]) -> str:
    return "".join(f"# {k}: {_format_meta_value(v)}".rstrip() + "\n" for k, v in metadata.items())


def _rows_text(block: NDArray[np.float64]) -> str:
    """CSV rows of a 2-D float64 block, each float written with the exact ``repr``."""
    return "".join(",".join(map(repr, row)) + "\n" for row in block.tolist())


def _first_non_increasing(t: NDArray[np.float64]) -> int | None:
    """Index ``i`` of the first sample with ``t[i] <= t[i-1]``, or ``None``."""
    if t.size < 2:
        return None
    bad = np.flatnonzero(np.diff(t) <= 0)
    return int(bad[0]) + 1 if bad.size else None


# --------------------------------------------------------------------------------------
# Recording
# --------------------------------------------------------------------------------------


@dataclass(eq=False)
class Recording:
    """A sampled input/output record: time (s), input (V), output (V) and extras.

    Construction validates and copies the data: every column is converted to a 1-D
    float64 array, all columns must have the same length, every value must be finite
    and ``t`` must be strictly increasing (otherwise :class:`ValueError`).

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing.
    u : array_like
        Actuator input (V).
    y : array_like
        Output (V).
    columns : dict of str to array_like, optional
        Extra columns, kept in insertion order.  Names use letters, digits, ``_``, ``.``
        and ``-`` and must not be ``t``, ``u`` or ``y``.
    metadata : dict, optional
        Metadata with ``str``, ``int`` or ``float`` values, e.g. ``sample_time`` (s),
        ``input_units``, ``output_units``, ``experiment``.

    Attributes
    ----------
    t, u, y : numpy.ndarray
        float64 arrays of length ``len(rec)``: time (s), input (V), output (V).
    columns : dict of str to numpy.ndarray
        Extra float64 columns.
    metadata : dict
        Metadata (see the module documentation for the conventional keys).

    Examples
    --------
    >>> rec = Recording.from_arrays(u=[0.0, 1.0, 2.0], y=[0.0, 0.5, 1.5], sample_time=1e-3)
    >>> rec.save("run.csv")  # doctest: +SKIP
    >>> Recording.load("run.csv").t  # doctest: +SKIP
    array([0.   , 0.001, 0.002])

    """

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    y: NDArray[np.float64]
    columns: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        def as_column(name: str, values: ArrayLike) -> NDArray[np.float64]:
            arr = np.array(values, dtype=np.float64)
            if arr.ndim != 1:
                raise ValueError(f"column {name!r} must be 1-D, got shape {arr.shape}")
            return arr

        self.t = as_column("t", self.t)
        self.u = as_column("u", self.u)
        self.y = as_column("y", self.y)
        extra: dict[str, NDArray[np.float64]] = {}
        for name, values in dict(self.columns).items():
            if name in REQUIRED_COLUMNS:
                raise ValueError(f"extra column {name!r} clashes with a required column")
            extra[_check_column_name(name)] = as_column(name, values)
        self.columns = extra
        self.metadata = dict(_check_metadata(self.metadata))

        n = self.t.size
        for name, arr in self._items():
            if arr.size != n:
                raise ValueError(
                    f"all columns must have the same length: 't' has {n} samples, "
                    f"{name!r} has {arr.size}"
                )
        for name, arr in self._items():
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                i = int(bad[0])
                raise ValueError(
                    f"column {name!r} has the non-finite value {float(arr[i])!r} at index {i}"
                )
        k = _first_non_increasing(self.t)
        if k is not None:
            raise ValueError(
                f"t must be strictly increasing: t[{k}] = {float(self.t[k])!r} s is not "
                f"greater than t[{k - 1}] = {float(self.t[k - 1])!r} s"
            )

    # ---- construction ----------------------------------------------------------------

    @classmethod
    def from_arrays(
        cls,
        t: ArrayLike | None = None,
        u: ArrayLike | None = None,
        y: ArrayLike | None = None,
        *,
        sample_time: float | None = None,
        experiment: str | None = None,
        input_units: str | None = None,
        output_units: str | None = None,
        metadata: Mapping[str, Any] | None = None,
        **extra: ArrayLike,
    ) -> Recording:
        """Build a recording from arrays.

        Parameters
        ----------
        t : array_like, optional
            Sample times (s).  If omitted, ``t = arange(len(u)) * sample_time``.
        u : array_like
            Actuator input (V).  Required.
        y : array_like
            Output (V).  Required.
        sample_time : float, optional
            Sampling period (s); stored in the metadata.  Required when ``t`` is omitted.
        experiment : str, optional
            Experiment name, stored in the metadata.
        input_units, output_units : str, optional
            Units of ``u`` and ``y``; default ``"V"`` unless ``metadata`` sets them.
        metadata : mapping, optional
            Further metadata; the explicit keyword arguments above take precedence.
        **extra : array_like
            Extra columns, e.g. ``u_cmd=...``.

        Returns
        -------
        Recording

        Raises
        ------
        TypeError
            If ``u`` or ``y`` is missing.
        ValueError
            If ``t`` and ``sample_time`` are both missing, ``sample_time`` is not a positive
            finite number, or the data are invalid (see :class:`Recording`).

        """
        if u is None or y is None:
            raise TypeError("from_arrays() requires both u (input, V) and y (output, V)")
        meta: dict[str, Any] = {}
        if sample_time is not None:
            st = float(sample_time)
            if not (np.isfinite(st) and st > 0):
                raise ValueError(f"sample_time must be a positive finite number (s), got {st!r}")
            meta["sample_time"] = st
        user = dict(metadata or {})
        meta["input_units"] = user.pop("input_units", "V") if input_units is None else input_units
        meta["output_units"] = (
            user.pop("output_units", "V") if output_units is None else output_units
        )
        if experiment is not None:
            meta["experiment"] = experiment
        for key, value in user.items():
            meta.setdefault(key, value)
        if t is None:
            if "sample_time" not in meta:
                raise ValueError("from_arrays() needs either t (s) or sample_time (s)")
            st = float(meta["sample_time"])
            if not (np.isfinite(st) and st > 0):
                raise ValueError(f"sample_time must be a positive finite number (s), got {st!r}")
            n = np.asarray(u).shape[0] if np.ndim(u) else 0
            t = np.arange(n, dtype=np.float64) * st
        # the dataclass checks and converts the columns (errors name the column)
        return cls(
            t=cast(Any, t),
            u=cast(Any, u),
            y=cast(Any, y),
            columns=cast(Any, dict(extra)),
            metadata=meta,
        )

    # ---- I/O -------------------------------------------------------------------------

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Recording:
        """Read a recording from a ``.csv`` or ``.npz`` file.

        Parameters
        ----------
        path : str or path-like
            File to read; the suffix (``.csv`` or ``.npz``, any case) selects the format.

        Returns
        -------
        Recording

        Raises
        ------
        preisach.errors.RecordingFormatError
            If the suffix is unknown or the file is malformed; the message names the file
            and, where it applies, the line (CSV) or index (NPZ) and the column.
        FileNotFoundError
            If the file does not exist.

        Warns
        -----
        preisach.errors.PreisachWarning
            If the last line of a CSV file has no trailing newline (the writer was killed in
            the middle of a write): that line, and only that line, is dropped.  Also if a
            trial runner's recording (metadata ``planned_samples``) has no ``end_status``:
            the process was killed before it finished the file.

        """
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix == ".csv":
            rec = _read_csv(p, os.fspath(path))
            if "planned_samples" in rec.metadata and "end_status" not in rec.metadata:
                warnings.warn(
                    f"{os.fspath(path)}: a trial recording without end_status: the process "
                    "writing it stopped before closing it (killed, or still running); its "
                    f"{len(rec)} rows are what was flushed, the run's outcome is unknown",
                    PreisachWarning,
                    stacklevel=2,
                )
            return rec
        if suffix == ".npz":
            return _read_npz(p, os.fspath(path))
        raise RecordingFormatError(
            f"{os.fspath(path)}: unsupported recording suffix {p.suffix!r}; "
            "expected '.csv' or '.npz'"
        )

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the recording to a ``.csv`` or ``.npz`` file.

        The file is written to a temporary file in the same directory, synced and renamed
        over ``path``, so an existing file is either fully replaced or left untouched.

        Parameters
        ----------
        path : str or path-like
            Destination; the suffix (``.csv`` or ``.npz``, any case) selects the format.

        Raises
        ------
        ValueError
            If the suffix is neither ``.csv`` nor ``.npz``.

        """
        p = Path(path)
        suffix = p.suffix.lower()
        metadata = _check_metadata(self.metadata)  # it may have been edited since __init__
        if suffix == ".csv":
            text = (
                _meta_lines(metadata)
                + ",".join(self.column_names)
                + "\n"
                + _rows_text(self._block())
            )
            atomic_write(p, lambda f: f.write(text), what="recording")
        elif suffix == ".npz":
            arrays: dict[str, Any] = dict(self._items())
            arrays[_NPZ_METADATA] = np.array(json.dumps(metadata))
            atomic_write(p, lambda f: np.savez(f, **arrays), binary=True, what="recording")
        else:
            raise ValueError(
                f"{os.fspath(path)}: unsupported recording suffix {p.suffix!r}; "
                "expected '.csv' or '.npz'"
            )

    # ---- views -----------------------------------------------------------------------

    @property
    def column_names(self) -> tuple[str, ...]:
        """Names of all columns: ``('t', 'u', 'y', *extra)``."""
        return (*REQUIRED_COLUMNS, *self.columns)

    @property
    def sample_time(self) -> float:
        """Sampling period (s).

        The ``sample_time`` metadata entry if present, otherwise the median of
        ``diff(t)``.

        Raises
        ------
        ValueError
            If there is no ``sample_time`` metadata and fewer than two samples, or the
            metadata entry is not a number.

        """
        st = self.metadata.get("sample_time")
        if st is not None:
            try:
                return float(st)
            except (TypeError, ValueError):
                raise ValueError(f"metadata 'sample_time' = {st!r} is not a number") from None
        if len(self) < 2:
            raise ValueError(
                "sample_time is unknown: no 'sample_time' metadata and fewer than 2 samples"
            )
        return float(np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        """Time spanned by the samples, ``t[-1] - t[0]`` (s); ``0.0`` below two samples."""
        return float(self.t[-1] - self.t[0]) if len(self) >= 2 else 0.0

    def slice(self, t0: float | None = None, t1: float | None = None) -> Recording:
        """Return the samples with ``t0 <= t < t1`` as a new recording.

        The interval is half-open so that ``rec.slice(None, tc)`` and ``rec.slice(tc, None)``
        split a recording into disjoint parts (e.g. identification and held-out
        validation data) that together contain every sample exactly once.  Times are not
        shifted; arrays are copied; metadata is copied unchanged.

        Parameters
        ----------
        t0 : float, optional
            Start time (s), inclusive; ``None`` for the beginning.
        t1 : float, optional
            End time (s), exclusive; ``None`` for the end.

        Returns
        -------
        Recording

        Raises
        ------
        ValueError
            If ``t0`` or ``t1`` is NaN, or ``t1 < t0``.

        """
        if (t0 is not None and np.isnan(t0)) or (t1 is not None and np.isnan(t1)):
            raise ValueError("slice bounds must not be NaN")
        if t0 is not None and t1 is not None and t1 < t0:
            raise ValueError(f"slice end t1={t1!r} s is before start t0={t0!r} s")
        lo = 0 if t0 is None else int(np.searchsorted(self.t, t0, side="left"))
        hi = len(self) if t1 is None else int(np.searchsorted(self.t, t1, side="left"))
        return Recording(
            t=self.t[lo:hi],
            u=self.u[lo:hi],
            y=self.y[lo:hi],
            columns={k: v[lo:hi] for k, v in self.columns.items()},
            metadata=dict(self.metadata),
        )

    def to_dict(self) -> dict[str, NDArray[np.float64]]:
        """Return the columns as ``{name: array}`` in column order (``t``, ``u``, ``y``, extras).

        The arrays are the recording's own (not copies); the metadata is not included
        (see :attr:`metadata`).  Handy for ``pandas.DataFrame(rec.to_dict())``.

        Returns
        -------
        dict of str to numpy.ndarray

        """
        return dict(self._items())

    def __len__(self) -> int:
        """Return the number of samples."""
        return int(self.t.size)

    def __eq__(self, other: object) -> bool:
        """Compare column names, values (exactly) and metadata."""
        if not isinstance(other, Recording):
            return NotImplemented
        if self.column_names != other.column_names or self.metadata != other.metadata:
            return False
        return all(np.array_equal(a, b) for (_, a), (_, b) in zip(self._items(), other._items()))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        """Return a short summary; the data arrays are not printed."""
        return (
            f"Recording(n={len(self)}, columns={list(self.column_names)}, "
            f"metadata={self.metadata!r})"
        )

    def _items(self) -> list[tuple[str, NDArray[np.float64]]]:
        return [("t", self.t), ("u", self.u), ("y", self.y), *self.columns.items()]

    def _block(self) -> NDArray[np.float64]:
        items = self._items()
        return np.column_stack([a for _, a in items]).reshape(len(self), len(items))


# --------------------------------------------------------------------------------------
# readers
# --------------------------------------------------------------------------------------


def _parse_comment(
    name: str, lineno: int, line: str, seen: dict[str, MetaValue], where: str
) -> tuple[str, MetaValue]:
    m = _COMMENT_RE.match(line.strip())
    if m is None:
        raise RecordingFormatError(
            f"{name} line {lineno}: comment line {line.strip()!r} is not of the form '# key: value'"
        )
    key, value = m.group(1), m.group(2)
    if not _valid_name(key):
        raise RecordingFormatError(
            f"{name} line {lineno}: metadata key {key!r} is not a valid name (use letters, "
            "digits, '_', '.' and '-', starting with a letter or '_')"
        )
    if key in seen:
        raise RecordingFormatError(
            f"{name} line {lineno}: metadata key {key!r} appears twice in the {where}"
        )
    return key, _parse_meta_value(value)


def _parse_header(name: str, lineno: int, line: str) -> list[str]:
    names = [c.strip() for c in line.split(",")]
    for i, col in enumerate(names, 1):
        if not col:
            raise RecordingFormatError(
                f"{name} line {lineno}: header row has an empty column name at position {i}"
            )
        if not _valid_name(col) or col.startswith("__"):
            raise RecordingFormatError(
                f"{name} line {lineno}: header column {i} {col!r} is not a valid column name "
                "(expected a header row such as 't,u,y' after the '# key: value' lines)"
            )
    dups = sorted({c for c in names if names.count(c) > 1})
    if dups:
        raise RecordingFormatError(
            f"{name} line {lineno}: duplicate column name(s) {', '.join(map(repr, dups))} "
            "in the header row"
        )
    missing = [c for c in REQUIRED_COLUMNS if c not in names]
    if missing:
        raise RecordingFormatError(
            f"{name} line {lineno}: missing required column(s) "
            f"{', '.join(map(repr, missing))}; the header row has "
            f"{', '.join(map(repr, names))}"
        )
    return names


def _read_csv(path: Path, name: str) -> Recording:
    preamble: dict[str, MetaValue] = {}
    trailer: dict[str, MetaValue] = {}
    header: list[str] = []
    data_start = 0  # line number of the first data row
    end_line = 0  # line number of the first comment/blank line after the data
    end_kind = ""
    values = array("d")
    n_rows = 0
    state = "preamble"  # -> "data" -> "trailer"

    with open(path, "rb") as f:
        for lineno, raw in enumerate(f, 1):
            if not raw.endswith(b"\n"):  # necessarily the last line of the file
                warnings.warn(
                    f"{name} line {lineno}: last line {raw[:80]!r} has no trailing newline "
                    "(the writer was probably interrupted mid-write); it was dropped",
                    PreisachWarning,
                    stacklevel=3,
                )
                break
            if lineno == 1 and raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]
            try:
                line = raw.decode("utf-8").rstrip("\r\n")
            except UnicodeDecodeError as exc:
                raise RecordingFormatError(
                    f"{name} line {lineno}: not valid UTF-8 text ({exc.reason})"
                ) from None
            stripped = line.strip()

            if state == "data":
                if stripped and stripped[0] != "#":
                    fields = line.split(",")
                    if len(fields) != len(header):
                        raise RecordingFormatError(
                            f"{name} line {lineno}: expected {len(header)} fields "
                            f"({','.join(header)}) but found {len(fields)}"
                        )
                    try:
                        if "_" in line:  # float() accepts '1_000'; the format does not
                            raise ValueError
                        values.extend(map(float, fields))
                    except ValueError:
                        for col, text in zip(header, fields):
                            try:
                                if "_" in text:
                                    raise ValueError
                                float(text)
                            except ValueError:
                                raise RecordingFormatError(
                                    f"{name} line {lineno}, column {col!r}: "
                                    f"{text.strip()!r} is not a number"
                                ) from None
                        raise  # pragma: no cover - unreachable
                    n_rows += 1
                    continue
                state = "trailer"
                end_line, end_kind = lineno, ("comment" if stripped else "blank")

            if not stripped:
                continue
            if state == "preamble":
                if stripped[0] == "#":
                    key, value = _parse_comment(name, lineno, line, preamble, "leading metadata")
                    preamble[key] = value
                else:
                    header = _parse_header(name, lineno, line)
                    data_start = lineno + 1
                    state = "data"
            elif stripped[0] == "#":
                key, value = _parse_comment(name, lineno, line, trailer, "trailing metadata")
                trailer[key] = value
            else:
                raise RecordingFormatError(
                    f"{name} line {end_line}: {end_kind} line in the middle of the data (data "
                    f"rows continue at line {lineno}); '# key: value' and blank lines are only "
                    "allowed before the header row and after the last data row"
                )

    if state == "preamble":
        raise RecordingFormatError(
            f"{name}: no header row found; expected a line such as 't,u,y' after the "
            "'# key: value' metadata lines"
        )

    ncol = len(header)
    block = np.frombuffer(values, dtype=np.float64).reshape(n_rows, ncol)
    bad = np.argwhere(~np.isfinite(block))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        raise RecordingFormatError(
            f"{name} line {data_start + i}, column {header[j]!r}: {float(block[i, j])!r} is "
            "not finite (NaN and infinite values are not allowed)"
        )
    t = block[:, header.index("t")]
    i_bad = _first_non_increasing(t)
    if i_bad is not None:
        raise RecordingFormatError(
            f"{name} line {data_start + i_bad}, column 't': time {float(t[i_bad])!r} s is not "
            f"greater than {float(t[i_bad - 1])!r} s on the line before (row index {i_bad}); "
            "t must be strictly increasing"
        )
    cols = {c: block[:, j] for j, c in enumerate(header)}
    return Recording(
        t=cols.pop("t"),
        u=cols.pop("u"),
        y=cols.pop("y"),
        columns=cols,
        metadata={**preamble, **trailer},
    )


def _read_npz(path: Path, name: str) -> Recording:
    f = open(path, "rb")  # opened here: np.load leaks its own handle on a bad archive
    try:
        npz = np.load(f, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - any failure here means a malformed file
        f.close()
        raise RecordingFormatError(
            f"{name}: not a readable NPZ archive ({npz_load_error(exc)})"
        ) from exc
    if not hasattr(npz, "files"):
        f.close()
        raise RecordingFormatError(f"{name}: a single .npy array, not an NPZ archive")

    metadata: dict[str, MetaValue] = {}
    cols: dict[str, NDArray[np.float64]] = {}
    with f, npz:
        for key in npz.files:
            try:
                arr = npz[key]
            except Exception as exc:  # noqa: BLE001 - e.g. pickled object arrays
                raise RecordingFormatError(
                    f"{name}, entry {key!r}: cannot be read ({exc})"
                ) from exc
            if key == _NPZ_METADATA:
                if arr.shape != () or arr.dtype.kind != "U":
                    raise RecordingFormatError(
                        f"{name}, entry {key!r}: expected a JSON string, got an array of "
                        f"dtype {arr.dtype} and shape {arr.shape}"
                    )
                try:
                    loaded = json.loads(str(arr[()]))
                    if not isinstance(loaded, dict):
                        raise TypeError(f"expected a JSON object, got {type(loaded).__name__}")
                    metadata = _check_metadata(loaded)
                except (ValueError, TypeError) as exc:
                    raise RecordingFormatError(f"{name}, entry {key!r}: {exc}") from exc
                continue
            if not _valid_name(key) or key.startswith("__"):
                raise RecordingFormatError(f"{name}: entry {key!r} is not a valid column name")
            if arr.dtype.kind not in "iuf":
                raise RecordingFormatError(
                    f"{name}, column {key!r}: dtype {arr.dtype} is not a real number type"
                )
            if arr.ndim != 1:
                raise RecordingFormatError(
                    f"{name}, column {key!r}: expected a 1-D array, got shape {arr.shape}"
                )
            cols[key] = arr.astype(np.float64)

    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if missing:
        raise RecordingFormatError(
            f"{name}: missing required column(s) {', '.join(map(repr, missing))}; found "
            f"{', '.join(map(repr, cols)) or 'no columns'}"
        )
    n = cols["t"].size
    for key, arr in cols.items():
        if arr.size != n:
            raise RecordingFormatError(
                f"{name}, column {key!r}: has {arr.size} samples but column 't' has {n}"
            )
    for key, arr in cols.items():
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            i = int(bad[0])
            raise RecordingFormatError(
                f"{name}, column {key!r}, index {i}: {float(arr[i])!r} is not finite "
                "(NaN and infinite values are not allowed)"
            )
    i_bad = _first_non_increasing(cols["t"])
    if i_bad is not None:
        t = cols["t"]
        raise RecordingFormatError(
            f"{name}, column 't', index {i_bad}: time {float(t[i_bad])!r} s is not greater "
            f"than {float(t[i_bad - 1])!r} s at index {i_bad - 1}; t must be strictly increasing"
        )
    return Recording(
        t=cols.pop("t"), u=cols.pop("u"), y=cols.pop("y"), columns=cols, metadata=metadata
    )


# --------------------------------------------------------------------------------------
# streaming writer
# --------------------------------------------------------------------------------------


class RecordingWriter:
    """Append-only CSV writer for recordings that must survive a crash.

    The metadata and header row are written and flushed when the writer is created; every
    :meth:`append` writes whole rows and flushes them to the operating system (and, with
    ``fsync=True``, to the disk) before returning.  :meth:`close` appends the trailing
    line ``# end_status: <status>``.  If the process dies before that, the file still
    loads with :meth:`Recording.load`, with every row whose line was completely written
    (a cut-off last line is dropped with a warning) and no ``end_status`` in its metadata.

    Each chunk is validated before anything is written (finite values, strictly
    increasing ``t`` that continues after the previous chunk), so the file on disk is
    always a valid recording.

    Use it as a context manager: leaving the block normally closes with status
    ``"complete"``, through :class:`KeyboardInterrupt` with ``"interrupted"``, and through
    any other exception with ``"aborted: <ExceptionType>: <message>"`` (or
    ``"aborted: <ExceptionType>"`` when the message is empty).  The exception is not
    suppressed.

    Parameters
    ----------
    path : str or path-like
        Destination ``.csv`` file.
    columns : sequence of str, default ``("t", "u", "y")``
        Column names in file order; must contain ``t`` (s), ``u`` (V) and ``y`` (V).
    metadata : mapping, optional
        Leading metadata (``str``/``int``/``float`` values), e.g. ``sample_time`` (s),
        ``input_units``, ``output_units``, ``experiment``.  ``end_status`` is reserved.
    fsync : bool, default True
        Also call :func:`os.fsync` after every append and at close, so data survive a power
        loss or OS crash, not just a crash of the Python process.  Costs a few
        milliseconds per append on a real disk; pass ``False`` for very frequent appends.
    overwrite : bool, default False
        Replace an existing file.  By default an existing file raises
        :class:`FileExistsError`, so an earlier recording is never clobbered.

    Examples
    --------
    >>> with RecordingWriter("trial.csv", metadata={"sample_time": 1e-3}) as w:  # doctest: +SKIP
    ...     for chunk in acquire():
    ...         w.append({"t": chunk.t, "u": chunk.u, "y": chunk.y})

    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        columns: Sequence[str] = REQUIRED_COLUMNS,
        metadata: Mapping[str, Any] | None = None,
        *,
        fsync: bool = True,
        overwrite: bool = False,
    ) -> None:
        names = tuple(_check_column_name(c) for c in columns)
        dups = sorted({c for c in names if names.count(c) > 1})
        if dups:
            raise ValueError(f"duplicate column name(s): {', '.join(map(repr, dups))}")
        missing = [c for c in REQUIRED_COLUMNS if c not in names]
        if missing:
            raise ValueError(
                f"columns must include 't', 'u' and 'y'; missing {', '.join(map(repr, missing))}"
            )
        meta = _check_metadata(metadata)
        if "end_status" in meta:
            raise ValueError("metadata key 'end_status' is reserved: close() writes it")
        self._path = Path(path)
        self._columns = names
        self._t_index = names.index("t")
        self._fsync = bool(fsync)
        self._n_rows = 0
        self._last_t = -np.inf
        self._status: str | None = None
        if overwrite:  # never stream into a directory or a device node
            check_target(self._path, "recording")
        self._file = open(self._path, "w" if overwrite else "x", encoding="utf-8", newline="")
        try:
            self._write(_meta_lines(meta) + ",".join(names) + "\n")
        except BaseException:
            self._file.close()
            raise

    @property
    def path(self) -> Path:
        """The file being written."""
        return self._path

    @property
    def columns(self) -> tuple[str, ...]:
        """Column names in file order."""
        return self._columns

    @property
    def n_rows(self) -> int:
        """Number of data rows written so far."""
        return self._n_rows

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run."""
        return self._file.closed

    @property
    def status(self) -> str | None:
        """The ``end_status`` written by :meth:`close`, ``None`` while open."""
        return self._status

    def _write(self, text: str) -> None:
        self._file.write(text)
        self._file.flush()
        if self._fsync:
            os.fsync(self._file.fileno())

    def _as_block(self, chunk: Mapping[str, ArrayLike] | ArrayLike) -> NDArray[np.float64]:
        k = len(self._columns)
        if isinstance(chunk, Mapping):
            missing = [c for c in self._columns if c not in chunk]
            unknown = [c for c in chunk if c not in self._columns]
            if missing or unknown:
                raise ValueError(
                    f"chunk keys must be exactly the columns {list(self._columns)}; "
                    f"missing {missing}, unknown {unknown}"
                )
            arrays = [np.atleast_1d(np.asarray(chunk[c], dtype=np.float64)) for c in self._columns]
            for c, a in zip(self._columns, arrays):
                if a.ndim != 1:
                    raise ValueError(f"chunk column {c!r} must be 1-D, got shape {a.shape}")
            lengths = {c: a.size for c, a in zip(self._columns, arrays)}
            if len(set(lengths.values())) > 1:
                raise ValueError(f"chunk columns have different lengths: {lengths}")
            return np.column_stack(arrays).reshape(arrays[0].size, k)
        block = np.asarray(chunk, dtype=np.float64)
        if block.ndim == 1 and block.size == k:
            block = block.reshape(1, k)
        if block.ndim != 2 or block.shape[1] != k:
            raise ValueError(
                f"array chunk must have shape (n, {k}) with columns {list(self._columns)}, "
                f"got shape {block.shape}"
            )
        return block

    def append(self, chunk: Mapping[str, ArrayLike] | ArrayLike) -> int:
        """Validate, write and flush a chunk of samples.

        Parameters
        ----------
        chunk : mapping or array_like
            Either a dict ``{column: values}`` with exactly the writer's columns and equal
            lengths (scalars count as one sample), or a 2-D array of shape
            ``(n, len(columns))`` with the columns in order (a 1-D array of length
            ``len(columns)`` is one row).  ``t`` in seconds, ``u`` and ``y`` in volts.

        Returns
        -------
        int
            Number of rows written.

        Raises
        ------
        ValueError
            If the writer is closed, the chunk has the wrong shape or keys, a value is
            NaN/inf, or ``t`` is not strictly increasing (within the chunk or relative to
            the last row written).  Nothing from a rejected chunk is written.

        """
        if self.closed:
            raise ValueError(f"{self._path}: cannot append, the writer is closed")
        block = self._as_block(chunk)
        n = block.shape[0]
        if n == 0:
            return 0
        bad = np.argwhere(~np.isfinite(block))
        if bad.size:
            i, j = (int(v) for v in bad[0])
            raise ValueError(
                f"{self._path}: chunk row {i}, column {self._columns[j]!r}: "
                f"{float(block[i, j])!r} is not finite; nothing from this chunk was written"
            )
        t = block[:, self._t_index]
        if t[0] <= self._last_t:
            raise ValueError(
                f"{self._path}: chunk row 0, column 't': time {float(t[0])!r} s is not greater "
                f"than the last time written, {float(self._last_t)!r} s; nothing from this "
                "chunk was written"
            )
        i_bad = _first_non_increasing(t)
        if i_bad is not None:
            raise ValueError(
                f"{self._path}: chunk row {i_bad}, column 't': time {float(t[i_bad])!r} s is "
                f"not greater than {float(t[i_bad - 1])!r} s; nothing from this chunk was written"
            )
        self._write(_rows_text(block))
        self._n_rows += n
        self._last_t = float(t[-1])
        return int(n)

    def close(self, status: str = "complete", metadata: Mapping[str, Any] | None = None) -> None:
        """Write the trailing metadata and ``# end_status: <status>``, then close the file.

        Calling it again does nothing.

        Parameters
        ----------
        status : str, default ``"complete"``
            Final status, stored as metadata ``end_status``.
        metadata : mapping, optional
            Further metadata to append as trailing ``# key: value`` lines (e.g. results
            known only at the end); it overrides leading metadata with the same key when
            the file is loaded.  ``end_status`` is reserved.

        """
        if self.closed:
            return
        meta = _check_metadata(metadata)
        if "end_status" in meta:
            raise ValueError("use the status argument, not metadata, to set 'end_status'")
        meta["end_status"] = str(status)
        try:
            self._write(_meta_lines(meta))
        finally:
            self._file.close()
        self._status = str(status)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close("complete")
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close("interrupted")
        else:
            message = str(exc) if exc is not None else ""
            status = f"aborted: {exc_type.__name__}"
            self.close(f"{status}: {message}" if message else status)

    def __repr__(self) -> str:
        """Return path, columns, rows written and state."""
        state = f"closed, status={self._status!r}" if self.closed else "open"
        return (
            f"RecordingWriter({str(self._path)!r}, columns={list(self._columns)}, "
            f"n_rows={self._n_rows}, {state})"
        )


# --------------------------------------------------------------------------------------
# recordings as input: the one place that turns what a caller passes into Recordings
# --------------------------------------------------------------------------------------


@runtime_checkable
class SampledData(Protocol):
    """Anything with sampled ``t`` (s), ``u`` (V) and ``y`` (V), e.g. a :class:`Recording`."""

    @property
    def t(self) -> Any: ...  # noqa: D102

    @property
    def u(self) -> Any: ...  # noqa: D102

    @property
    def y(self) -> Any: ...  # noqa: D102


#: One recording as a caller may give it: a :class:`Recording`, a file path (``.csv`` or
#: ``.npz``) or any object with ``t``, ``u`` and ``y``.
RecordingLike = Union[Recording, str, "os.PathLike[str]", SampledData]
#: One recording or a sequence of them (what every ``recordings`` argument accepts).
RecordingsInput = Union[RecordingLike, Sequence[RecordingLike]]

#: Metadata keys giving a recording's label, in order of precedence.
LABEL_KEYS: tuple[str, str] = ("experiment", "name")


def _has_tuy(obj: object) -> bool:
    return all(hasattr(obj, a) for a in REQUIRED_COLUMNS) and not isinstance(obj, np.ndarray)


def _one_recording(obj: object, where: str) -> Recording:
    if isinstance(obj, Recording):
        return obj
    if isinstance(obj, (str, os.PathLike)):
        rec = Recording.load(obj)
        if recording_label(rec) is None:
            rec.metadata["experiment"] = Path(os.fspath(obj)).stem
        return rec
    if _has_tuy(obj):
        meta = getattr(obj, "metadata", None)
        kept = {
            k: v
            for k, v in (meta.items() if isinstance(meta, Mapping) else ())
            if _valid_name(k)
            and isinstance(v, (str, int, float, np.integer, np.floating))
            and not isinstance(v, (bool, np.bool_))
        }
        try:
            return Recording(
                t=cast(Any, getattr(obj, "t")),  # noqa: B009
                u=cast(Any, getattr(obj, "u")),  # noqa: B009
                y=cast(Any, getattr(obj, "y")),  # noqa: B009
                metadata=kept,
            )
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from exc
    raise TypeError(
        f"{where}: expected a Recording, a file path or an object with t, u, y; "
        f"got {type(obj).__name__}"
    )


def as_recordings(recordings: object, *, argument: str = "recordings") -> list[Recording]:
    """Turn what a caller passes as recordings into a list of :class:`Recording`.

    Every public function taking ``recordings`` goes through this one function, so each
    accepts the same things: a :class:`Recording`, a path to a ``.csv`` or ``.npz`` recording
    file, any object with sampled ``t`` (s), ``u`` (V) and ``y`` (V) attributes (copied into a
    :class:`Recording`, keeping its ``str``/``int``/``float`` metadata), or a sequence
    (list, tuple, generator) of any of these.  ``Recording`` objects are passed through, not
    copied.  A file whose metadata has no label (see :func:`recording_label`) gets its file
    stem as ``experiment``.

    Parameters
    ----------
    recordings : Recording, path, object with t/u/y, or a sequence of them
        What to convert.
    argument : str
        Argument name used in error messages.

    Returns
    -------
    list of Recording
        At least one recording, in the order given.

    Raises
    ------
    TypeError
        If an item is none of the accepted kinds.
    ValueError
        If no recording is given or an item's data are invalid (see :class:`Recording`).
    OSError
        If a file cannot be opened (e.g. :class:`FileNotFoundError`).
    RecordingFormatError
        If a file is not a valid recording.

    """
    if isinstance(recordings, (Recording, str, os.PathLike)) or _has_tuy(recordings):
        return [_one_recording(recordings, argument)]
    if isinstance(recordings, (Mapping, np.ndarray)):
        raise TypeError(
            f"{argument}: expected a Recording, a file path, an object with t, u, y or a "
            f"sequence of them; got {type(recordings).__name__}"
        )
    try:
        items = list(cast(Any, recordings))
    except TypeError:
        raise TypeError(
            f"{argument}: expected a Recording, a file path, an object with t, u, y or a "
            f"sequence of them; got {type(recordings).__name__}"
        ) from None
    if not items:
        raise ValueError(f"{argument}: need at least one recording")
    return [_one_recording(r, f"{argument}[{k}]") for k, r in enumerate(items)]


def recording_label(recording: object) -> str | None:
    """Return a recording's own label: its ``experiment`` metadata, else its ``name``.

    Empty values do not count; ``None`` when neither key gives a label.
    """
    meta = getattr(recording, "metadata", None)
    if not isinstance(meta, Mapping):
        return None
    for key in LABEL_KEYS:
        value = meta.get(key)
        if value is not None and str(value):
            return str(value)
    return None


def recording_labels(
    recordings: Sequence[object],
    labels: Sequence[str] | None = None,
    *,
    argument: str = "labels",
) -> list[str]:
    """Label each recording by the one rule every report, table and figure uses.

    The rule: explicit ``labels`` if given (one per recording); otherwise each recording's
    :func:`recording_label` (``experiment`` metadata, else ``name``; a file loaded by
    :func:`as_recordings` carries its stem), else ``"recording k"`` (``k`` its position from
    0).  A label shared by several recordings gets `` #1``, `` #2``... in order, so labels are
    unique.

    Parameters
    ----------
    recordings : sequence
        The recordings (see :func:`as_recordings`).
    labels : sequence of str, optional
        Explicit labels, one per recording, used as given (duplicates numbered too).
    argument : str
        Name of the ``labels`` argument in error messages.

    Returns
    -------
    list of str
        One unique label per recording.

    Raises
    ------
    ValueError
        If ``labels`` does not have one entry per recording.

    """
    if labels is not None:
        names = [str(n) for n in labels]
        if len(names) != len(recordings):
            raise ValueError(
                f"{argument}: got {len(names)} labels for {len(recordings)} recordings"
            )
    else:
        names = [recording_label(r) or f"recording {k}" for k, r in enumerate(recordings)]
    seen: dict[str, int] = {}
    out = []
    for n in names:
        if names.count(n) > 1:
            seen[n] = seen.get(n, 0) + 1
            out.append(f"{n} #{seen[n]}")
        else:
            out.append(n)
    return out
