"""Verification of Preisach models and of the Preisach properties of data (thesis §3.2, §3.3.4).

Three tools, all in volts and in percent of an output range:

* :func:`verify` simulates each recording's input through a model and reports the maximum
  and RMS error per experiment, as the thesis does in §3.3.4 ("the error of the maximum
  magnitude over the whole output range is about 2.33 %, 4.51 % and 9.23 %" for the wiping-out
  test at 1, 2 and 4 Hz).
* :func:`wiping_out_metric` tests the wiping-out (return-point memory) property on a recording
  (§3.2.1, Figs 3.10-3.12): where the input returns to a previous reversal value, the output
  must return to the value it had there.
* :func:`congruency_metric` tests the congruent-minor-loop property (§3.2.2, Figs 3.14-3.16):
  minor loops between the same input extrema must have the same shape, up to a vertical shift.

Percentages use the *output range* of the recording: ``max(y) - min(y)`` of its measured
output (the thesis's "whole output range", about 7 V for the SS15), unless ``output_range`` is
given.  Pass/fail compares the largest difference with ``tolerance`` percent of that range;
the default 5 % is the thesis's criterion ("the largest offset 0.32 V is within 5 % of the whole
output range. Thus, this is considered to be sufficiently close to zero").

Initial state
-------------
A recording does not say what state the model starts in.  :func:`verify` and :func:`predict`
take the policies of :mod:`preisach.initial_state`: ``"burn-in"`` (default) simulates from
negative saturation and scores only the samples from the burn-in end on - the first sample at
the model's ``u_min`` or ``u_max`` (from then on the state is exact), or where the recording has
visited both its own extremes (then relays it never switches are assumed at -1); or
``"negative"``, ``"positive"``, ``"anhysteretic"`` or a :class:`~preisach.State`, scoring every
sample.  The thesis's experiments start at negative saturation, so ``"burn-in"`` scores them from
their first sample.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .errors import PreisachWarning
from .initial_state import InitialState, burn_in_end, check_policy, initial_state_for
from .model import PreisachModel
from .recording import RecordingsInput, SampledData, as_recordings, recording_labels

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = [
    "Comparison",
    "CongruencyResult",
    "LoopPair",
    "MinorLoop",
    "Prediction",
    "VerificationRow",
    "VerificationTable",
    "WipingOutResult",
    "comparable_loops",
    "congruency_metric",
    "minor_loops",
    "predict",
    "verify",
    "wiping_out_metric",
]


def _arrays(
    rec: SampledData,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    if not all(hasattr(rec, a) for a in ("t", "u", "y")):
        raise TypeError(f"expected a recording with attributes t, u, y, got {type(rec).__name__}")
    t, u, y = (np.asarray(getattr(rec, a), dtype=float) for a in ("t", "u", "y"))
    if not (t.ndim == u.ndim == y.ndim == 1 and t.size == u.size == y.size):
        raise ValueError("recording: t, u and y must be 1-D arrays of the same length")
    if t.size < 2:
        raise ValueError(f"recording: need at least 2 samples, got {t.size}")
    for nm, a in (("t", t), ("u", u), ("y", y)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"recording: {nm}[{int(np.argmax(~np.isfinite(a)))}] is not finite")
    return t, u, y


def _range(y: NDArray[np.float64], output_range: float | None) -> float:
    if output_range is not None:
        r = float(output_range)
        if not (math.isfinite(r) and r > 0):
            raise ValueError(
                f"output_range: must be a positive finite number (V), got {output_range!r}"
            )
        return r
    r = float(np.max(y) - np.min(y))
    if not r > 0:
        raise ValueError(
            "the recording's output is constant, so it has no output range; pass output_range"
        )
    return r


def _check_tolerance(tolerance: float) -> float:
    tol = float(tolerance)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tolerance: must be a positive percentage, got {tolerance!r}")
    return tol


# ------------------------------------------------------------------------------------------
# model verification
# ------------------------------------------------------------------------------------------
@dataclass
class Prediction:
    """A model's prediction of one recording.

    Attributes
    ----------
    t, u, y : ndarray
        Time (s), input (V) and measured output (V) of the scored samples' pairs: ``y[k]`` is
        the measured output ``delay`` samples after the input ``u[k]``.
    y_model : ndarray
        Model output (V) for ``u``.
    first : int
        Index (into ``t``) of the first scored sample; earlier ones are the burn-in.
    exact_state : bool
        Whether the model's state is exact from ``first`` on (see the module docstring).

    """

    t: NDArray[np.float64]
    u: NDArray[np.float64]
    y: NDArray[np.float64]
    y_model: NDArray[np.float64]
    first: int
    exact_state: bool

    @property
    def error(self) -> NDArray[np.float64]:
        """Model minus measurement (V) on the scored samples."""
        return self.y_model[self.first :] - self.y[self.first :]


def predict(
    model: PreisachModel,
    recording: SampledData,
    *,
    initial_state: InitialState = "burn-in",
    delay: int = 0,
) -> Prediction:
    """Simulate a recording's input through a model.

    Parameters
    ----------
    model : PreisachModel
        The model to simulate.
    recording : Recording
        Any object with ``t``, ``u``, ``y`` (s, V, V).
    initial_state : {"burn-in", "negative", "positive", "anhysteretic"} or State
        See the module docstring.
    delay : int
        Output delay in samples: ``y[k + delay]`` is the response to ``u[k]`` (1 for the
        yan9a piezo data).

    Returns
    -------
    Prediction

    """
    t, u, y = _arrays(recording)
    pol = check_policy(initial_state)
    if isinstance(delay, bool) or int(delay) != delay or delay < 0:
        raise ValueError(f"delay: need an integer number of samples >= 0, got {delay!r}")
    d = int(delay)
    n = u.size - d
    if n < 1:
        raise ValueError(f"recording has {u.size} samples, too few for delay = {d}")
    uu, yy, tt = u[:n], y[d:], t[:n]
    s0 = initial_state_for(model, initial_state)
    ym = model.simulate(uu, s0).output
    first, exact = 0, True
    if pol == "burn-in":
        first, exact = burn_in_end(uu, model.u_min, model.u_max)
        if first >= n:
            raise ValueError(
                "the recording has no sample after the burn-in; use another initial_state"
            )
    return Prediction(tt, uu, yy, ym, first, exact)


@dataclass
class VerificationRow:
    """Errors of a model on one experiment (volts and percent of the output range).

    Attributes
    ----------
    experiment : str
    n_samples : int
        Samples scored.
    n_skipped : int
        Samples not scored (burn-in and the last ``delay`` samples).
    max_error, rms_error, mean_error : float
        ``max |e|``, ``sqrt(mean e^2)`` and ``mean e`` (V), ``e`` = model - measurement.
    output_range : float
        Range (V) the percentages refer to.
    exact_state : bool
        Whether the model's state was exact on the scored samples.
    n_out_of_range : int
        Simulated input samples outside the model's input range ``[u_min, u_max]``; the
        model clamped them to the range (see :func:`verify`).

    """

    experiment: str
    n_samples: int
    n_skipped: int
    max_error: float
    rms_error: float
    mean_error: float
    output_range: float
    exact_state: bool = True
    n_out_of_range: int = 0

    @property
    def max_pct(self) -> float:
        """``max_error`` in percent of ``output_range``."""
        return 100.0 * self.max_error / self.output_range

    @property
    def rms_pct(self) -> float:
        """``rms_error`` in percent of ``output_range``."""
        return 100.0 * self.rms_error / self.output_range

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form (percentages included)."""
        return {
            "experiment": self.experiment,
            "n_samples": self.n_samples,
            "n_skipped": self.n_skipped,
            "max_error": self.max_error,
            "rms_error": self.rms_error,
            "mean_error": self.mean_error,
            "output_range": self.output_range,
            "max_pct": self.max_pct,
            "rms_pct": self.rms_pct,
            "exact_state": self.exact_state,
            "n_out_of_range": self.n_out_of_range,
        }


