"""FORC measurements end to end: a Preisach model from a MicroMag file, and the FORC diagram.

:func:`identify_forc` reads a ``.forc`` file (:func:`preisach.forc.read_forc`), corrects the
instrument's drift from the calibration points, and identifies a model on the grid of the
measured reversal fields (plus the top field): first-order reversal curves rise from a
reversal field after positive saturation, which is the thesis's FOD sweep mirrored
(``u -> -u``, ``y -> -y``), so Mayergoyz applies to the mirrored curves and the model is
mirrored back (:func:`preisach.identify.auto.mirror_model`).  Field and moment keep the file's
units (tesla and A m^2 for "Hybrid SI").

:func:`forc_diagram` computes the FORC distribution
``rho(H_r, H) = -1/2 d^2 M / (dH_r dH)`` the way the rock-magnetism literature does (Pike,
Roberts and Verosub 1999; Harrison and Feinberg 2008): at each measured point a second-order
polynomial ``a1 + a2 H_r + a3 H_r^2 + a4 H + a5 H^2 + a6 H_r H`` is fitted by least squares to
the ``(2 SF + 1)^2`` points around it (SF the smoothing factor, in grid steps), and
``rho = -a6 / 2``.  Outside the measured band (``H < H_r``) there are no data and none are
invented: windows at the band's edge use only their measured points (at least
:data:`MIN_POINTS`, spread over three reversal fields and three fields, else rho is left
undefined), and rho is not drawn where ``H < H_r``.  The diagram is drawn in the usual
coordinates ``H_c = (H - H_r) / 2``, ``H_u = (H + H_r) / 2``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..forc import ForcMeasurement, read_forc
from .report import IdentificationReport

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .identifiers import Delay

__all__ = ["ForcDiagram", "forc_diagram", "forc_grid", "identify_forc"]

#: Fewest measured points a smoothing window needs for the local quadratic fit (6 unknowns).
MIN_POINTS = 9

Source = Union[str, "os.PathLike[str]", ForcMeasurement]


def _measurement(source: Source, drift: bool) -> ForcMeasurement:
    meas = source if isinstance(source, ForcMeasurement) else read_forc(source)
    return meas.drift_corrected() if drift else meas


def _units(meas: ForcMeasurement) -> tuple[str, str]:
    hybrid = str(meas.header.get("Units of measure", "")).lower().startswith("hybrid")
    return ("T", "A m^2") if hybrid else ("field", "moment")


def identify_forc(
    source: Source,
    *,
    method: str = "auto",
    levels: ArrayLike | int | None = None,
    drift: bool = True,
    name: str = "",
    project: bool = False,
    delay: Delay = 0,
    folds: int = 5,
    solver: str = "auto",
) -> IdentificationReport:
    """Identify a Preisach model from a FORC measurement (MicroMag file or ForcMeasurement).

    Parameters
    ----------
    source : path or ForcMeasurement
        The ``.forc`` file or the measurement read already.
    method : {"auto", "fod", "lsq"}
        ``"auto"``/``"fod"``: Mayergoyz on the mirrored curves (the FORCs are a complete
        reversal-curve sweep); ``"lsq"``: least squares on every sample of the measurement.
    levels : int or array_like, optional
        Grid: default the measured reversal fields plus the top field (so every measured point
        on a level is a node).
    drift : bool
        Scale each curve by its calibration point (:meth:`ForcMeasurement.drift_corrected`).
    name : str
        Model name.
    project : bool
        Project the table to Mp (fod).
    delay : int, float or "auto"
        Output delay in samples (a magnetometer answers at once: default 0).
    folds, solver
        Least squares (``method="lsq"``).

    Returns
    -------
    IdentificationReport
        In the file's units; ``choice`` says what was done.

    """
    from .auto import identify, mirror_recording

    if method not in ("auto", "fod", "lsq"):
        raise ValueError(f"method: expected 'auto', 'fod' or 'lsq' for FORC data, got {method!r}")
    raw = _measurement(source, False)
    meas = raw.drift_corrected() if drift else raw
    rec = meas.to_recording()
    if name:
        rec.metadata["experiment"] = name
    if levels is None and method != "lsq":
        levels = np.r_[np.sort(meas.reversal_fields), float(np.max(rec.u))]
    if method == "lsq":
        rep = identify(rec, "lsq", levels, delay=delay, name=name, folds=folds, solver=solver)
        rep.choice = "least squares on every sample of the FORC measurement (as asked)"
    else:
        lv = None if levels is None else np.asarray(levels, dtype=float)
        mirrored_levels = None if lv is None else (-lv[::-1] if lv.ndim else lv)
        rep = identify(
            mirror_recording(rec), "fod", mirrored_levels, delay=delay, name=name, project=project
        )
        from .auto import mirror_model

        model = mirror_model(rep.model)
        model.metadata["source"] = "identify_forc (Mayergoyz on the mirrored FORCs)"
        rep.model = model
        rep.fod = None
        n = model.levels.size
        rep.choice = (
            f"FORC measurement: {len(meas.curves)} reversal curves, "
            + ("drift-corrected from the calibration points, " if drift else "")
            + f"Mayergoyz on the mirrored curves (u -> -u, y -> -y) on {n} levels"
        )
    iu, ou = _units(meas)
    rep.input_units, rep.output_units = iu, ou
    if drift:
        d = raw.drift()
        rep.warnings.append(
            f"instrument drift: the calibration moment changed by {100 * d[-1]:+.2f} % over "
            "the run; each curve was scaled by its calibration point"
        )
    return rep


@dataclass
class ForcDiagram:
    """A FORC distribution on the measurement grid.

    Attributes
    ----------
    h_r : ndarray, shape (n_curves,)
        Reversal fields (field units), one per curve, increasing.
    h : ndarray, shape (n_fields,)
        Fields of the regular grid the curves were read on (field units).
    moment : ndarray, shape (n_curves, n_fields)
        The moment on the grid (NaN where ``h < h_r``: not measured).
    rho : ndarray, shape (n_curves, n_fields)
        ``-1/2 d^2 M / (dH_r dH)`` (moment units per field unit squared); NaN where undefined.
    smoothing_factor : int
        SF of the local polynomial regression.
    full_window : ndarray of bool, shape (n_curves, n_fields)
        Where the whole ``(2 SF + 1)^2`` window was measured (away from the band's edge, where
        one-sided windows make rho less certain).
    field_units, moment_units : str

    """

    h_r: NDArray[np.float64]
    h: NDArray[np.float64]
    moment: NDArray[np.float64]
    rho: NDArray[np.float64]
    smoothing_factor: int
    full_window: NDArray[np.bool_]
    field_units: str = "T"
    moment_units: str = "A m^2"

    @property
    def h_c(self) -> NDArray[np.float64]:
        """Coercive field ``(H - H_r) / 2`` at every grid point."""
        return np.asarray(0.5 * (self.h[None, :] - self.h_r[:, None]))

    @property
    def h_u(self) -> NDArray[np.float64]:
        """Interaction field ``(H + H_r) / 2`` at every grid point."""
        return np.asarray(0.5 * (self.h[None, :] + self.h_r[:, None]))

    def plot(self, *, ax: Axes | None = None, levels: int = 21) -> Figure:
        """Draw rho in (H_c, H_u) with filled contours (:func:`.plots.plot_forc_diagram`)."""
        from .plots import plot_forc_diagram

        return plot_forc_diagram(self, ax=ax, levels=levels)


def forc_grid(
    meas: ForcMeasurement,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Read the curves onto a regular grid: ``(h_r, h, M)``, curves sorted by reversal field.

    The field grid has the median field step of the curves and spans all of them; each curve
    is interpolated linearly onto it between its own first and last field (NaN outside).
    """
    curves = sorted(meas.curves, key=lambda c: float(c[0, 0]))
    steps = np.concatenate([np.diff(c[:, 0]) for c in curves if len(c) > 1])
    dh = float(np.median(steps[steps > 0]))
    lo = min(float(c[0, 0]) for c in curves)
    hi = max(float(c[-1, 0]) for c in curves)
    h = lo + dh * np.arange(int(np.floor((hi - lo) / dh + 1e-6)) + 1)
    M = np.full((len(curves), h.size), np.nan)
    for k, c in enumerate(curves):
        inside = (h >= c[0, 0] - 1e-9 * dh) & (h <= c[-1, 0] + 1e-9 * dh)
        M[k, inside] = np.interp(h[inside], c[:, 0], c[:, 1])
    h_r = np.array([float(c[0, 0]) for c in curves], dtype=np.float64)
    return h_r, np.asarray(h, dtype=np.float64), np.asarray(M, dtype=np.float64)


