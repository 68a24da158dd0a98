"""One entry point that picks the identification method from the data: :func:`identify`.

``method="auto"`` (the default of ``preisach identify``) looks at what the recordings hold:

* an FOD sweep (first-order descending curves from negative saturation, thesis §2.6) whose
  curves measure at least :data:`FOD_COVERAGE` of the FOD grid's nodes: Mayergoyz
  (:func:`~preisach.identify.identify_fod`), which reads the table off the curves;
* a FORC measurement (first-order *reversal* curves from positive saturation, the
  magnetometer's form) covering the grid as well: Mayergoyz on the mirrored data
  (``u -> -u``, ``y -> -y`` turns FORCs into FOD curves), the model mirrored back;
* anything else (periodic drives, noise, a few minor loops): least squares on every sample
  (:func:`~preisach.identify.identify_lsq`), which needs no particular excitation.

The report's ``choice`` says which method ran and why (the coverage found).  The method is
chosen on the recordings as given; the output delay is then estimated (unless given) - for the
FOD method by the Mayergoyz model's own residual - and applied to whichever method runs.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .. import _core
from ..initial_state import InitialState, check_policy
from ..model import PreisachModel
from ..recording import Recording, RecordingsInput, SampledData
from .fod_finder import FODData, find_fod_curves
from .identifiers import (
    FOD_DELAY_SCORE,
    MAX_FOD_LEVELS,
    Delay,
    _delay_recordings,
    _recordings,
    fod_delay_score,
    identify_fod,
    identify_lsq,
    identify_surface,
)
from .report import IdentificationReport

__all__ = ["FOD_COVERAGE", "identify", "mirror_model", "mirror_recording"]

#: Fraction of the FOD grid's nodes the curves must measure for ``method="auto"`` to use
#: Mayergoyz; below it most of the table would be extrapolated, and least squares does better.
FOD_COVERAGE = 0.9
METHODS = ("auto", "fod", "surface", "lsq")


def _mirrored(recs: Sequence[SampledData]) -> list[Recording]:
    """Return every recording mirrored (:func:`mirror_recording`)."""
    return [mirror_recording(r) for r in recs]


def mirror_recording(rec: SampledData) -> Recording:
    """Return the recording with input and output negated (FORC <-> FOD curves)."""
    meta = dict(getattr(rec, "metadata", None) or {})
    meta["mirrored"] = 1
    return Recording.from_arrays(
        t=np.asarray(rec.t, dtype=float),
        u=-np.asarray(rec.u, dtype=float),
        y=-np.asarray(rec.y, dtype=float),
        metadata=meta,
    )


def mirror_model(model: PreisachModel) -> PreisachModel:
    """Return the model of the mirrored system ``y'(u') = -y(-u')``.

    ``E'(alpha, beta) = E(-beta, -alpha)`` on the negated, reversed levels, and
    ``y_min' = -y_max``: a relay (alpha, beta) of one is the relay (-beta, -alpha) of the other.
    """
    lv = model.levels
    values = np.asarray(model.table.values)[::-1, ::-1].T
    table = _core.EverettTable(
        -lv[::-1], np.ascontiguousarray(values), -model.y_max, model.interpolation
    )
    return PreisachModel(
        table,
        name=model.name,
        metadata=dict(model.metadata),
        out_of_range=model.out_of_range,
    )


def _coverage(fd: FODData) -> tuple[int, int]:
    n = fd.levels.size
    return int(np.count_nonzero(np.tril(fd.count))), n * (n + 1) // 2


def _find(
    recs: list[Recording], levels: ArrayLike | None, mirrored: bool
) -> tuple[FODData | None, str]:
    """FOD curves of the recordings (mirrored: their FORCs), or None and why not."""
    parts = []
    lo = min(float(np.min(r.u)) for r in recs)
    hi = max(float(np.max(r.u)) for r in recs)
    for r in recs:
        try:
            parts.append(find_fod_curves(r, levels=levels, u_min=lo, u_max=hi))
        except ValueError as exc:
            return None, str(exc)
        if levels is None:
            levels = parts[-1].levels
    best = max(parts, key=lambda p: _coverage(p)[0])
    if not best.used_curves:
        return None, "no usable curve"
    return best, ""


def identify(
    recordings: RecordingsInput,
    method: str = "auto",
    levels: ArrayLike | int | None = None,
    *,
    delay: Delay = None,
    initial_state: InitialState = "burn-in",
    name: str = "",
    project: bool = False,
    folds: int = 5,
    solver: str = "auto",
    y_min_source: str = "column_mean",
    progress: bool = True,
    interpolation: str = "auto",
) -> IdentificationReport:
    """Identify a model from recordings with the method the data call for (or the one given).

    Parameters
    ----------
    recordings : Recording, path, object with t/u/y, or a sequence of them
        Any recordings of one actuator (or one magnetometer sample), as
        :func:`~preisach.recording.as_recordings` accepts them.
    method : {"auto", "fod", "surface", "lsq"}
        ``"auto"`` (default) chooses as the module docstring says; the others force a method.
    levels : int or array_like, optional
        FOD grid (fod/surface; default from the turning values) or table levels (lsq;
        default 41).
    delay : int, float, "auto" or None
        Output delay in samples; estimated when ``None``/``"auto"``: for the FOD method by the
        Mayergoyz model's residual on the sweep shifted by each whole-sample delay (a nonzero
        one must lower it by 25 %, :data:`~preisach.identify.delay.SCORE_MARGIN`), else by
        cross-validation (:func:`~preisach.identify.delay.estimate_delay`).
    initial_state : str or State
        Initial-state policy (see :mod:`preisach.initial_state`).
    name : str
        Model name.
    project : bool
        fod: project the table to Mp.
    folds : int
        lsq: cross-validation folds.
    solver : {"auto", "dense", "sparse"}
        lsq: the least-squares solver.
    y_min_source : {"column_mean", "corner"}
        surface: where ``y_min`` comes from.
    progress : bool
        lsq: show a progress bar over the cross-validation fits (``False``: nothing).
    interpolation : {"auto", "bilinear", "cubic"}
        fod: the table's interpolation between the nodes (``"auto"``: the one whose residual
        on the recordings is lower, cubic by at least 10 %; see
        :func:`~preisach.identify.identify_fod`).

    Returns
    -------
    IdentificationReport
        ``choice`` says why the method ran; unpacks as ``model, report``.

    """
    t0 = time.perf_counter()
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    check_policy(initial_state)
    recs = _recordings(recordings)
    choice = ""
    mirrored = False
    chosen = method
    if method == "auto":
        lv_arg: ArrayLike | None = levels
        if lv_arg is not None and np.ndim(lv_arg) == 0 and int(np.asarray(lv_arg)) > MAX_FOD_LEVELS:
            lv_arg = None  # too fine for an FOD grid: found on the default grid
        fod, why = _find(recs, lv_arg, False)
        forc, why_r = _find(_mirrored(recs), lv_arg, True)
        cov = _coverage(fod) if fod is not None else (0, 1)
        cov_r = _coverage(forc) if forc is not None else (0, 1)
        frac, frac_r = cov[0] / cov[1], cov_r[0] / cov_r[1]
        if fod is not None and frac >= FOD_COVERAGE and frac >= frac_r:
            chosen = "fod"
            choice = (
                f"the recordings hold {len(fod.used_curves)} FOD curves measuring {cov[0]} of "
                f"{cov[1]} FOD nodes ({100 * frac:.0f} % >= {100 * FOD_COVERAGE:.0f} %): "
                "Mayergoyz reads the table off them"
            )
        elif forc is not None and frac_r >= FOD_COVERAGE:
            chosen, mirrored = "fod", True
            choice = (
                f"the recordings hold {len(forc.used_curves)} first-order reversal curves "
                f"(FORC) measuring {cov_r[0]} of {cov_r[1]} nodes ({100 * frac_r:.0f} % >= "
                f"{100 * FOD_COVERAGE:.0f} %): Mayergoyz on the mirrored curves"
            )
        else:
            chosen = "lsq"
            best = max(frac, frac_r)
            found = (
                f"FOD/FORC curves measure only {100 * best:.0f} % of their grid's nodes"
                if fod is not None or forc is not None
                else f"no FOD or FORC curves ({why or why_r})"
            )
            choice = (
                f"{found} (Mayergoyz needs >= {100 * FOD_COVERAGE:.0f} %): least squares on "
                "every sample, which needs no particular excitation"
            )
    if chosen != "fod" and project:
        raise ValueError("project applies to the fod method only")
    if chosen != "fod" and interpolation not in ("auto", "bilinear"):
        raise ValueError(
            f"interpolation: {interpolation!r} applies to the fod method only "
            f"(this identification is {chosen})"
        )
    score, score_name = None, ""
    if chosen == "fod":  # the method is chosen on the recordings as given (a few samples of
        # delay do not change which curves they hold); the delay is then scored by the model
        mirror = _mirrored if mirrored else None
        score, score_name = fod_delay_score(levels, initial_state, None, mirror), FOD_DELAY_SCORE
    recs, d, estimate, _ = _delay_recordings(recs, delay, initial_state, False, score, score_name)
    data = _mirrored(recs) if mirrored else recs
    if chosen == "fod":
        rep = identify_fod(
            data,
            levels,
            project=project,
            name=name,
            initial_state=initial_state,
            delay=0,
            interpolation=interpolation,
        )
    elif chosen == "surface":
        rep = identify_surface(
            data,
            levels,
            y_min_source=y_min_source,
            name=name,
            initial_state=initial_state,
            delay=0,
        )
    else:
        rep = identify_lsq(
            data,
            41 if levels is None else levels,
            folds=folds,
            initial_state=initial_state,
            delay=0,
            name=name,
            solver=solver,
            progress=progress,
        )
    if mirrored:
        model = mirror_model(rep.model)
        model.metadata["source"] = "identify_fod (FORC, mirrored)"
        rep.model = model
        rep.fod = None  # the curves are those of the mirrored data
        rep.warnings.append(
            "FORC data: identified as FOD curves of the mirrored recording (u -> -u, y -> -y); "
            "the model is mirrored back"
        )
    rep.model.metadata["delay"] = d
    if rep.lsq is not None:
        rep.lsq.delay = d
    rep.delay = d
    rep.delay_estimate = estimate
    rep.choice = choice
    rep.elapsed = time.perf_counter() - t0
    return rep