@dataclass
class VerificationTable:
    """Result of :func:`verify`: one row per experiment.

    Attributes
    ----------
    rows : list of VerificationRow
    model_name : str
    predictions : list of Prediction
        The simulations behind the rows (for :meth:`plot`).
    output_units : str
        Units of the errors (the recordings' ``output_units`` metadata, ``"V"`` when absent).

    """

    rows: list[VerificationRow]
    model_name: str = ""
    predictions: list[Prediction] = field(default_factory=list, repr=False)
    output_units: str = "V"

    @property
    def max_pct(self) -> float:
        """Largest ``max_pct`` over the experiments."""
        return max(r.max_pct for r in self.rows)

    def table(self) -> str:
        """Format the error table as text.

        ``mean`` is the bias (model - measurement); ``clamped`` counts the input samples
        outside the model's input range (clamped to it by the simulation).
        """
        u = self.output_units
        head = (
            f"{'experiment':<24} {'samples':>8} {'clamped':>8} {f'max ({u})':>10} "
            f"{f'rms ({u})':>10} {f'mean ({u})':>10} {f'range ({u})':>10} {'max %':>8} "
            f"{'rms %':>8}"
        )
        lines = [f"verification of {self.model_name or 'model'}", head, "-" * len(head)]
        for r in self.rows:
            flag = "" if r.exact_state else "  (state not exact: offset may be biased)"
            lines.append(
                f"{r.experiment[:24]:<24} {r.n_samples:>8d} {r.n_out_of_range:>8d} "
                f"{r.max_error:>10.4g} {r.rms_error:>10.4g} {r.mean_error:>10.3g} "
                f"{r.output_range:>10.4g} {r.max_pct:>8.3f} {r.rms_pct:>8.3f}{flag}"
            )
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """HTML for Jupyter: the error table, doubtful rows highlighted."""
        from ._display import verification_html

        return verification_html(self)

    def __str__(self) -> str:
        return self.table()

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {"model": self.model_name, "rows": [r.to_dict() for r in self.rows]}

    def plot(self, *, fig: Figure | None = None) -> Figure:
        """Measured and simulated output, and their difference, per experiment (time in s)."""
        from .identify.plots import plot_verification

        return plot_verification(self, fig=fig)