def forc_diagram(source: Source, smoothing_factor: int = 3, *, drift: bool = True) -> ForcDiagram:
    """Compute the FORC distribution by local second-order polynomial regression (module docstring).

    Parameters
    ----------
    source : path or ForcMeasurement
        The measurement.
    smoothing_factor : int
        SF >= 1: the fit window is ``(2 SF + 1)`` reversal fields by ``(2 SF + 1)`` fields.
    drift : bool
        Correct the drift from the calibration points first.

    Returns
    -------
    ForcDiagram

    """
    from scipy.ndimage import correlate

    if isinstance(smoothing_factor, bool) or int(smoothing_factor) != smoothing_factor:
        raise ValueError(f"smoothing_factor: need an integer >= 1, got {smoothing_factor!r}")
    sf = int(smoothing_factor)
    if sf < 1:
        raise ValueError(f"smoothing_factor: need an integer >= 1, got {smoothing_factor!r}")
    meas = _measurement(source, drift)
    h_r, h, M = forc_grid(meas)
    dhr = float(np.median(np.diff(h_r)))
    dh = float(h[1] - h[0])
    mask = np.isfinite(M).astype(float)
    Mz = np.where(np.isfinite(M), M, 0.0)
    off = np.arange(-sf, sf + 1, dtype=float)
    X, Y = np.meshgrid(off, off, indexing="ij")  # X along h_r (rows), Y along h
    basis = [np.ones_like(X), X, X * X, Y, Y * Y, X * Y]
    nb = len(basis)
    A = np.empty(M.shape + (nb, nb))
    b = np.empty(M.shape + (nb,))
    for i in range(nb):
        b[..., i] = correlate(Mz, basis[i], mode="constant", cval=0.0)
        for j in range(i, nb):
            A[..., i, j] = A[..., j, i] = correlate(
                mask, basis[i] * basis[j], mode="constant", cval=0.0
            )
    count = A[..., 0, 0]
    # the window needs MIN_POINTS points over >= 3 reversal fields and >= 3 fields
    rows = correlate(
        (correlate(mask, np.ones((1, 2 * sf + 1)), mode="constant") > 0).astype(float),
        np.ones((2 * sf + 1, 1)),
        mode="constant",
    )
    cols = correlate(
        (correlate(mask, np.ones((2 * sf + 1, 1)), mode="constant") > 0).astype(float),
        np.ones((1, 2 * sf + 1)),
        mode="constant",
    )
    ok = (mask > 0) & (count >= MIN_POINTS) & (rows >= 3) & (cols >= 3)
    rho = np.full(M.shape, np.nan)
    idx = np.nonzero(ok)
    Ak, bk = A[idx], b[idx]
    cond_ok = np.linalg.cond(Ak) < 1e10
    coef = np.full((Ak.shape[0], nb), np.nan)
    coef[cond_ok] = np.linalg.solve(Ak[cond_ok], bk[cond_ok][..., None])[..., 0]
    rho[idx] = -0.5 * coef[:, 5] / (dhr * dh)
    fu, mu = _units(meas)
    return ForcDiagram(
        h_r=h_r,
        h=h,
        moment=M,
        rho=rho,
        smoothing_factor=sf,
        full_window=np.asarray(ok & (count >= (2 * sf + 1) ** 2 - 0.5)),
        field_units=fu,
        moment_units=mu,
    )
