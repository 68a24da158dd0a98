"""Reports of the identifiers of :mod:`preisach.identify`.

:class:`IdentificationReport` is what every ``identify_*`` function returns: the model
(``report.model``), the data used, the residuals in the recording's own units, warnings and the
method's details.  It still unpacks like the ``(model, report)`` pair the functions used to
return (``model, report = identify_lsq(rec)``).  Reports are built with keyword arguments.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np
from numpy.typing import NDArray

from .. import _core
from ..model import PreisachModel

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .delay import DelayEstimate
    from .fod_finder import FODData
    from .lsq import LsqDetails
    from .surface_fit import SurfaceFitResult

__all__ = ["DataUsage", "IdentificationReport", "ProjectionSummary", "Residuals"]


@dataclass
class Residuals:
    """Residual statistics of a model against some data (output units and % of the output range).

    Attributes
    ----------
    name : str
        What was compared (an experiment, or ``"FOD nodes"``).
    n : int
        Number of values compared.
    max_error, rms_error : float
        ``max |e|`` and ``sqrt(mean e^2)`` (output units), ``e`` = model - measurement.
    output_range : float
        Range (output units) the percentages refer to.

    """

    name: str
    n: int
    max_error: float
    rms_error: float
    output_range: float

    @property
    def max_pct(self) -> float:
        """``max_error`` in % of ``output_range``."""
        return 100.0 * self.max_error / self.output_range

    @property
    def rms_pct(self) -> float:
        """``rms_error`` in % of ``output_range``."""
        return 100.0 * self.rms_error / self.output_range

    @classmethod
    def of(cls, name: str, e: NDArray[np.float64], output_range: float) -> Residuals:
        """Statistics of the errors ``e`` (output units)."""
        e = np.asarray(e, dtype=float)
        return cls(
            name=name,
            n=int(e.size),
            max_error=float(np.max(np.abs(e))) if e.size else 0.0,
            rms_error=float(np.sqrt(np.mean(e * e))) if e.size else 0.0,
            output_range=float(output_range),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            "name": self.name,
            "n": self.n,
            "max_error": self.max_error,
            "rms_error": self.rms_error,
            "output_range": self.output_range,
            "max_pct": self.max_pct,
            "rms_pct": self.rms_pct,
        }


@dataclass
class DataUsage:
    """Which data an identification used.

    Attributes
    ----------
    name : str
        Experiment name (``experiment`` metadata, or ``"recording k"``).
    n_samples : int
        Samples in the recording.
    n_used : int
        Samples the identification used: fitted samples (lsq) or samples on used FOD curves.
    note : str
        Details (curves used/rejected, burn-in, ...).

    """

    name: str
    n_samples: int
    n_used: int
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return dict(self.__dict__)


@dataclass
class ProjectionSummary:
    """How much the projection to ``mu >= 0`` changed the table (all masses in output units).

    Attributes
    ----------
    n_negative : int
        Cells with negative mass before.
    negative_mass : float
        Sum of the negative masses before (V, <= 0).
    mass_moved : float
        ``sum |w' - w|`` over the cells (V).
    total_mass : float
        ``sum |w|`` before (V).
    max_node_change, rms_node_change : float
        Largest and RMS change of the Everett nodes (V); outputs move by at most twice the
        largest.
    kept : str
        What was kept exactly: ``"y_min and y_max"`` or ``"y_min"``.
    converged : bool
        Whether the projection converged to its tolerance.
    sweeps : int
        Sweeps of Hildreth's method.

    """

    n_negative: int
    negative_mass: float
    mass_moved: float
    total_mass: float
    max_node_change: float
    rms_node_change: float
    kept: str
    converged: bool
    sweeps: int

    @property
    def fraction_moved(self) -> float:
        """``mass_moved / total_mass`` (0 for an empty table)."""
        return self.mass_moved / self.total_mass if self.total_mass > 0 else 0.0

    @classmethod
    def of(cls, r: _core.ProjectionResult) -> ProjectionSummary:
        """From the C++ result."""
        return cls(
            n_negative=int(r.n_negative),
            negative_mass=float(r.negative_mass),
            mass_moved=float(r.mass_moved),
            total_mass=float(r.total_mass),
            max_node_change=float(r.max_node_change),
            rms_node_change=float(r.rms_node_change),
            kept="y_min and y_max" if r.kept_y_max else "y_min",
            converged=bool(r.converged),
            sweeps=int(r.sweeps),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {**self.__dict__, "fraction_moved": self.fraction_moved}


@dataclass
class IdentificationReport:
    """What an identifier did and how well the model fits (build it with keyword arguments).

    Unpacks as ``(model, report)``: ``model, report = identify_lsq(rec)`` keeps working.

    Attributes
    ----------
    method : str
        ``"fod"``, ``"surface"`` or ``"lsq"`` (the method that ran).
    model : PreisachModel
        The identified model.
    data : list of DataUsage
        Recordings (or FOD data) used.
    residuals : list of Residuals
        Per recording: the model simulated on the recording's input (burn-in policy of
        :func:`preisach.verify.verify`, output ``delay`` applied).  Empty when only FOD data
        were given.
    node_residuals : Residuals or None
        fod/surface: model FOD outputs against the measured FOD nodes.
    warnings : list of str
    fod : FODData or None
        The FOD curves found (merged over the recordings).
    surface_fit : SurfaceFitResult or None
        surface: the square-root fit (Table 3.1-style parameters, fit errors).
    projection : ProjectionSummary or None
        fod with ``project=True``: the mass moved.
    lsq : LsqDetails or None
        lsq: cross-validation curve, chosen lambda, ...
    negative_cells : int
        Cells of the final table with negative mass (not in Mp when > 0).
    elapsed : float
        Wall-clock seconds of the identification.
    input_units, output_units : str
        Units of the recordings' input and output (``input_units`` / ``output_units``
        metadata; ``"V"`` when absent); every number in :meth:`summary` is in these units.
    delay : float
        Output delay (samples) the model was identified and scored with: ``y(k + delay)``
        answers ``u(k)``.
    delay_estimate : DelayEstimate or None
        How the delay was estimated when it was not given.
    choice : str
        Why this method ran (``method="auto"``); empty when the caller chose it.

    """

    method: str
    model: PreisachModel
    data: list[DataUsage] = field(default_factory=list)
    residuals: list[Residuals] = field(default_factory=list)
    node_residuals: Residuals | None = None
    warnings: list[str] = field(default_factory=list)
    fod: FODData | None = field(default=None, repr=False)
    surface_fit: SurfaceFitResult | None = field(default=None, repr=False)
    projection: ProjectionSummary | None = None
    lsq: LsqDetails | None = field(default=None, repr=False)
    negative_cells: int = 0
    elapsed: float = 0.0
    input_units: str = "V"
    output_units: str = "V"
    delay: float = 0.0
    delay_estimate: DelayEstimate | None = field(default=None, repr=False)
    choice: str = ""

    # Unpacking is what the identifiers returned before the report was the result: typed
    # Any on purpose, so ``model, report = identify_lsq(rec)`` still type-checks; new code
    # uses ``report.model``, and indexing is typed exactly.
    def __iter__(self) -> Iterator[Any]:
        """Unpack as ``(model, report)`` (the identifiers' former return value)."""
        yield self.model
        yield self

    @overload
    def __getitem__(self, index: Literal[0, -2]) -> PreisachModel: ...
    @overload
    def __getitem__(self, index: Literal[1, -1]) -> IdentificationReport: ...
    @overload
    def __getitem__(self, index: int) -> PreisachModel | IdentificationReport: ...
    def __getitem__(self, index: int) -> PreisachModel | IdentificationReport:
        """``report[0]`` is the model, ``report[1]`` the report (tuple compatibility)."""
        return (self.model, self)[index]

    def summary(self) -> str:
        """Readable multi-line report (numbers in the recording's units)."""
        m = self.model
        ui, uo = self.input_units, self.output_units
        names = {
            "fod": "Mayergoyz (FOD grid -> Everett table)",
            "surface": "square-root FOD surface (thesis Eq 3.2)",
            "lsq": "least squares on every sample",
        }
        lines = [f"identification: {names.get(self.method, self.method)}"]
        if self.choice:
            lines.append(f"  method chosen automatically: {self.choice}")
        lines += [
            f"  model: {m!r}",
            f"  levels: {m.levels.size} from {m.u_min:.6g} to {m.u_max:.6g} {ui}; "
            + (
                "in Mp (all cell masses >= 0)"
                if self.negative_cells == 0
                else f"{self.negative_cells} cells with negative mass (not in Mp)"
            ),
            f"  output delay: {self.delay:g} samples"
            + ("" if self.delay_estimate is None else f" ({self.delay_estimate.describe()})"),
            f"  interpolation between the nodes: {self._interpolation_text()}",
            f"  time: {self.elapsed:.3f} s",
            "  data:",
        ]
        for d in self.data:
            lines.append(
                f"    {d.name}: {d.n_used} of {d.n_samples} samples used"
                + (f"; {d.note}" if d.note else "")
            )
        if self.fod is not None:
            n = self.fod.levels.size
            lines.append(
                f"  FOD nodes measured: {int(np.count_nonzero(self.fod.count))} of "
                f"{n * (n + 1) // 2}"
            )
        if self.surface_fit is not None:
            sf = self.surface_fit
            lines.append("  surface parameters (Table 3.1 layout):")
            lines += ["    " + ln for ln in sf.table().splitlines()]
            lines.append(
                f"  surface fit: rms {sf.rmse:.4g} {uo}, max {sf.max_error:.4g} {uo} over "
                f"{sf.n_points} FOD points"
            )
        if self.projection is not None:
            p = self.projection
            lines.append(
                f"  projection to mu >= 0: {p.n_negative} negative cells (sum "
                f"{p.negative_mass:.4g} {uo}); moved {p.mass_moved:.4g} {uo} = "
                f"{100 * p.fraction_moved:.3g} % of the total mass {p.total_mass:.4g} {uo}; "
                f"max node change {p.max_node_change:.3g} {uo}; kept {p.kept}"
                + ("" if p.converged else " (did not converge)")
            )
        if self.lsq is not None:
            lines += self.lsq.summary_lines(uo)
        if self.node_residuals is not None:
            r = self.node_residuals
            lines.append(
                f"  residuals at the FOD nodes: max {r.max_error:.4g} {uo} "
                f"({r.max_pct:.3f} %), rms {r.rms_error:.4g} {uo} ({r.rms_pct:.3f} %) of "
                f"{r.output_range:.4g} {uo}, {r.n} nodes"
            )
        if self.residuals:
            lines.append("  residuals on the recordings (model simulated on their inputs):")
            h1, h2 = f"max ({uo})", f"rms ({uo})"
            lines.append(f"    {'experiment':<24} {h1:>10} {h2:>10} {'max %':>8} {'rms %':>8}")
            for r in self.residuals:
                lines.append(
                    f"    {r.name[:24]:<24} {r.max_error:>10.4g} {r.rms_error:>10.4g} "
                    f"{r.max_pct:>8.3f} {r.rms_pct:>8.3f}"
                )
        if self.warnings:
            lines.append("  warnings:")
            lines += [f"    - {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """HTML for Jupyter: model, data, residuals with units, warnings highlighted."""
        from .._display import identification_html

        return identification_html(self)

    def __str__(self) -> str:
        return self.summary()

    def _interpolation_text(self) -> str:
        c = self.model.metadata.get("interpolation")
        kind = self.model.interpolation
        if not isinstance(c, dict) or "rms_cubic" not in c:
            return kind
        uo = self.output_units
        return (
            f"{kind} (RMS residual on the recordings: bilinear {c['rms_bilinear']:.4g} {uo}, "
            f"cubic {c['rms_cubic']:.4g} {uo}; cubic needs {100 * c['margin']:.0f} % less)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form (no arrays of samples)."""
        choice = self.model.metadata.get("interpolation")
        out: dict[str, Any] = {
            "method": self.method,
            "choice": self.choice,
            "interpolation": choice
            if isinstance(choice, dict)
            else {"interpolation": self.model.interpolation},
            "model": repr(self.model),
            "levels": self.model.levels.tolist(),
            "y_min": self.model.y_min,
            "y_max": self.model.y_max,
            "input_units": self.input_units,
            "output_units": self.output_units,
            "delay": self.delay,
            "delay_estimate": None
            if self.delay_estimate is None
            else self.delay_estimate.to_dict(),
            "negative_cells": self.negative_cells,
            "elapsed": self.elapsed,
            "data": [d.to_dict() for d in self.data],
            "residuals": [r.to_dict() for r in self.residuals],
            "node_residuals": None
            if self.node_residuals is None
            else self.node_residuals.to_dict(),
            "warnings": list(self.warnings),
            "projection": None if self.projection is None else self.projection.to_dict(),
            "lsq": None if self.lsq is None else self.lsq.to_dict(),
        }
        if self.surface_fit is not None:
            sf = self.surface_fit
            out["surface"] = {
                **sf.surface.to_dict(),
                "rmse": sf.rmse,
                "max_error": sf.max_error,
                "root_sum_sq_error": sf.root_sum_sq_error,
                "n_points": sf.n_points,
            }
        return out

    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Draw the identification: FOD data and model, weight density, kappa, CV curve.

        Six panels (:func:`preisach.identify.plots.plot_report`): the FOD data with the model's
        FOD curves (fod/surface) or the cross-validation curve (lsq), the FOD surface in
        (alpha, beta) and (r, s), the density v in both, and kappa, axes in the recording's
        units.  Returns the Figure.
        """
        from .plots import plot_report

        return plot_report(self, fig=fig)