def verify(
    model: PreisachModel,
    recordings: RecordingsInput,
    *,
    initial_state: InitialState = "burn-in",
    delay: int = 0,
    output_range: float | None = None,
    names: Sequence[str] | None = None,
    warn_out_of_range: bool = True,
) -> VerificationTable:
    """Simulate every recording's input through ``model`` and tabulate the errors.

    Input samples outside the model's input range ``[u_min, u_max]`` are clamped to it by the
    simulation (with the model's default ``out_of_range="clamp"``); their number is reported
    per experiment (:attr:`VerificationRow.n_out_of_range`, the ``clamped`` column) and a
    :class:`~preisach.errors.PreisachWarning` names each recording that has any.

    Parameters
    ----------
    model : PreisachModel
        The model to verify.
    recordings : Recording, path, object with t/u/y, or a sequence of them
        The recordings (s, V, V); see :func:`preisach.recording.as_recordings`.
    initial_state : {"burn-in", "negative", "positive", "anhysteretic"} or State
        See the module docstring.
    delay : int
        Output delay in samples (``y[k + delay]`` answers ``u[k]``).
    output_range : float, optional
        Range (V) for the percentages; default each recording's measured output range.
    names : sequence of str, optional
        Experiment names; default the label rule of
        :func:`preisach.recording.recording_labels` (``experiment`` metadata, else ``name``,
        else the file stem or ``recording k``; repeated labels numbered ``#1``, ``#2``).
    warn_out_of_range : bool
        Warn about recordings with input samples outside the model's range (default); the
        counts are in the rows either way.

    Returns
    -------
    VerificationTable
        Max and RMS error in volts and in percent of the output range, per experiment.

    Warns
    -----
    PreisachWarning
        For each recording with input samples outside ``[model.u_min, model.u_max]``.

    """
    recs = as_recordings(recordings)
    nm = recording_labels(recs, names, argument="names")
    rows: list[VerificationRow] = []
    preds: list[Prediction] = []
    for name, rec in zip(nm, recs):
        try:
            p = predict(model, rec, initial_state=initial_state, delay=delay)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from exc
        e = p.error
        rng = _range(np.asarray(rec.y, dtype=float), output_range)
        n_out = int(np.count_nonzero((p.u < model.u_min) | (p.u > model.u_max)))
        if n_out and warn_out_of_range:
            warnings.warn(
                f"{name}: {n_out} of {p.u.size} input samples lie outside the model's input "
                f"range [{model.u_min:g}, {model.u_max:g}] V (from {float(np.min(p.u)):g} to "
                f"{float(np.max(p.u)):g} V) and were clamped to it",
                PreisachWarning,
                stacklevel=2,
            )
        rows.append(
            VerificationRow(
                name,
                int(e.size),
                int(len(rec.u) - e.size),
                float(np.max(np.abs(e))),
                float(np.sqrt(np.mean(e * e))),
                float(np.mean(e)),
                rng,
                p.exact_state,
                n_out,
            )
        )
        preds.append(p)
    units = sorted({str(r.metadata.get("output_units", "V")) or "V" for r in recs})
    return VerificationTable(rows, model.name, preds, output_units=" / ".join(units) or "V")


