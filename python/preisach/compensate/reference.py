"""Reference outputs from files: a recording-format CSV with columns ``t`` (s) and ``y`` (V)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["read_reference"]


def read_reference(path: str) -> tuple[NDArray[np.float64], NDArray[np.float64], dict[str, str]]:
    """Read ``t`` (s) and ``y`` (V) from a recording-format CSV; returns ``(t, y, metadata)``.

    Raises
    ------
    ValueError
        Naming the file and line: unreadable file, no header, no ``t`` or ``y`` column, a
        row with the wrong number of fields or a non-finite number, ``t`` not increasing,
        no data rows.

    """
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the reference ({exc})") from exc
    meta: dict[str, str] = {}
    header: list[str] | None = None
    rows: list[list[float]] = []
    done = False
    for lineno, raw in enumerate(lines, 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            if header is not None and rows:
                done = True
            if line.startswith("#") and ":" in line:
                key, _, value = line[1:].partition(":")
                meta[key.strip()] = value.strip()
            continue
        if done:
            raise ValueError(f"{path} line {lineno}: data after a comment or blank line")
        if header is None:
            header = [c.strip() for c in line.split(",")]
            missing = [c for c in ("t", "y") if c not in header]
            if missing:
                raise ValueError(
                    f"{path} line {lineno}: the header row needs columns 't' and 'y' "
                    f"(missing {', '.join(map(repr, missing))}); got {line[:80]!r}"
                )
            continue
        fields = line.split(",")
        if len(fields) != len(header):
            raise ValueError(
                f"{path} line {lineno}: expected {len(header)} fields, got {len(fields)}"
            )
        try:
            row = [float(f) for f in fields]
        except ValueError as exc:
            raise ValueError(f"{path} line {lineno}: not a number ({exc})") from exc
        if not all(math.isfinite(v) for v in row):
            raise ValueError(f"{path} line {lineno}: values must be finite")
        rows.append(row)
    if header is None or not rows:
        raise ValueError(f"{path}: no data: a reference needs a header row (t,y) and samples")
    data = np.array(rows, dtype=np.float64)
    t = np.ascontiguousarray(data[:, header.index("t")])
    y = np.ascontiguousarray(data[:, header.index("y")])
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ValueError(f"{path}: t must be strictly increasing (sample {bad[0] + 1})")
    return t, y, meta
