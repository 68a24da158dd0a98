"""Identification of Preisach models from measured data.

* :func:`find_fod_curves` / :func:`find_forc_curves` find first-order descending (FOD) or
  reversal (FORC) curves in any recording and read them on a grid of levels;
* :func:`fit_sqrt_surface` identifies the constrained square-root FOD surface of the thesis
  (section 3.3.2, Eq 3.2) from such a grid.
"""

from __future__ import annotations

from .fod_finder import CurveRecord, FODData, find_fod_curves, find_forc_curves
from .surface_fit import SurfaceFitResult, fit_sqrt_surface, format_table

__all__ = [
    "CurveRecord",
    "FODData",
    "SurfaceFitResult",
    "find_fod_curves",
    "find_forc_curves",
    "fit_sqrt_surface",
    "format_table",
]