# ------------------------------------------------------------------------------------------
# turning points
# ------------------------------------------------------------------------------------------
def _turning_points(
    u: NDArray[np.float64], tol: float
) -> tuple[NDArray[np.intp], NDArray[np.int8]]:
    """Find the turning points of ``u`` with hysteresis ``tol`` (V).

    Returns the sample indices ``P_0 = 0 < P_1 < ... < P_L`` between which the input is
    monotone up to ``tol`` - the reversals, the first sample and the end of the last leg - and
    their kinds: +1 where the leg into the point rises (a maximum), -1 where it falls (a
    minimum); ``kind[0] = -kind[1]``.  A reversal counts only when the input moves back by more
    than ``tol`` from its running extreme; the extreme is the last sample at the extreme value.
    A last leg shorter than ``tol`` is dropped.
    """
    n = u.size
    d = np.diff(u)
    left, right = d[:-1], d[1:]
    mid = (
        np.nonzero(
            ((left > 0) & (right <= 0)) | ((left < 0) & (right >= 0)) | ((left == 0) & (right != 0))
        )[0]
        + 1
    )
    cand = np.concatenate((mid, [n - 1])).tolist()
    vals = u[cand].tolist()
    pts = [0]
    direction, ext = 0, 0
    for k, v in zip(cand, vals):
        if direction == 0:
            if v - u[0] > tol:
                direction, ext = 1, k
            elif u[0] - v > tol:
                direction, ext = -1, k
        elif direction > 0:
            if v >= u[ext]:
                ext = k
            elif u[ext] - v > tol:
                pts.append(ext)
                direction, ext = -1, k
        else:
            if v <= u[ext]:
                ext = k
            elif v - u[ext] > tol:
                pts.append(ext)
                direction, ext = 1, k
    if direction != 0 and ext != pts[-1]:
        pts.append(ext)
    idx = np.asarray(pts, dtype=np.intp)
    kind = np.zeros(idx.size, dtype=np.int8)
    if idx.size > 1:
        kind[1:] = np.where(u[idx[1:]] > u[idx[:-1]], 1, -1)
        kind[0] = -kind[1]
    return idx, kind


def _cross(
    u: NDArray[np.float64], y: NDArray[np.float64], i0: int, i1: int, level: float, rising: bool
) -> float | None:
    """Read the output where the monotone envelope of ``u[i0..i1]`` first reaches ``level``."""
    seg = u[i0 : i1 + 1]
    env = np.maximum.accumulate(seg) if rising else np.minimum.accumulate(seg)
    hit = np.nonzero(env >= level)[0] if rising else np.nonzero(env <= level)[0]
    if hit.size == 0:
        return None
    k = int(hit[0])
    if k == 0:
        return float(y[i0])
    a, b = env[k - 1], env[k]
    w = 0.0 if b == a else (level - a) / (b - a)
    # interpolate between the raw samples bracketing the crossing of the envelope
    return float(y[i0 + k - 1] + w * (y[i0 + k] - y[i0 + k - 1]))


def _branch_read(
    u: NDArray[np.float64],
    y: NDArray[np.float64],
    i0: int,
    i1: int,
    grid: NDArray[np.float64],
    rising: bool,
) -> NDArray[np.float64]:
    """Output on the monotone envelope of the branch ``u[i0..i1]`` at ``grid`` (NaN outside)."""
    seg = u[i0 : i1 + 1]
    ys = y[i0 : i1 + 1]
    env = np.maximum.accumulate(seg) if rising else -np.minimum.accumulate(seg)
    g = grid if rising else -grid
    # first sample reaching each grid value, interpolated on the envelope
    pos = np.searchsorted(env, g, side="left")
    out = np.full(grid.size, np.nan)
    ok = (pos < env.size) & (g >= env[0])
    p = pos[ok]
    p0 = np.maximum(p - 1, 0)
    a, b = env[p0], env[p]
    w = np.divide(g[ok] - a, b - a, out=np.zeros(p.size), where=b > a)
    out[ok] = ys[p0] + w * (ys[p] - ys[p0])
    return out


