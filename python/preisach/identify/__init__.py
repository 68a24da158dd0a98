"""Identification of Preisach models from measured data.

* :func:`identify` picks the method from the data (``method="auto"``: Mayergoyz for FOD/FORC
  sweeps that cover their grid, least squares otherwise) and estimates the output delay
  (:func:`estimate_delay`); :func:`identify_forc` and :func:`forc_diagram` read MicroMag FORC
  files;
* :func:`find_fod_curves` / :func:`find_forc_curves` find first-order descending (FOD) or
  reversal (FORC) curves in any recording and read them on a grid of levels;
* :func:`fit_sqrt_surface` identifies the constrained square-root FOD surface of the thesis
  (section 3.3.2, Eq 3.2) from such a grid;
* :func:`identify_fod` (Mayergoyz, C++), :func:`identify_surface` (square-root surface) and
  :func:`identify_lsq` (least squares on every sample of any recording) each return an
  :class:`IdentificationReport` (``report.model``; it unpacks as ``model, report``);
  :func:`project_nonnegative` and :func:`weight_density` give the nearest model in Mp and the
  split mu = v + kappa delta.
"""

from __future__ import annotations

from .auto import identify, mirror_model, mirror_recording
from .delay import DelayEstimate, estimate_delay, shift_output
from .fod_finder import CurveRecord, FODData, find_fod_curves, find_forc_curves
from .forc_identify import ForcDiagram, forc_diagram, identify_forc
from .identifiers import (
    identify_fod,
    identify_lsq,
    identify_surface,
    project_nonnegative,
    weight_density,
)
from .lsq import LsqDetails
from .report import DataUsage, IdentificationReport, ProjectionSummary, Residuals
from .surface_fit import SurfaceFitResult, fit_sqrt_surface, format_table

__all__ = [
    "CurveRecord",
    "DataUsage",
    "DelayEstimate",
    "ForcDiagram",
    "FODData",
    "IdentificationReport",
    "LsqDetails",
    "ProjectionSummary",
    "Residuals",
    "SurfaceFitResult",
    "find_fod_curves",
    "estimate_delay",
    "find_forc_curves",
    "forc_diagram",
    "fit_sqrt_surface",
    "format_table",
    "identify",
    "identify_fod",
    "identify_forc",
    "identify_lsq",
    "identify_surface",
    "mirror_model",
    "mirror_recording",
    "project_nonnegative",
    "shift_output",
    "weight_density",
]
