"""The output delay of a recording, estimated by cross-validation, and applied to recordings.

A sampled rig answers an input sample a few samples later (sensor filters, the ADC/DAC
pipeline): ``y(k + d)`` answers ``u(k)``.  A Preisach model has no dynamics, so an unmodelled
delay shows up as a hysteresis loop that is too wide, and costs every identifier accuracy.

:func:`estimate_delay` tries the integer delays ``0, 1, 2, ...`` (until three in a row are worse
than the best, or ``max_delay``): for each, a coarse least-squares model (21 levels, the smoothness
weight chosen by 5-fold cross-validation over time blocks) is fitted and its cross-validated RMS
error noted.  The delay with the lowest error wins; a parabola through it and its neighbours then
proposes a fractional delay, which is kept when its own cross-validated error is lower still.
A caller may score the delays its own way (``score``): the FOD identifiers (and so
:func:`preisach.identify.identify` when it chose them) score an FOD sweep by the Mayergoyz
model's residual on the shifted sweep itself, whole
samples only, and keeps a nonzero delay only when it lowers that residual by
:data:`SCORE_MARGIN` - the coarse least-squares grid's own resolution error moves with the
delay on steep loops (6 samples found on a delay-free blind test device).
:func:`shift_output` applies a delay (integer or fractional, by linear interpolation of the
output) to a recording, which is how every identifier honours ``delay``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from ..initial_state import InitialState
from ..recording import Recording, SampledData

__all__ = ["DelayEstimate", "estimate_delay", "shift_output"]

#: Levels of the coarse least-squares model that scores each candidate delay.
ESTIMATE_LEVELS = 21
#: Smoothness weights tried for each candidate (dimensionless, see preisach.identify.lsq).
ESTIMATE_LAMBDAS = (1e-4, 1e-2, 1.0)
#: With a model's own residual as the score (``score``): the least share of the error at
#: delay 0 a nonzero delay must remove.  Whole samples only.  The residual of a grid
#: interpolated between its nodes falls by about 13 % at one sample on delay-free blind test
#: devices (seed 11, cases 008 and 014: a loop steeper than the grid is traced slightly late),
#: and by 53 % at a true 3-sample delay (tests/test_identify_solver_delay.py).
SCORE_MARGIN = 0.25


@dataclass
class DelayEstimate:
    """How an output delay was estimated.

    Attributes
    ----------
    delay : float
        The estimate (samples; fractional when that cross-validated better).
    candidates : ndarray
        Delays tried (samples), integers first, then the fractional proposal if any.
    cv_rms : ndarray
        Cross-validated RMS error (output units) of the coarse model for each candidate, or
        the caller's score when ``scored_by`` names one.
    levels : int
        Levels of the coarse least-squares model used for scoring.
    folds : int
        Cross-validation folds.
    notes : list of str
        Anything worth knowing (the range of delays searched, a fractional proposal rejected).
    scored_by : str
        What scored the delays when not the least-squares cross-validation (``score_name``).

    """

    delay: float
    candidates: NDArray[np.float64]
    cv_rms: NDArray[np.float64]
    levels: int = ESTIMATE_LEVELS
    folds: int = 5
    notes: list[str] = field(default_factory=list)
    scored_by: str = ""

    def describe(self) -> str:
        """One line: the estimate and the cross-validated errors that chose it."""
        if self.cv_rms.size == 0:
            return "; ".join(self.notes) or "not estimated"
        best = float(np.min(self.cv_rms))
        order = np.argsort(self.candidates)
        tried = ", ".join(
            f"{self.candidates[k]:g}: {self.cv_rms[k]:.4g}" for k in order[: min(order.size, 8)]
        )
        if self.scored_by:
            return f"estimated by {self.scored_by}; rms by delay {tried}; best {best:.4g}"
        return (
            f"estimated by {self.folds}-fold cross-validation of a {self.levels}-level "
            f"least-squares model; CV rms by delay {tried}; best {best:.4g}"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            "delay": self.delay,
            "candidates": self.candidates.tolist(),
            "cv_rms": self.cv_rms.tolist(),
            "levels": self.levels,
            "folds": self.folds,
            "notes": list(self.notes),
            "scored_by": self.scored_by or "cross-validation",
        }


def shift_output(rec: SampledData, delay: float) -> Recording:
    """Return the recording whose samples pair the output ``y(k + delay)`` with the input ``u(k)``.

    For ``delay = k0 + f`` (``k0`` an integer, ``0 < f < 1``) sample ``j`` pairs
    ``y(j + k0 + 1)`` with the input interpolated at ``j + 1 - f``: the fraction is taken on the
    input, which keeps the output samples (and their noise) as measured - interpolating the
    output would average its noise down and make any fractional delay look better.

    Parameters
    ----------
    rec : Recording or object with ``t``, ``u``, ``y`` (and optionally ``metadata``)
        The recording.
    delay : float
        Output delay in samples (>= 0).

    Returns
    -------
    Recording
        ``len(rec) - ceil(delay)`` samples (the last ones have no delayed output), metadata
        kept, ``output_delay`` added.

    """
    d = float(delay)
    if not (math.isfinite(d) and d >= 0.0):
        raise ValueError(f"delay: need a number of samples >= 0, got {delay!r}")
    u = np.asarray(rec.u, dtype=float)
    y = np.asarray(rec.y, dtype=float)
    t = np.asarray(rec.t, dtype=float)
    k0 = int(math.floor(d))
    f = d - k0
    n = u.size - int(math.ceil(d))
    if n < 2:
        raise ValueError(f"delay: {u.size} samples are too few for an output delay of {d:g}")
    if f > 0.0:  # y(j + k0 + 1) answers u(j + 1 - f)
        us = (1.0 - f) * u[1 : n + 1] + f * u[:n]
        ys = y[k0 + 1 : k0 + 1 + n]
        ts = t[1 : n + 1]
    else:
        us, ys, ts = u[:n], y[k0 : k0 + n], t[:n]
    meta = dict(getattr(rec, "metadata", None) or {})
    meta["output_delay"] = d
    return Recording.from_arrays(t=np.array(ts), u=np.array(us), y=np.array(ys), metadata=meta)


def estimate_delay(
    recordings: Sequence[SampledData],
    *,
    max_delay: int | None = None,
    folds: int = 5,
    initial_state: InitialState = "burn-in",
    names: Sequence[str] | None = None,
    score: Callable[[list[SampledData]], float] | None = None,
    score_name: str = "",
) -> DelayEstimate:
    """Estimate the output delay of recordings by cross-validation (see the module docstring).

    Parameters
    ----------
    recordings : sequence of Recording
        The recordings (one common delay).
    max_delay : int, optional
        Largest delay tried (samples); default ``min(50, shortest recording / 20)``.
    folds : int
        Cross-validation folds.
    initial_state : str or State
        Initial-state policy of the least-squares fits.
    names : sequence of str, optional
        Recording names for messages.
    score : callable, optional
        Another error of a candidate delay: called with the recordings shifted by it
        (:func:`shift_output`), returns an RMS error (output units), lower is better.
        The FOD identifiers pass the residual of the Mayergoyz model on its own recordings
        (:func:`preisach.identify.identifiers.fod_delay_score`), which a coarse
        least-squares grid's resolution error does not blur.  Whole samples only, and a
        nonzero delay must lower it by :data:`SCORE_MARGIN` of its value at 0.
    score_name : str
        What ``score`` measures, for the report.

    Returns
    -------
    DelayEstimate

    """
    from .lsq import identify_lsq_core

    recs = list(recordings)
    if not recs:
        raise ValueError("no recordings given")
    nm = list(names) if names is not None else [f"recording {k}" for k in range(len(recs))]
    shortest = min(int(np.size(r.u)) for r in recs)
    limit = min(50, shortest // 20) if max_delay is None else int(max_delay)
    limit = max(limit, 0)
    lo = min(float(np.min(r.u)) for r in recs)
    hi = max(float(np.max(r.u)) for r in recs)
    levels = np.linspace(lo, hi, ESTIMATE_LEVELS)
    notes: list[str] = []

    def evaluate(recs_d: Sequence[SampledData], d: int) -> float:
        if score is not None:
            shifted_d: list[SampledData] = (
                [shift_output(r, d) for r in recs_d] if d else list(recs_d)
            )
            return float(score(shifted_d))
        _, _, details, _, _ = identify_lsq_core(
            recs_d,
            levels,
            lambdas=ESTIMATE_LAMBDAS,
            folds=folds,
            initial_state=initial_state,
            delay=d,
            nonnegative=False,
            names=nm,
            solver="dense",
        )
        return float(np.min(details.cv_rms))

    cand: list[float] = []
    cv: list[float] = []
    best = 0
    for d in range(limit + 1):
        try:
            value = evaluate(recs, d)
        except ValueError as exc:  # too few samples after the burn-in for this delay, ...
            if d == 0:
                return DelayEstimate(
                    delay=0.0,
                    candidates=np.zeros(0),
                    cv_rms=np.zeros(0),
                    folds=folds,
                    notes=[f"not estimated (0 used): {exc}"],
                )
            notes.append(f"delays from {d} on not tried: {exc}")
            break
        cand.append(float(d))
        cv.append(value)
        if cv[-1] < cv[best]:
            best = d
        if d >= best + 3:
            break
    if len(cand) == limit + 1 and best == limit and limit > 0 and not notes:
        notes.append(f"the best delay is the largest tried ({limit}); pass max_delay to go further")
    if score is not None and best > 0 and cv[best] > (1.0 - SCORE_MARGIN) * cv[0]:
        notes.append(
            f"the best delay, {best}, lowers the error by only "
            f"{100 * (1 - cv[best] / cv[0]):.0f} % (< {100 * SCORE_MARGIN:.0f} %): 0 used"
        )
        best = 0
    delay = float(best)
    if score is None and 0 < best < len(cand) - 1:
        c0, c1, c2 = cv[best - 1] ** 2, cv[best] ** 2, cv[best + 1] ** 2
        curv = c0 - 2.0 * c1 + c2
        if curv > 0:
            frac = 0.5 * (c0 - c2) / curv  # vertex of the parabola, in (-0.5, 0.5)
            if abs(frac) >= 0.05:
                dfrac = best + frac
                shifted = [shift_output(r, dfrac) for r in recs]
                try:
                    s = evaluate(shifted, 0)
                except ValueError:
                    s = math.inf
                cand.append(dfrac)
                cv.append(s)
                if s < cv[best]:
                    delay = dfrac
                else:
                    notes.append(
                        f"the fractional delay {dfrac:.3g} proposed by the parabola through "
                        "the best integer delays did not cross-validate better"
                    )
    return DelayEstimate(
        delay=delay,
        candidates=np.array(cand),
        cv_rms=np.array(cv),
        folds=folds,
        notes=notes,
        scored_by=score_name if score is not None else "",
    )