# ------------------------------------------------------------------------------------------
# wiping-out
# ------------------------------------------------------------------------------------------
@dataclass
class Comparison:
    """One wiping-out comparison: the output at a reversal value, then and on its return.

    Attributes
    ----------
    kind : str
        ``"ascending"`` (return to a previous maximum) or ``"descending"`` (to a minimum).
    level : float
        Input (V) at which the two branches are compared: the reversal value (the lower of the
        two peaks when the later one does not quite reach it).
    t_first, t_return : float
        Times (s) of the reversal and of the return.
    y_first, y_return : float
        Outputs (V) at ``level`` on the earlier and the later branch.

    """

    kind: str
    level: float
    t_first: float
    t_return: float
    y_first: float
    y_return: float

    @property
    def difference(self) -> float:
        """``y_return - y_first`` (V)."""
        return self.y_return - self.y_first


class _PropertyTest:
    """What the wiping-out and the congruency results share: percentages, verdict, HTML, JSON.

    A subclass (a dataclass with ``output_range`` and ``tolerance`` fields) says what its
    ``max_difference`` is and whether its recording was testable at all.
    """

    output_range: float
    tolerance: float

    @property
    def max_difference(self) -> float:
        """The largest difference the test measured (V)."""
        raise NotImplementedError

    @property
    def _tested(self) -> bool:
        raise NotImplementedError

    @property
    def max_pct(self) -> float:
        """``max_difference`` in % of the output range."""
        return 100.0 * self.max_difference / self.output_range

    @property
    def passed(self) -> bool:
        """At least one comparison, and every one within ``tolerance``."""
        return self._tested and self.max_pct <= self.tolerance

    def _verdict(self, untestable: str) -> str:
        """``PASS``/``FAIL`` with the tolerance, or ``NOT TESTABLE (untestable)``."""
        if not self._tested:
            return f"NOT TESTABLE ({untestable})"
        return f"{'PASS' if self.passed else 'FAIL'} (tolerance {self.tolerance:g} %)"

    def _repr_html_(self) -> str:
        """HTML for Jupyter: the verdict and the comparisons."""
        from ._display import property_test_html

        return property_test_html(self)

    def _summary(self) -> dict[str, Any]:
        keys = ("max_difference", "max_pct", "passed", "tolerance", "output_range")
        return {k: getattr(self, k) for k in keys}


@dataclass
class WipingOutResult(_PropertyTest):
    """Result of :func:`wiping_out_metric`.

    Attributes
    ----------
    comparisons : list of Comparison
    output_range : float
        Range (V) of the percentages.
    tolerance : float
        Pass/fail threshold (% of ``output_range``).

    """

    comparisons: list[Comparison]
    output_range: float
    tolerance: float

    @property
    def max_difference(self) -> float:
        """Largest ``|difference|`` (V); 0 without comparisons."""
        return max((abs(c.difference) for c in self.comparisons), default=0.0)

    @property
    def _tested(self) -> bool:
        return bool(self.comparisons)

    def table(self) -> str:
        """Format the comparisons as text."""
        lines = [
            f"wiping-out test: {len(self.comparisons)} returns to a reversal value; max "
            f"|dy| = {self.max_difference:.4g} V = {self.max_pct:.3f} % of "
            f"{self.output_range:.4g} V -> "
            + self._verdict("no return to a reversal value in this recording"),
            f"{'branch':<11} {'level (V)':>10} {'t1 (s)':>9} {'t2 (s)':>9} {'y1 (V)':>10} "
            f"{'y2 (V)':>10} {'dy (V)':>10} {'dy %':>7}",
        ]
        for c in self.comparisons:
            lines.append(
                f"{c.kind:<11} {c.level:>10.4g} {c.t_first:>9.4g} {c.t_return:>9.4g} "
                f"{c.y_first:>10.5g} {c.y_return:>10.5g} {c.difference:>10.4g} "
                f"{100 * c.difference / self.output_range:>7.3f}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            **self._summary(),
            "comparisons": [{**c.__dict__, "difference": c.difference} for c in self.comparisons],
        }


