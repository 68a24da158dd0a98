"""The three identifiers of :mod:`preisach.identify`, each returning a model and a report.

* :func:`identify_fod` - Mayergoyz: FOD grid -> Everett table ``E = (y(a, a) - y(a, b)) / 2``
  (C++), gaps filled by a documented rule, optional projection to ``mu >= 0``;
* :func:`identify_surface` - the thesis's square-root FOD surface (section 3.3.2, Eq 3.2),
  tabulated on a fine grid;
* :func:`identify_lsq` - least squares on every sample of arbitrary recordings, ``mu >= 0`` and a
  smoothness penalty chosen by cross-validation (:mod:`preisach.identify.lsq`).

All three accept :class:`~preisach.Recording` objects (anything with ``t``, ``u``, ``y`` in s, V,
V); the first two also accept :class:`~preisach.identify.FODData` (the FOD curves already
found).  Each returns an :class:`~preisach.identify.IdentificationReport` (``report.model`` is
the model; it unpacks as ``model, report``); the report lists the data used, the residuals (max
and RMS in the recording's output units and in percent of the output range), warnings, and the
method's own details (FOD coverage, surface parameters, projection, cross-validation curve).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Callable, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _core
from ..initial_state import InitialState, check_policy
from ..model import PreisachModel
from ..recording import (
    Recording,
    RecordingsInput,
    SampledData,
    as_recordings,
    recording_labels,
)
from .delay import DelayEstimate, estimate_delay, shift_output
from .fod_finder import FODData, find_fod_curves
from .lsq import LsqDetails, identify_lsq_core, weights_matrix
from .report import DataUsage, IdentificationReport, ProjectionSummary, Residuals
from .surface_fit import SurfaceFitResult, fit_sqrt_surface

__all__ = [
    "DataUsage",
    "IdentificationReport",
    "ProjectionSummary",
    "Residuals",
    "identify_fod",
    "identify_lsq",
    "identify_surface",
    "project_nonnegative",
    "weight_density",
]

#: What the FOD identifiers take: recordings (anything :func:`~preisach.recording.as_recordings`
#: accepts) or FOD curves found already.
Data = Union[FODData, RecordingsInput]
#: An output delay in samples, or ``"auto"``/``None`` to estimate it.
Delay = Union[int, float, str, None]
#: Options passed on to :func:`~preisach.identify.find_fod_curves` (``u_min``, ``u_max``,
#: ``saturation_tol``, ``reversal_tol``, ``level_tol``; V).
FinderOption = Union[float, None]


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def _recordings(data: RecordingsInput) -> list[Recording]:
    """Return the recordings given (paths, Recordings, t/u/y objects) by the package rule."""
    return as_recordings(data)


def _unique_names(recs: Sequence[Recording]) -> list[str]:
    """Return the recordings' labels by the package rule (repeated labels numbered)."""
    return recording_labels(recs)


def _check_lengths(recs: Sequence[Recording], names: Sequence[str]) -> None:
    """Raise ValueError naming the first recording with fewer than 2 samples."""
    for nm, r in zip(names, recs):
        n = int(np.size(r.u))
        if n < 2:
            raise ValueError(f"{nm}: a recording needs at least 2 samples, got {n}")


#: Most levels of an FOD grid given to :func:`identify_fod` / :func:`identify_surface`: the
#: resolution of the built-in models (1 V steps on +-100 V).  The grid's cost grows as
#: levels^2 (401 levels: ~10 s and 540 MB; 1000 levels ran for minutes).
MAX_FOD_LEVELS = 201


def _levels_arg(levels: ArrayLike | int | None, lo: float, hi: float) -> NDArray[np.float64] | None:
    if levels is None:
        return None
    if np.ndim(levels) == 0:
        n = int(np.asarray(levels))
        if n < 2:
            raise ValueError(f"levels: need at least 2 levels, got {n}")
        return np.linspace(lo, hi, n)
    lv = np.asarray(levels, dtype=float)
    if lv.ndim != 1 or lv.size < 2 or not np.all(np.isfinite(lv)) or np.any(np.diff(lv) <= 0):
        raise ValueError("levels: need a finite, strictly increasing 1-D array of >= 2 levels (V)")
    return lv


