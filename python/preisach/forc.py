"""First-order reversal curve (FORC) files of magnetometers (Princeton MicroMag AGM/VSM).

A FORC measurement is the mirror image of the thesis's FOD identification (§2.6): after each
visit to positive saturation the field falls to a reversal field ``H_r`` (= beta) and the
moment is measured while the field rises again (alpha).  The same Preisach machinery applies
(:func:`preisach.identify.fod_finder.find_forc_curves`, ``PreisachModel.from_fod_grid`` on the
mirrored grid), with the field in place of the input voltage and the moment in place of the
output.

The MicroMag text format: a free-text preamble, ``key = value`` header lines (``NCrv``,
``HSat``, ``HCal``, ``HNcr``, ``Elapsed time``, ``NData``, ...), then blank-line-separated
blocks of ``field,moment`` pairs that alternate between a single calibration point measured at
the calibration field ``HCal`` (near saturation) and one FORC, and a closing ``... ends`` line.
Units are those of the header's ``Units of measure`` (``Hybrid SI``: field mu0*H in tesla,
moment in A m^2).  The calibration points let the instrument's drift over the run be corrected
(:meth:`ForcMeasurement.drift_corrected`).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Union

import numpy as np

from .errors import RecordingFormatError
from .recording import Recording

__all__ = ["ForcMeasurement", "read_forc"]

PathLike = Union[str, "os.PathLike[str]"]

_HEADER = re.compile(r"^\s*([A-Za-z][\w .()/-]*?)\s*[=:]\s*(.*?)\s*$")


@dataclass(frozen=True)
class ForcMeasurement:
    """A FORC measurement: the curves, the calibration points between them and the header.

    Attributes
    ----------
    curves : list of numpy.ndarray
        One ``(n, 2)`` array per FORC, in measurement order: field (T for Hybrid SI) rising from
        the reversal field in the first row, and the moment (A m^2).
    calibration : numpy.ndarray
        ``(len(curves), 2)``: the calibration point (field, moment) measured just before each
        curve.
    header : dict
        ``key = value`` lines of the file; numeric values as ``float``.
    source : str
        The file read.

    """

    curves: list[np.ndarray]
    calibration: np.ndarray
    header: dict[str, object] = field(default_factory=dict)
    source: str = ""

    @property
    def reversal_fields(self) -> np.ndarray:
        """The reversal field ``H_r`` (beta) of each curve: its first field value (T)."""
        return np.array([c[0, 0] for c in self.curves])

    def drift(self) -> np.ndarray:
        """Relative change of the calibration moment from the first curve (1, per curve)."""
        m = np.asarray(self.calibration[:, 1], dtype=np.float64)
        return m / float(m[0]) - 1.0

    def drift_corrected(self) -> ForcMeasurement:
        """Return the measurement with each curve's moment scaled by its calibration point.

        The calibration moment (at a fixed field near saturation) should not change during
        the run; a change is instrument drift (temperature, vibration amplitude), taken here as
        a gain drift: curve ``k`` is multiplied by ``m_cal[0] / m_cal[k]``.
        """
        m = self.calibration[:, 1]
        curves = [
            np.column_stack([c[:, 0], c[:, 1] * (m[0] / mk)]) for c, mk in zip(self.curves, m)
        ]
        cal = np.column_stack([self.calibration[:, 0], np.full(len(m), m[0])])
        return replace(self, curves=curves, calibration=cal)

    def to_recording(self) -> Recording:
        """Return the measurement as one recording, in the order it was measured.

        Each calibration point (``u`` = the calibration field, at positive saturation) is
        followed by its curve, so :func:`preisach.identify.fod_finder.find_forc_curves` finds
        the curves by themselves.  ``u`` is the field and ``y`` the moment, in the file's
        units (named in ``input_units``/``output_units``).  The file has no time stamps: ``t``
        spreads the points evenly over the header's ``Elapsed time`` (s) when it is given,
        else one second per point (``metadata["time_base"]`` says which).
        """
        us, ys = [], []
        for (cu, cm), c in zip(self.calibration, self.curves):
            us.append([cu, *c[:, 0]])
            ys.append([cm, *c[:, 1]])
        u = np.concatenate(us)
        y = np.concatenate(ys)
        elapsed = self.header.get("Elapsed time")
        if isinstance(elapsed, float) and elapsed > 0:
            dt, base = elapsed / u.size, "points spread evenly over the elapsed time"
        else:
            dt, base = 1.0, "one second per point (no elapsed time in the file)"
        hybrid = str(self.header.get("Units of measure", "")).lower().startswith("hybrid")
        return Recording.from_arrays(
            u=u,
            y=y,
            sample_time=dt,
            experiment="forc",
            input_units="T" if hybrid else "field",
            output_units="A m^2" if hybrid else "moment",
            metadata={"source": self.source, "time_base": base},
        )


def read_forc(path: PathLike) -> ForcMeasurement:
    """Read a MicroMag FORC file (see the module docstring for the format).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.forc`` text file.

    Returns
    -------
    ForcMeasurement
        Curves and calibration points in measurement order.

    Raises
    ------
    preisach.errors.RecordingFormatError
        If a data line is not two numbers (file and line named), a curve has no calibration
        point before it, or the file holds no curve.

    """
    name = os.fspath(path)
    lines = Path(name).read_text(encoding="utf-8", errors="replace").splitlines()
    header: dict[str, object] = {}
    k = 0
    # the header ends at the first line that is a "field,moment" pair
    while k < len(lines) and not _is_pair(lines[k]):
        m = _HEADER.match(lines[k])
        if m:
            key, value = m.group(1).strip(), m.group(2)
            try:
                header[key] = float(value)
            except ValueError:
                header[key] = value
        k += 1
    blocks: list[list[tuple[float, float]]] = []
    block: list[tuple[float, float]] = []
    for lineno in range(k, len(lines)):
        text = lines[lineno].strip()
        if not text:
            if block:
                blocks.append(block)
                block = []
            continue
        if not _is_pair(text):
            if "ends" in text.lower():
                break
            raise RecordingFormatError(
                f"{name}, line {lineno + 1}: expected 'field,moment', got {text[:60]!r}"
            )
        a, b = text.split(",")
        block.append((float(a), float(b)))
    if block:
        blocks.append(block)
    if len(blocks) < 2:
        raise RecordingFormatError(f"{name}: no first-order reversal curve found")
    cal, curves = blocks[0::2], blocks[1::2]
    if len(cal) != len(curves) or any(len(c) != 1 for c in cal):
        raise RecordingFormatError(
            f"{name}: expected blocks alternating between one calibration point and one curve; "
            f"got {len(blocks)} blocks of sizes {[len(b) for b in blocks[:6]]}..."
        )
    return ForcMeasurement(
        curves=[np.array(c, dtype=float) for c in curves],
        calibration=np.array([c[0] for c in cal], dtype=float),
        header=header,
        source=name,
    )


def _is_pair(text: str) -> bool:
    """Whether a line is two comma-separated numbers."""
    parts = text.strip().split(",")
    if len(parts) != 2:
        return False
    try:
        float(parts[0])
        float(parts[1])
    except ValueError:
        return False
    return True