def wiping_out_metric(
    recording: SampledData,
    *,
    tolerance: float = 5.0,
    reversal_tol: float | None = None,
    branches: str = "both",
    output_range: float | None = None,
) -> WipingOutResult:
    """Wiping-out (return-point memory) test of a recording (thesis §3.2.1, Figs 3.10-3.12).

    For every reversal of the input - a maximum ``M`` reached by a rise that started at the
    minimum ``m0`` - find the first later time the input rises to ``M`` again.  If the input
    stayed within ``[m0 - reversal_tol, M + reversal_tol]`` in between, a Preisach system is back
    in the state it had at the reversal (the excursions between were wiped out), so its output
    must be the same: the difference of the two outputs at ``M`` is the metric.  The same for
    minima and falls (``branches="descending"``).  When the later peak stops short of ``M`` by
    less than ``reversal_tol`` (noise), both branches are read at the lower peak.

    Parameters
    ----------
    recording : Recording
        Any object with ``t``, ``u``, ``y`` (s, V, V).
    tolerance : float
        Pass if every ``|difference|`` is within this percentage of the output range (5 %: the
        thesis's criterion).
    reversal_tol : float, optional
        Hysteresis (V) of the turning-point detector, and the slack allowed when the input
        returns; default 0.5 % of the input range.
    branches : {"both", "ascending", "descending"}
        Returns to maxima (the thesis's ascending branches), to minima, or both.
    output_range : float, optional
        Range (V) for the percentages; default the recording's output range.

    Returns
    -------
    WipingOutResult
        For the thesis's input (Fig 3.6) the ascending comparisons are the 4th ascending branch
        against the 1st, 2nd and 3rd at their peaks (Figs 3.10-3.12).

    """
    t, u, y = _arrays(recording)
    tol_pct = _check_tolerance(tolerance)
    if branches not in ("both", "ascending", "descending"):
        raise ValueError(
            f"branches: expected 'both', 'ascending' or 'descending', got {branches!r}"
        )
    span = float(u.max() - u.min())
    if not span > 0:
        raise ValueError("the recording's input is constant: it has no reversals")
    rtol = 0.005 * span if reversal_tol is None else float(reversal_tol)
    if not (math.isfinite(rtol) and rtol > 0):
        raise ValueError(f"reversal_tol: must be a positive number (V), got {reversal_tol!r}")
    rng = _range(y, output_range)
    idx, kind = _turning_points(u, rtol)
    comps: list[Comparison] = []
    last = idx.size - 1
    for sign, name in ((1, "ascending"), (-1, "descending")):
        if branches not in ("both", name):
            continue
        s = sign * u  # working frame: returns to maxima
        for q in range(1, last):  # P_q a reversal (not the end of the recording)
            if kind[q] != sign:
                continue
            k0, k1 = int(idx[q - 1]), int(idx[q])
            base, peak = s[k0], s[k1]
            lowest = np.inf
            for r in range(q + 2, last + 1, 2):  # the later maxima (working frame)
                lowest = min(lowest, s[int(idx[r - 1])])
                if lowest < base - rtol:
                    break  # a deeper reversal wiped out the rise to this peak: no return
                kr = int(idx[r])
                if s[kr] >= peak - rtol:
                    level = min(peak, s[kr])
                    y1 = _cross(s, y, k0, k1, level, True)
                    y2 = _cross(s, y, int(idx[r - 1]), kr, level, True)
                    if y1 is not None and y2 is not None:
                        seg = np.maximum.accumulate(s[int(idx[r - 1]) : kr + 1])
                        k2 = int(idx[r - 1]) + int(np.argmax(seg >= level))
                        comps.append(
                            Comparison(
                                name, float(sign * level), float(t[k1]), float(t[k2]), y1, y2
                            )
                        )
                    break
    comps.sort(key=lambda c: (c.t_return, c.t_first))
    return WipingOutResult(comps, rng, tol_pct)