def _merge_fod(parts: list[FODData]) -> FODData:
    """Count-weighted merge of FOD grids on the same levels (pooled spread)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    cnt = np.zeros_like(first.count)
    s1 = np.zeros_like(first.y_grid)
    s2 = np.zeros_like(first.y_grid)
    for p in parts:
        c = p.count.astype(float)
        m = np.where(p.count > 0, p.y_grid, 0.0)
        sd = np.where(p.count >= 2, p.spread, 0.0)
        cnt += p.count
        s1 += c * m
        s2 += (c - 1).clip(min=0) * sd * sd + c * m * m
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, s1 / np.maximum(cnt, 1), np.nan)
        var = np.where(cnt >= 2, (s2 - cnt * mean * mean) / np.maximum(cnt - 1, 1), np.nan)
    spread = np.sqrt(np.clip(var, 0.0, None))
    curves = [c for p in parts for c in p.curves]
    return FODData(
        levels=first.levels,
        y_grid=mean,
        count=cnt.astype(np.int64),
        spread=spread,
        curves=curves,
        direction=first.direction,
        u_min=min(p.u_min for p in parts),
        u_max=max(p.u_max for p in parts),
        saturation_tol=first.saturation_tol,
        reversal_tol=first.reversal_tol,
        level_tol=first.level_tol,
        levels_source=first.levels_source + f" (merged over {len(parts)} recordings)",
        n_samples=sum(p.n_samples for p in parts),
        input_noise=max(p.input_noise for p in parts),
    )


def _fod_data(
    data: Data, levels: ArrayLike | int | None, finder_options: dict[str, FinderOption]
) -> tuple[FODData, list[Recording], list[str], list[DataUsage]]:
    if isinstance(data, FODData):
        if levels is not None:
            raise ValueError(
                "levels: not used with FODData (its levels are fixed); find the "
                "curves again with find_fod_curves(..., levels=...)"
            )
        if data.direction != "descending":
            raise ValueError(
                "FODData: the Mayergoyz identifiers need first-order descending "
                "curves (find_fod_curves), got first-order reversal curves"
            )
        n_used = sum(c.stop - c.turn + 1 for c in data.used_curves)
        only = [
            DataUsage(
                name="FOD data",
                n_samples=data.n_samples,
                n_used=n_used,
                note=f"{len(data.used_curves)} FOD curves used, "
                f"{len(data.rejected_curves)} rejected",
            )
        ]
        return data, [], [], only
    recs = _recordings(data)
    names = _unique_names(recs)
    _check_lengths(recs, names)
    lo = min(float(np.min(r.u)) for r in recs)
    hi = max(float(np.max(r.u)) for r in recs)
    lv = _levels_arg(levels, lo, hi)
    if lv is not None and lv.size > MAX_FOD_LEVELS:
        raise ValueError(
            f"levels: at most {MAX_FOD_LEVELS} levels for an FOD grid (identify_fod, "
            "identify_surface; the built-in models' resolution - the grid's cost grows as "
            f"levels^2), got {lv.size}"
        )
    parts: list[FODData] = []
    usage: list[DataUsage] = []
    for name, rec in zip(names, recs):
        opts = dict(finder_options)
        opts.setdefault("u_min", lo)
        opts.setdefault("u_max", hi)
        fd = find_fod_curves(rec, levels=lv, **opts)
        if lv is None:
            lv = fd.levels  # every later recording on the first one's grid
        parts.append(fd)
        used = fd.used_curves
        usage.append(
            DataUsage(
                name=name,
                n_samples=fd.n_samples,
                n_used=sum(c.stop - c.turn + 1 for c in used),
                note=f"{len(used)} FOD curves used, {len(fd.rejected_curves)} rejected",
            )
        )
    merged = _merge_fod(parts)
    if not merged.used_curves:
        reasons = "; ".join(sorted({c.reason for c in merged.curves}))[:500]
        raise ValueError(
            "no usable first-order descending curve was found in the recordings"
            + (f" ({reasons})" if reasons else "")
        )
    return merged, recs, names, usage


def _fod_warnings(fd: FODData) -> list[str]:
    out = []
    rej = [c for c in fd.curves if not c.used]
    off = [c for c in rej if c.first_order]
    if off:
        out.append(
            f"{len(off)} first-order curves turned between grid levels and were not used "
            "(see fod.report())"
        )
    n = fd.levels.size
    missing = n * (n + 1) // 2 - int(np.count_nonzero(np.tril(fd.count)))
    if missing:
        out.append(f"{missing} of {n * (n + 1) // 2} FOD nodes were not measured")
    return out


def _node_residuals(model: PreisachModel, fd: FODData, output_range: float) -> Residuals:
    """Model FOD outputs y = y_min + 2 E(a, u_min) - 2 E(a, b) against the measured nodes."""
    a, b = np.meshgrid(fd.levels, fd.levels, indexing="ij")
    mask = (fd.count > 0) & (b <= a)
    aa, bb = a[mask], b[mask]
    y = (
        model.y_min
        + 2.0 * model.everett(aa, np.full_like(aa, model.u_min))
        - 2.0 * model.everett(aa, bb)
    )
    return Residuals.of("FOD nodes", y - fd.y_grid[mask], output_range)


def _recording_residuals(
    model: PreisachModel,
    recs: Sequence[Recording],
    names: Sequence[str],
    initial_state: InitialState,
    delay: int,
    state_warnings: bool = True,
) -> tuple[list[Residuals], list[str]]:
    """Residuals of the model on the recordings, and warnings (inexact state, clamped input)."""
    from ..verify import verify

    if not recs:
        return [], []
    table = verify(
        model,
        recs,
        initial_state=initial_state,
        delay=delay,
        names=names,
        warn_out_of_range=False,
    )
    res = [
        Residuals(
            name=r.experiment,
            n=r.n_samples,
            max_error=r.max_error,
            rms_error=r.rms_error,
            output_range=r.output_range,
        )
        for r in table.rows
    ]
    warn = [
        f"{r.experiment}: the model's state is not exact on this recording (it never reaches "
        f"u_min or u_max); its residuals include an unknown constant offset"
        for r in table.rows
        if state_warnings and not r.exact_state
    ]
    warn += [
        f"{r.experiment}: {r.n_out_of_range} input samples lie outside the model's input "
        f"range [{model.u_min:g}, {model.u_max:g}] V; the residuals there are those of the "
        "clamped input"
        for r in table.rows
        if r.n_out_of_range
    ]
    return res, warn


#: How an FOD sweep's output delay is scored (:func:`fod_delay_score`), for the reports.
FOD_DELAY_SCORE = "the RMS residual of the Mayergoyz model on its own recordings"


def fod_delay_score(
    levels: ArrayLike | int | None,
    initial_state: InitialState,
    finder_options: dict[str, FinderOption] | None = None,
    prepare: Callable[[list[SampledData]], Sequence[SampledData]] | None = None,
) -> Callable[[list[SampledData]], float]:
    """Return the error of an output delay for FOD recordings: the Mayergoyz model's residual.

    The model is read off the FOD nodes of the recordings shifted by the delay (and passed
    through ``prepare``, e.g. mirrored) and simulated on them; the samples between the nodes
    are not fitted, and a delay that pairs the output with the wrong input leaves them off the
    model's branches.  The default least-squares score (a 21-level grid cross-validated over
    time blocks) is blurred by that grid's own resolution error on steep loops: on a
    delay-free blind test device (seed 11, case 008, Gaussian density) its error fell from
    0.40 V at delay 0 to 0.21 V at 6 samples, and the 6-sample model left 181 mV on its own
    sweep against 32 mV at delay 0.
    """
    opts: dict[str, Any] = dict(finder_options or {})

    def score(recs: list[SampledData]) -> float:
        data = prepare(recs) if prepare is not None else list(recs)
        # bilinear, as the 25 % margin was measured with (a cubic model follows a delay-free
        # sweep more closely, so its relative gains from a shift differ)
        rep = identify_fod(
            data,
            levels,
            gaps="fill",
            initial_state=initial_state,
            delay=0,
            interpolation="bilinear",
            **opts,
        )
        n = np.array([r.n for r in rep.residuals], float)
        rms = np.array([r.rms_error for r in rep.residuals], float)
        return float(np.sqrt(np.sum(n * rms**2) / max(float(np.sum(n)), 1.0)))

    return score


def _resolve_delay(
    data: Data,
    delay: Delay,
    initial_state: InitialState,
    levels: ArrayLike | int | None,
    finder_options: dict[str, FinderOption],
) -> tuple[FODData | list[Recording], float, DelayEstimate | None]:
    """Apply (or estimate, for ``None``/``"auto"``) the output delay to FOD identifiers' data.

    FOD data take no delay (their curves are found already); recordings go through
    :func:`_delay_recordings`, an estimate scored by :func:`fod_delay_score`.  Returns
    ``(data, delay, estimate)``.
    """
    if isinstance(data, FODData):
        if delay not in (None, "auto", 0):
            raise ValueError("delay: not used with FODData (its curves are found already)")
        return data, 0.0, None
    score = fod_delay_score(levels, initial_state, finder_options)
    recs, d, est, _ = _delay_recordings(
        _recordings(data), delay, initial_state, False, score, FOD_DELAY_SCORE
    )
    return recs, d, est


def _delay_recordings(
    recs: list[Recording],
    delay: Delay,
    initial_state: InitialState,
    integer_native: bool = False,
    score: Callable[[list[SampledData]], float] | None = None,
    score_name: str = "",
) -> tuple[list[Recording], float, DelayEstimate | None, float]:
    """Apply (or estimate, for ``None``/``"auto"``) the output delay; see :mod:`.delay`.

    Returns ``(recordings, delay, estimate, native)``: the recordings with the delay applied by
    :func:`shift_output` (unchanged when it is 0, or when ``integer_native`` and it is an
    integer - the caller then applies ``native`` itself), the delay (samples), how it was
    estimated, and the delay left for the caller.  ``score``, ``score_name``: how an estimate
    scores each delay (:func:`~preisach.identify.delay.estimate_delay`).
    """
    names = _unique_names(recs)
    _check_lengths(recs, names)
    est = None
    if delay is None or delay == "auto":
        est = estimate_delay(
            recs, initial_state=initial_state, names=names, score=score, score_name=score_name
        )
        d = est.delay
    elif isinstance(delay, str) or isinstance(delay, bool):
        raise ValueError(f"delay: expected a number of samples >= 0 or 'auto', got {delay!r}")
    else:
        d = float(delay)
        if not (math.isfinite(d) and d >= 0.0):
            raise ValueError(f"delay: need a number of samples >= 0, got {delay!r}")
    if d == 0.0:
        return recs, 0.0, est, 0.0
    if integer_native and d == int(d):
        return recs, d, est, d
    return [shift_output(r, d) for r in recs], d, est, 0.0


def _units(recs: Sequence[Recording]) -> dict[str, str]:
    """``input_units`` and ``output_units`` of the recordings (``"V"`` when not stated)."""
    out = {}
    for key in ("input_units", "output_units"):
        found = {str((getattr(r, "metadata", None) or {}).get(key, "V")) or "V" for r in recs}
        out[key] = " / ".join(sorted(found)) or "V"
    return out


def _negative_cells(model: PreisachModel) -> int:
    """Cells with negative mass, beyond round-off (1e-12 of the total absolute mass)."""
    w = np.tril(model.cell_weights())
    return int(np.count_nonzero(w < -1e-12 * float(np.abs(w).sum())))


def _output_range(fd: FODData, recs: Sequence[Recording]) -> float:
    if recs:
        return max(float(np.ptp(r.y)) for r in recs)
    y = fd.y_grid[np.isfinite(fd.y_grid)]
    return float(np.ptp(y)) if y.size else 1.0


@dataclass
class _Source:
    """The data an identifier fitted: recordings (delay applied), their labels and usage.

    ``native_delay``: samples the residuals pair the output later (least squares applies an
    integer delay itself; the FOD identifiers' recordings are shifted already).
    """

    recs: list[Recording]
    names: list[str]
    usage: list[DataUsage]
    initial_state: InitialState
    delay: float
    estimate: DelayEstimate | None
    native_delay: int = 0


def _fod_source(
    data: Data,
    levels: ArrayLike | int | None,
    delay: Delay,
    initial_state: InitialState,
    finder_options: dict[str, FinderOption],
) -> tuple[FODData, _Source]:
    """Prepare the FOD identifiers' data: delay applied, FOD curves found and merged."""
    check_policy(initial_state)
    shifted, delay_used, estimate = _resolve_delay(
        data, delay, initial_state, levels, finder_options
    )
    fd, recs, names, usage = _fod_data(shifted, levels, finder_options)
    return fd, _Source(recs, names, usage, initial_state, delay_used, estimate)


def _report(
    method: str,
    model: PreisachModel,
    src: _Source,
    warnings: list[str],
    t0: float,
    *,
    fod: FODData | None = None,
    surface_fit: SurfaceFitResult | None = None,
    projection: ProjectionSummary | None = None,
    lsq: LsqDetails | None = None,
) -> IdentificationReport:
    """Score the model and assemble the report every identifier returns.

    The residuals on the recordings, at the FOD nodes when ``fod`` is given, the negative
    cells, the units, and the wall time since ``t0``.
    """
    recs = src.recs
    node_res = None
    if fod is not None:
        node_res = _node_residuals(model, fod, _output_range(fod, recs))
    # lsq reports the inexact-state recordings itself (usage notes)
    res, w_res = _recording_residuals(
        model, recs, src.names, src.initial_state, src.native_delay, state_warnings=lsq is None
    )
    units = _units(recs)
    return IdentificationReport(
        method=method,
        model=model,
        data=src.usage,
        residuals=res,
        node_residuals=node_res,
        warnings=warnings + w_res,
        fod=fod,
        surface_fit=surface_fit,
        projection=projection,
        lsq=lsq,
        negative_cells=_negative_cells(model),
        elapsed=time.perf_counter() - t0,
        input_units=units["input_units"],
        output_units=units["output_units"],
        delay=src.delay,
        delay_estimate=src.estimate,
    )


# ------------------------------------------------------------------------------------------
# public functions
# ------------------------------------------------------------------------------------------
def weight_density(model: PreisachModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Split a model's weight as in thesis Eq 2.12-2.14: density ``v`` and ``kappa``.

    Parameters
    ----------
    model : PreisachModel
        The model (its cell masses are the mixed second differences of its Everett table).

    Returns
    -------
    v : ndarray, shape (n-1, n-1)
        Density (V/V^2) of the off-diagonal cells: ``v[i, j]`` is the mass of
        ``[levels[i], levels[i+1]] x [levels[j], levels[j+1]]`` divided by its area, ``j < i``;
        NaN on and above the diagonal.
    kappa : ndarray, shape (n-1,)
        ``kappa[i]`` (V/V): the mass of the diagonal half-cell ``i`` divided by its width - half
        the initial slope dy/dbeta of the FOD curves there (Eq 2.14).  It includes the
        half-cell's share of ``v`` (O(h) smaller).

    """
    v, kappa = _core.weight_density(model.table)
    return np.asarray(v), np.asarray(kappa)


def project_nonnegative(
    model: PreisachModel, *, keep_y_max: bool = True, tol: float = 1e-12
) -> tuple[PreisachModel, ProjectionSummary]:
    """Project a model to the nearest one in Mp (all cell masses >= 0), in least squares.

    ``minimise sum (E'(i, j) - E(i, j))^2`` over the nodes ``j < i`` subject to every cell mass
    ``w' >= 0``, with ``y_min`` kept and, when ``keep_y_max`` and possible (``E(u_max, u_min) >=
    0``), ``y_max = y(u_max, u_max)`` kept too.  Least squares in ``E`` because every model
    output is a signed sum of Everett values: outputs move by at most twice the largest node
    change, and a negative cell is absorbed by its neighbours.  Solved in C++ by Hildreth's
    method; masses left within ``tol`` (relative to the total mass) of zero are set to zero, so
    ``y_max`` is kept to within about ``tol`` times the total mass, and the cell masses of the
    result are >= 0 up to round-off.

    Parameters
    ----------
    model : PreisachModel
        The model to project.
    keep_y_max : bool
        Keep ``y_max`` (the corner node) fixed.
    tol : float
        Relative tolerance of the projection.

    Returns
    -------
    model : PreisachModel
        The projected model (the input model when it is already in Mp).
    summary : ProjectionSummary
        Cells that were negative, mass moved (absolute and as a fraction of the total), node
        changes, what was kept.

    """
    r = _core.project_nonnegative(model.table, keep_y_max, float(tol))
    meta = dict(model.metadata)
    meta["projected"] = True
    out = PreisachModel(r.table, name=model.name, metadata=meta, out_of_range=model.out_of_range)
    return out, ProjectionSummary.of(r)


#: How much lower (relative) the cubic model's RMS residual on the FOD recordings must be for
#: ``interpolation="auto"`` to choose it over the bilinear one.
CUBIC_MARGIN = 0.10


def _choose_interpolation(
    model: PreisachModel, src: _Source, interpolation: str
) -> tuple[PreisachModel, dict[str, Any]]:
    """Apply ``interpolation`` to the Mayergoyz model; ``"auto"`` scores both on the sweep.

    The nodes are the FOD readings at the turning points; every other sample of the sweep
    is predicted, not fitted, so the RMS residual there tells which interpolant between the
    nodes the device follows.  Returns the model and the choice with both residuals.
    """
    if interpolation not in ("auto", "bilinear", "cubic"):
        raise ValueError(
            f"interpolation: expected 'auto', 'bilinear' or 'cubic', got {interpolation!r}"
        )
    if model.levels.size < 4:  # the cubic interpolant needs a 4 x 4 stencil
        if interpolation == "cubic":
            raise ValueError(
                f"interpolation: 'cubic' needs at least 4 FOD levels, got {model.levels.size}"
            )
        return model, {"interpolation": "bilinear", "chosen_by": "fewer than 4 levels"}
    if interpolation != "auto":
        return model.with_interpolation(interpolation), {
            "interpolation": interpolation,
            "chosen_by": "given",
        }
    cubic = model.with_interpolation("cubic")
    rms = {}
    for kind, m in (("bilinear", model), ("cubic", cubic)):
        res, _ = _recording_residuals(
            m, src.recs, src.names, src.initial_state, src.native_delay, state_warnings=False
        )
        n = np.array([r.n for r in res], float)
        e = np.array([r.rms_error for r in res], float)
        rms[kind] = float(np.sqrt(np.sum(n * e**2) / np.sum(n))) if n.sum() else float("nan")
    pick = "cubic" if rms["cubic"] <= (1.0 - CUBIC_MARGIN) * rms["bilinear"] else "bilinear"
    return (cubic if pick == "cubic" else model), {
        "interpolation": pick,
        "chosen_by": "RMS residual on the FOD recordings "
        f"(cubic needs {100 * CUBIC_MARGIN:.0f} % less)",
        "rms_bilinear": rms["bilinear"],
        "rms_cubic": rms["cubic"],
        "margin": CUBIC_MARGIN,
    }


def identify_fod(
    data: Data,
    levels: ArrayLike | int | None = None,
    *,
    project: bool = False,
    gaps: str = "fill",
    name: str = "",
    initial_state: InitialState = "burn-in",
    delay: Delay = 0,
    interpolation: str = "auto",
    **finder_options: FinderOption,
) -> IdentificationReport:
    """Mayergoyz identification: FOD curves -> Everett table (thesis §2.6, Eq 2.12-2.14).

    Parameters
    ----------
    data : Recording, sequence of Recording, or FODData
        Recordings holding FOD curves (e.g. the FOD sweep of Fig 3.17), or FOD data found
        already.  Several recordings are merged node by node (count-weighted means).
    levels : int or array_like, optional
        FOD grid: a number of equally spaced levels over the recordings' input range, or the
        levels (V); at most :data:`MAX_FOD_LEVELS` (201).  Default: inferred from the turning
        values (see :func:`~preisach.identify.find_fod_curves`).
    project : bool
        Project the table to the nearest one with all cell masses >= 0
        (:func:`project_nonnegative`); the report gives the mass moved.
    gaps : {"fill", "raise"}
        Nodes the FOD curves did not reach: fill them (a missing end point ``y(a, u_min)`` with
        ``y_min``; every other node by the smoothest density, see ``mayergoyz`` in
        ``cpp/include/preisach/identify.hpp``) or raise :class:`ValueError` naming the node.
    name : str
        Name of the model.
    initial_state : str or State
        Policy for the residuals on the recordings (see :func:`preisach.verify.verify`).
    delay : int, float, "auto" or None
        Output delay (samples): ``y(k + delay)`` answers ``u(k)``.  The recordings are shifted
        by it (:func:`~preisach.identify.delay.shift_output`; fractional delays interpolate the
        input) before the FOD curves are found, and the residuals are those of the shifted
        recordings (default 0).  ``None``/``"auto"``: whole samples scored by this model's own
        residual on the shifted recordings (:func:`fod_delay_score`; a nonzero delay must
        lower it by 25 %, :data:`~preisach.identify.delay.SCORE_MARGIN`; the default of
        :func:`~preisach.identify.identify` and ``preisach identify``); the report gives it.
    interpolation : {"auto", "bilinear", "cubic"}
        How the model interpolates its table between the FOD nodes
        (:attr:`PreisachModel.interpolation`).  ``"auto"`` (default) takes the cubic one when
        its RMS residual on the recordings (the samples between the nodes, which are not
        fitted) is at least :data:`CUBIC_MARGIN` (10 %) lower than the bilinear one's: a
        smooth density read on the 21-level grid is followed far more closely by it (on the
        seed-12 blind devices the given model's residual on the experiments fell from
        12-70 mV to 4-40 mV), a device that is piecewise linear between the nodes is not.
        ``report.model.metadata["interpolation"]`` records the choice and both residuals.
    **finder_options
        Passed to :func:`~preisach.identify.find_fod_curves` (``saturation_tol``,
        ``reversal_tol``, ``level_tol``, ``u_min``, ``u_max``).

    Returns
    -------
    IdentificationReport
        ``report.model`` on the FOD levels (``y_min`` is the mean measured FOD end point);
        unpacks as ``model, report``.

    """
    t0 = time.perf_counter()
    if gaps not in ("fill", "raise"):
        raise ValueError(f"gaps: expected 'fill' or 'raise', got {gaps!r}")
    fd, src = _fod_source(data, levels, delay, initial_state, finder_options)
    table, filled, n_col0, n_ymin, rows = _core.mayergoyz(fd.levels, fd.y_grid, gaps)
    warnings = _fod_warnings(fd)
    if len(filled):
        warnings.append(
            f"{len(filled)} Everett nodes were filled ({n_col0} FOD end points set to "
            f"y_min, {len(filled) - n_col0} by the smoothest density)"
        )
        n_nodes = fd.levels.size * (fd.levels.size - 1) // 2
        if len(filled) > n_nodes // 2:
            warnings.append(
                f"most of the table ({len(filled)} of {n_nodes} nodes) is extrapolated, "
                "not measured: these recordings hold few FOD curves; identify_lsq "
                "uses every sample of any excitation"
            )
    if len(rows):
        warnings.append(
            f"FOD curves without a turning point reading (alpha = "
            f"{', '.join(f'{fd.levels[i]:.6g}' for i in rows)} V): their readings were "
            "not used"
        )
    meta: dict[str, Any] = {
        "source": "identify_fod",
        "n_ymin": int(n_ymin),
        "filled_nodes": int(len(filled)),
    }
    model = PreisachModel(table, name=name, metadata=meta)
    proj = None
    if project:
        model, proj = project_nonnegative(model)
        model.metadata["source"] = "identify_fod"
    neg = _negative_cells(model)
    if neg and not project:
        w = np.tril(model.cell_weights())
        warnings.append(
            f"{neg} cells have negative mass (sum {float(w[w < 0].sum()):.4g} "
            f"{_units(src.recs)['output_units']}): the "
            "model is not in Mp; project=True gives the nearest model that is"
        )
    model, choice = _choose_interpolation(model, src, interpolation)
    model.metadata["interpolation"] = choice
    model.metadata["delay"] = src.delay
    return _report("fod", model, src, warnings, t0, fod=fd, projection=proj)


def identify_surface(
    data: Data,
    levels: ArrayLike | int | None = None,
    *,
    table_levels: ArrayLike | int = 201,
    frequency: float = math.nan,
    refine: bool = True,
    y_min_source: str = "column_mean",
    name: str = "",
    initial_state: InitialState = "burn-in",
    delay: Delay = 0,
    **finder_options: FinderOption,
) -> IdentificationReport:
    """Square-root FOD surface identification (thesis §3.3.2, Eq 3.1-3.2), tabulated.

    The FOD grid is found as for :func:`identify_fod`, fitted by
    :func:`~preisach.identify.fit_sqrt_surface` (per-curve Nelder-Mead fits, quadratic
    polynomials in alpha, the constrained surface of Eq 3.2, and a joint least-squares
    refinement), and the surface is tabulated on ``table_levels``.

    Parameters
    ----------
    data : Recording, sequence of Recording, or FODData
        As for :func:`identify_fod`.
    levels : int or array_like, optional
        FOD grid (as for :func:`identify_fod`).
    table_levels : int or array_like
        Grid on which the surface is tabulated (default 201 levels over the FOD range).
    frequency : float
        Frequency (Hz) of the identification input, stored in the surface.
    refine : bool
        Run the joint refinement of the surface parameters (beyond the thesis).
    y_min_source : {"column_mean", "corner"}
        Where the surface's ``y_min`` (V) comes from.  ``"corner"`` is Eq 3.1 as the thesis
        states it: the single measured corner ``y(u_hat, -u_hat)``.  ``"column_mean"``
        (default) averages the end points ``y(alpha, u_min)`` of every measured FOD curve,
        which all measure the same output (every FOD curve ends at negative saturation), so
        the noise on ``y_min`` drops by about ``sqrt(n)`` for ``n`` curves.  See
        :func:`~preisach.identify.fit_sqrt_surface`.
    name, initial_state, delay, **finder_options
        As for :func:`identify_fod`.

    Returns
    -------
    IdentificationReport
        ``report.model``; ``surface_fit`` holds the Table 3.1-style parameters and fit errors.
        Unpacks as ``model, report``.

    """
    t0 = time.perf_counter()
    check_policy(initial_state)
    if y_min_source not in ("column_mean", "corner"):
        raise ValueError(f"y_min_source: expected 'column_mean' or 'corner', got {y_min_source!r}")
    fd, src = _fod_source(data, levels, delay, initial_state, finder_options)
    fit = fit_sqrt_surface(
        fd.levels, fd.y_grid, frequency=frequency, refine=refine, y_min_source=y_min_source
    )
    model = PreisachModel.from_surface(fit.surface, table_levels, name=name)
    model.metadata["source"] = "identify_surface"
    model.metadata["y_min_source"] = y_min_source
    warnings = _fod_warnings(fd) + [f"surface fit: {w}" for w in fit.warnings]
    neg = _negative_cells(model)
    if neg:
        warnings.append(
            f"{neg} cells of the tabulated surface have negative mass (the thesis "
            "reports such cells for its 2 and 4 Hz surfaces)"
        )
    model.metadata["delay"] = src.delay
    return _report("surface", model, src, warnings, t0, fod=fd, surface_fit=fit)


def identify_lsq(
    recordings: RecordingsInput,
    levels: ArrayLike | int = 41,
    *,
    lambdas: str | Sequence[float] = "auto",
    folds: int = 5,
    initial_state: InitialState = "burn-in",
    delay: Delay = 0,
    nonnegative: bool = True,
    u_range: tuple[float, float] | None = None,
    name: str = "",
    progress: bool = True,
    solver: str = "auto",
) -> IdentificationReport:
    """Least-squares identification of the Everett table from arbitrary recordings.

    Every sample is used: the model output is linear in the table, so the cell masses ``w``
    (``mu >= 0`` is ``w >= 0``) and ``y_min`` are fitted by penalised least squares with a
    smoothness penalty whose weight is chosen by K-fold cross-validation over contiguous time
    blocks.  See :mod:`preisach.identify.lsq` for the formulation and the initial-state policy.

    Parameters
    ----------
    recordings : Recording, path, object with t/u/y, or a sequence of them
        Any excitation (sines, noise, minor loops, FOD sweeps), as
        :func:`~preisach.recording.as_recordings` accepts it (``t``, ``u``, ``y`` in s, V, V).
    levels : int or array_like
        Table grid: a number of equally spaced levels over ``u_range`` (default 41), or the
        levels (V); at most 401.
    lambdas : "auto" or sequence of float
        Smoothness weights to try (dimensionless).  ``"auto"``: ``1e-8, 1e-6, ..., 1e2`` and
        then the decades on either side of the best of those (8 values).
    folds : int
        Number of contiguous time blocks for cross-validation (>= 2).
    initial_state : {"burn-in", "negative", "positive", "anhysteretic"} or State
        Initial-state policy (default: discard each recording's burn-in).
    delay : int, float, "auto" or None
        Output delay in samples: ``y[k + delay]`` answers ``u[k]``.  An integer is applied by
        pairing the samples; a fractional one by shifting the recordings
        (:func:`~preisach.identify.delay.shift_output`); default 0.  ``None``/``"auto"``:
        estimated by cross-validation (:func:`~preisach.identify.delay.estimate_delay`; the
        default of :func:`~preisach.identify.identify` and ``preisach identify``).
    nonnegative : bool
        Impose ``mu >= 0`` (all cell masses >= 0).
    u_range : (float, float), optional
        Input range (V) of the table; default the recordings' input range.
    name : str
        Name of the model.
    progress : bool
        Show a progress bar over the cross-validation fits (``False``: nothing).
    solver : {"auto", "dense", "sparse"}
        ``"dense"``: the cell masses by exact non-negative least squares on dense normal
        equations (at most 81 levels; cubic cost).  ``"sparse"``: the Everett nodes by
        conjugate gradients on sparse normal equations (:mod:`preisach.identify.lsq_sparse`),
        then the projection to Mp when ``nonnegative`` (its moved mass is in
        ``report.projection``).  ``"auto"`` (default): dense up to 41 levels, sparse beyond.

    Returns
    -------
    IdentificationReport
        ``report.model``; ``lsq`` holds the cross-validation curve and the chosen lambda.
        Unpacks as ``model, report``.

    """
    t0 = time.perf_counter()
    recs = _recordings(recordings)
    names = _unique_names(recs)
    _check_lengths(recs, names)
    recs, delay_used, estimate, native = _delay_recordings(
        recs, delay, initial_state, integer_native=True
    )
    names = _unique_names(recs)
    for nm, r in zip(names, recs):
        for a in ("u", "y"):
            arr = np.asarray(getattr(r, a), dtype=float)
            if arr.ndim != 1 or arr.size < 2:
                raise ValueError(f"{nm}: {a} must be a 1-D array of at least 2 samples")
            if not np.all(np.isfinite(arr)):
                k = int(np.argmax(~np.isfinite(arr)))
                raise ValueError(f"{nm}: {a}[{k}] is not finite")
    if u_range is None:
        lo = min(float(np.min(r.u)) for r in recs)
        hi = max(float(np.max(r.u)) for r in recs)
    else:
        lo, hi = (float(v) for v in u_range)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError(f"input range [{lo}, {hi}] V is empty: the input must vary")
    lv = _levels_arg(levels, lo, hi)
    assert lv is not None
    w, y_min, details, spans, warnings = identify_lsq_core(
        recs,
        lv,
        lambdas=lambdas,
        folds=folds,
        initial_state=initial_state,
        delay=int(native),
        nonnegative=nonnegative,
        names=names,
        progress=progress,
        solver=solver,
    )
    details.delay = delay_used
    model = PreisachModel.from_weights(lv, weights_matrix(lv, w), y_min=y_min, name=name)
    proj = None
    if details.solver == "sparse" and nonnegative and _negative_cells(model):
        model, proj = project_nonnegative(model)
        ci, cj = np.tril_indices(lv.size - 1)
        details.n_zero = int(np.count_nonzero(model.cell_weights()[ci, cj] <= 0.0))
    model.metadata = {
        "source": "identify_lsq",
        "chosen_lambda": details.chosen_lambda,
        "folds": details.folds,
        "initial_state": details.initial_state,
        "delay": details.delay,
        "solver": details.solver,
    }
    usage = [
        DataUsage(
            name=span.name,
            n_samples=span.n_samples,
            n_used=span.n_used,
            note=f"fitted from sample {span.start}"
            + ("" if span.exact_state else " (state not exact)"),
        )
        for span in spans
    ]
    src = _Source(recs, names, usage, initial_state, delay_used, estimate, int(native))
    return _report("lsq", model, src, warnings, t0, projection=proj, lsq=details)
