"""Sensor drift as a smooth function of time per recording, its roughness chosen by held-out time.

A sensor's offset wanders with time for reasons the input does not control (temperature, a
charge amplifier's leakage, a strain gauge's creep of its own).  In a lab that wander can be
a ramp, a slow thermal cycle, a random walk or a 1/f wander; no one law covers them, so the
drift of each recording is a P-spline in time: a cubic B-spline whose coefficients are
penalised by their **first** differences (the random-walk prior: between data the curve
stays where it was, so a held-out stretch at a recording's start or end is predicted by the
level next to it, not by extrapolating a local slope over a second or more).

How rough the curve may be is not fixed: per recording the knot spacing is chosen among a
few (a single interval per recording up to a knot every :data:`MIN_SPACING` seconds), and
one penalty weight for all recordings among :data:`SMOOTHINGS`, by cross-validation **held
out in time**, the way the drift is scored: the curve fitted on the recording's blocks of one
parity predicts the blocks of the other (a random split of the samples would let the curve
follow anything slower than the sample rate).  The residual it is chosen on is the refitted classical base's, on the recording's usable
samples: like the initial history, one discrete choice per recording made with its
measured output (:meth:`~preisach.diagnose.context.Context.choose_drift_roughness`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import interpolate

Array = NDArray[np.float64]

__all__ = [
    "DRIFT_SMOOTHING",
    "MAX_INTERVALS",
    "MIN_SPACING",
    "ROUGHER_GAIN",
    "SMOOTHINGS",
    "bspline_basis",
    "choose_roughness",
    "choose_spacing",
    "penalised_system",
    "spacing_options",
]

#: Weight of the first-difference penalty, relative to the mean diagonal of ``A^T A``.
DRIFT_SMOOTHING: float = 0.3
#: Smallest knot spacing (s) a drift curve may get.
MIN_SPACING: float = 0.5
#: Most knot intervals per recording (bounds the dense basis of long recordings).
MAX_INTERVALS: int = 40
#: Relative drop of the held-out error a rougher spacing must bring to be preferred.
ROUGHER_GAIN: float = 0.0
#: Penalty weights tried (:func:`choose_roughness`).
SMOOTHINGS: tuple[float, ...] = (0.03, 0.1, 0.3, 1.0)


def bspline_basis(t: Array, spacing: float) -> Array:
    """Cubic B-spline basis over ``t`` (s, from the recording's start), knots every ``spacing``."""
    t = np.asarray(t, dtype=float) - float(t[0])
    T = max(float(t[-1]), 1e-9)
    n_int = max(1, int(math.ceil(T / spacing - 1e-9)))
    inner = np.linspace(0.0, T, n_int + 1)
    knots = np.concatenate([[0.0] * 3, inner, [T] * 3])
    return np.asarray(
        interpolate.BSpline.design_matrix(np.clip(t, 0.0, T), knots, 3).toarray(), dtype=float
    )


def penalised_system(A: Array, smoothing: float = DRIFT_SMOOTHING) -> tuple[Array, float]:
    """Penalised normal matrix ``A^T A + lam D^T D`` (first differences) and its effective dof.

    ``lam`` is ``smoothing`` times the mean diagonal of ``A^T A`` (so the penalty does not
    depend on how many samples a column covers).
    """
    m = A.shape[1]
    D = np.diff(np.eye(m), 1, axis=0) if m > 1 else np.zeros((0, m))
    AtA = A.T @ A
    lam = smoothing * max(float(np.trace(AtA)) / max(m, 1), 1e-300)
    G = AtA + lam * (D.T @ D) + 1e-9 * lam * np.eye(m)
    dof = float(np.trace(np.linalg.solve(G, AtA)))
    return G, dof


def spacing_options(duration: float) -> list[float]:
    """Knot spacings (s) tried for a recording of ``duration`` seconds, smoothest first.

    One interval over the whole recording, then halved, down to :data:`MIN_SPACING` (and no
    more than :data:`MAX_INTERVALS` intervals).
    """
    T = max(float(duration), 1e-9)
    floor = max(MIN_SPACING, T / MAX_INTERVALS)
    out = [T]
    while out[-1] / 2 >= floor - 1e-12:
        out.append(out[-1] / 2)
    return out


def _fit(A: Array, r: Array, smoothing: float) -> Array:
    G, _ = penalised_system(A, smoothing)
    return np.asarray(np.linalg.solve(G, A.T @ r), dtype=float)


def choose_spacing(
    t: Array,
    res: Array,
    usable: NDArray[np.bool_],
    parity: NDArray[np.int64],
    smoothing: float = DRIFT_SMOOTHING,
) -> tuple[float, dict[float, float]]:
    """Knot spacing (s) of one recording's drift chosen by held-out time blocks.

    Parameters
    ----------
    t : array
        Sample times (s).
    res : array
        Residual (V) the drift would explain.
    usable : bool array
        Samples that count.
    parity : int array
        Block parity (0/1) of every sample: the curve fitted on one parity predicts the other.
    smoothing : float
        Penalty weight (:func:`penalised_system`).

    Returns
    -------
    spacing : float
        The smoothest spacing within :data:`ROUGHER_GAIN` of the best held-out error.
    sse : dict
        Held-out sum of squares (V^2) per spacing tried.
    """
    table = _heldout_table(t, res, usable, parity, [smoothing])
    return _smoothest_best(table[smoothing])


def choose_roughness(
    recordings: list[tuple[Array, Array, NDArray[np.bool_], NDArray[np.int64]]],
    smoothings: tuple[float, ...] = SMOOTHINGS,
) -> tuple[float, list[float], float]:
    """Penalty weight (one for all) and knot spacing per recording, by held-out time blocks.

    ``recordings`` holds ``(t, res, usable, parity)`` per recording (see
    :func:`choose_spacing`).  For every penalty weight in ``smoothings`` each recording gets
    its best spacing; the weight with the lowest held-out error summed over the recordings is
    chosen.  Returns the weight, the spacings and that held-out sum of squares (V^2).
    """
    tables = [_heldout_table(*rec, smoothings) for rec in recordings]
    best: tuple[float, list[float], float] | None = None
    for lam in smoothings:
        picks = [_smoothest_best(tb[lam]) for tb in tables]
        total = float(sum(sse[sp] for sp, sse in picks))
        if best is None or total < best[2]:
            best = (lam, [sp for sp, _ in picks], total)
    assert best is not None
    return best


def _heldout_table(
    t: Array,
    res: Array,
    usable: NDArray[np.bool_],
    parity: NDArray[np.int64],
    smoothings: tuple[float, ...] | list[float],
) -> dict[float, dict[float, float]]:
    """Held-out sum of squares per penalty weight and knot spacing (other parity predicts)."""
    usable = np.asarray(usable, dtype=bool)
    out: dict[float, dict[float, float]] = {lam: {} for lam in smoothings}
    for s in spacing_options(float(t[-1] - t[0])):
        B = bspline_basis(t, s)
        for lam in smoothings:
            tot, n = 0.0, 0
            for p in (0, 1):
                tr = usable & (parity != p)
                te = usable & (parity == p)
                if not tr.any() or not te.any():
                    continue
                e = res[te] - B[te] @ _fit(B[tr], res[tr], lam)
                tot += float(e @ e)
                n += int(te.sum())
            out[lam][s] = tot if n else math.inf
    return out


def _smoothest_best(sse: dict[float, float]) -> tuple[float, dict[float, float]]:
    """Return the smoothest spacing unless a rougher one lowers the error enough."""
    opts = sorted(sse, reverse=True)
    chosen = opts[0]
    for s in opts[1:]:
        if sse[s] < (1.0 - ROUGHER_GAIN) * sse[chosen]:
            chosen = s
    return chosen, sse