# ------------------------------------------------------------------------------------------
# congruent minor loops
# ------------------------------------------------------------------------------------------
@dataclass
class LoopPair:
    """Two minor loops between the same input extrema, compared after a vertical shift.

    Attributes
    ----------
    low, high : float
        Common input extrema (V) (the inner ones when the loops differ slightly).
    t_a, t_b : float
        Start times (s) of the two loops.
    shift : float
        Mean vertical offset (V) of loop B over loop A (least-squares shift).
    shape_difference : float
        ``max |(y_B - y_A) - shift|`` over both branches (V).

    """

    low: float
    high: float
    t_a: float
    t_b: float
    shift: float
    shape_difference: float


@dataclass
class CongruencyResult(_PropertyTest):
    """Result of :func:`congruency_metric`.

    Attributes
    ----------
    pairs : list of LoopPair
    n_loops : int
        Minor loops found.
    output_range : float
        Range (V) of the percentages.
    tolerance : float
        Pass/fail threshold (% of ``output_range``).

    """

    pairs: list[LoopPair]
    n_loops: int
    output_range: float
    tolerance: float

    @property
    def max_difference(self) -> float:
        """Largest shape difference (V); 0 without pairs."""
        return max((p.shape_difference for p in self.pairs), default=0.0)

    @property
    def _tested(self) -> bool:
        return bool(self.pairs)

    def table(self) -> str:
        """Format the loop pairs as text."""
        lines = [
            f"congruent minor loop test: {self.n_loops} minor loops, {len(self.pairs)} "
            f"comparable pairs; max shape difference {self.max_difference:.4g} V = "
            f"{self.max_pct:.3f} % of {self.output_range:.4g} V -> "
            + self._verdict("no comparable loop pairs in this recording"),
            f"{'low (V)':>9} {'high (V)':>9} {'tA (s)':>9} {'tB (s)':>9} {'shift (V)':>10} "
            f"{'shape (V)':>10} {'shape %':>8}",
        ]
        for p in self.pairs:
            lines.append(
                f"{p.low:>9.4g} {p.high:>9.4g} {p.t_a:>9.4g} {p.t_b:>9.4g} "
                f"{p.shift:>10.4g} {p.shape_difference:>10.4g} "
                f"{100 * p.shape_difference / self.output_range:>8.3f}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            **self._summary(),
            "n_loops": self.n_loops,
            "pairs": [dict(p.__dict__) for p in self.pairs],
        }


@dataclass
class MinorLoop:
    """A minor loop found by :func:`minor_loops`: sample ranges of its two branches.

    Attributes
    ----------
    low, high : float
        Its input extrema (V).
    t0 : float
        Time (s) of its first reversal.
    rise, fall : (int, int)
        Sample ranges ``[i0, i1]`` of the rising branch ``low -> high`` and of the falling
        branch ``high -> low``.

    """

    low: float
    high: float
    t0: float
    rise: tuple[int, int]
    fall: tuple[int, int]


def minor_loops(
    t: NDArray[np.float64], u: NDArray[np.float64], reversal_tol: float
) -> list[MinorLoop]:
    """Find the minor loops of an input (thesis §3.2.2).

    A minor loop is a reversal at one input extreme, a branch to the other extreme and a
    branch back through the first (``high -> low -> high`` or ``low -> high -> low``; the
    second branch may continue beyond, and the loop closes where it passes the first extreme
    again).  Reversals count when the input moves back by more than ``reversal_tol`` (V).
    """
    idx, kind = _turning_points(u, reversal_tol)
    loops: list[MinorLoop] = []
    for q in range(2, idx.size - 1):  # P_{q-1} and P_q both reversals, P_{q+1} follows
        k0, k1, k2 = int(idx[q - 1]), int(idx[q]), int(idx[q + 1])
        first, turn, nxt = u[k0], u[k1], u[k2]
        if kind[q] < 0:  # high (k0) -> low (k1) -> back up through high
            if nxt < first - reversal_tol:
                continue
            lv = min(first, nxt)
            back = k1 + int(np.argmax(np.maximum.accumulate(u[k1 : k2 + 1]) >= lv))
            loops.append(MinorLoop(float(turn), float(first), float(t[k0]), (k1, back), (k0, k1)))
        else:  # low (k0) -> high (k1) -> back down through low
            if nxt > first + reversal_tol:
                continue
            lv = max(first, nxt)
            back = k1 + int(np.argmax(np.minimum.accumulate(u[k1 : k2 + 1]) <= lv))
            loops.append(MinorLoop(float(first), float(turn), float(t[k0]), (k0, k1), (k1, back)))
    return loops


def comparable_loops(loops: Sequence[MinorLoop], match_tol: float) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of loops whose extrema agree within ``match_tol`` (V).

    Each loop is paired with the first earlier loop between the same extrema (whose inner
    extrema still leave a range between them).  For a Preisach system such loops are
    congruent: equal up to a vertical shift (Mayergoyz's congruency property).
    """
    pairs = []
    for j, B in enumerate(loops):
        for i in range(j):
            A = loops[i]
            if abs(A.low - B.low) > match_tol or abs(A.high - B.high) > match_tol:
                continue
            if max(A.low, B.low) < min(A.high, B.high):
                pairs.append((i, j))
                break
    return pairs


def congruency_metric(
    recording: SampledData,
    *,
    tolerance: float = 5.0,
    reversal_tol: float | None = None,
    match_tol: float | None = None,
    points: int = 101,
    output_range: float | None = None,
) -> CongruencyResult:
    """Congruent-minor-loop test of a recording (thesis §3.2.2, Figs 3.13-3.16).

    A *minor loop* is a reversal at one input extreme, a branch to the other extreme and a
    branch back through the first (``high -> low -> high`` or ``low -> high -> low``; the second
    branch may continue beyond).  Two loops are *comparable* when their extrema agree within
    ``match_tol``.  For a Preisach system comparable loops are congruent: the outputs of their
    rising branches (and of their falling branches) differ by one constant.  For every pair the
    rising and falling branches are read on ``points`` common input values between the inner
    extrema, the least-squares vertical shift (the mean difference) is removed, and the largest
    remaining difference is the shape difference.

    Parameters
    ----------
    recording : Recording
        Any object with ``t``, ``u``, ``y`` (s, V, V).
    tolerance : float
        Pass if every shape difference is within this percentage of the output range.
    reversal_tol : float, optional
        Hysteresis (V) of the turning-point detector; default 0.5 % of the input range.
    match_tol : float, optional
        How close (V) the extrema of two loops must be; default ``2 * reversal_tol``.
    points : int
        Input values per branch at which the loops are compared.
    output_range : float, optional
        Range (V) for the percentages; default the recording's output range.

    Returns
    -------
    CongruencyResult

    """
    t, u, y = _arrays(recording)
    tol_pct = _check_tolerance(tolerance)
    span = float(u.max() - u.min())
    if not span > 0:
        raise ValueError("the recording's input is constant: it has no minor loops")
    rtol = 0.005 * span if reversal_tol is None else float(reversal_tol)
    if not (math.isfinite(rtol) and rtol > 0):
        raise ValueError(f"reversal_tol: must be a positive number (V), got {reversal_tol!r}")
    mtol = 2.0 * rtol if match_tol is None else float(match_tol)
    if not (math.isfinite(mtol) and mtol >= 0):
        raise ValueError(f"match_tol: must be a non-negative number (V), got {match_tol!r}")
    if int(points) < 3:
        raise ValueError(f"points: need at least 3, got {points!r}")
    rng = _range(y, output_range)
    loops = minor_loops(t, u, rtol)
    pairs: list[LoopPair] = []
    for i, j in comparable_loops(loops, mtol):
        A, B = loops[i], loops[j]
        lo, hi = max(A.low, B.low), min(A.high, B.high)
        grid = np.linspace(lo, hi, int(points))
        parts = []
        for rising in (True, False):
            ra = A.rise if rising else A.fall
            rb = B.rise if rising else B.fall
            d = _branch_read(u, y, rb[0], rb[1], grid, rising) - _branch_read(
                u, y, ra[0], ra[1], grid, rising
            )
            parts.append(d[np.isfinite(d)])
        dd = np.concatenate(parts)
        if dd.size < 2:
            continue
        shift = float(np.mean(dd))
        pairs.append(LoopPair(lo, hi, A.t0, B.t0, shift, float(np.max(np.abs(dd - shift)))))
    return CongruencyResult(pairs, len(loops), rng, tol_pct)
