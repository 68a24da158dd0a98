r"""Identification of a rate-dependent Preisach model from recordings at several rates.

The model (:mod:`preisach.rate_model`) is ``y_t = sum_k b_k(v_t) Gamma_k(psi_t)``.  For a given
input history the boundary ``psi_t`` and the filtered rate ``v_t`` are known, so every sample
is linear in the stacked tables:

    ``y_t = sum_k b_k(v_t) r_t . theta_k``

with ``r_t`` the Everett-regressor row of the classical least squares
(:mod:`preisach.identify.lsq`) and ``theta_k = (E_k nodes, y_min_k)``.  The normal equations of
these stacked rows are accumulated in C++ (``preisach._core.rate_normal_equations``, GIL
released) per cross-validation fold, and solved here:

* **parameters**: per table the relay masses of the grid cells ``w_k`` (``E_k = C w_k``) and
  ``y_min_k``; ``w_k >= 0`` (``mu >= 0`` at every rate) with ``nonnegative=True``;
* **smoothness in (alpha, beta)**: ``lambda_s sum_k ||R w_k||^2`` (the roughness of
  :func:`~preisach.identify.lsq.roughness_matrix`), and **smoothness across rate**:
  ``lambda_r sum_k ||R_0 (w_{k+1} - w_k)||^2 + (y_min_{k+1} - y_min_k)^2 n`` with ``R_0`` the
  identity scaled like ``R``: ``lambda_r -> infinity`` is the classical (rate-independent)
  model, ``lambda_r -> 0`` independent tables;
* both weights are dimensionless (scaled by the trace of the Gram matrix) and chosen by K-fold
  cross-validation over contiguous blocks of every recording (each fold holds a part of every
  rate), the held-out error from the fold's normal equations;
* the **rate filter's time constant** ``tau`` is chosen by the same cross-validation from a
  grid (:data:`TAUS`; the normal equations are accumulated once per ``tau``), and so is the
  **interpolation scale** between knots (``ln v`` or ``v``) when the data have rates between
  the knots (:data:`MIN_BETWEEN`); recordings only at the knots' rates cannot tell the scales
  apart, and the model then interpolates in ``v``, which the thesis's three SS15 surfaces
  support (:mod:`preisach.rate_model`).  With sweeps at two rates the scale is what decides the
  prediction at a third: a 2 Hz sweep predicted from 1 and 4 Hz sweeps of ``ss15-rate`` has
  5 mV rms error interpolating in ``v`` against 29 mV in ``ln v``
  (``scripts/rate_heldout_study.py``).

Knots: by default one per distinct rate of the recordings - the mean ``|du/dt|`` of each
recording over the samples where its input moves (``4 u_hat f`` for a full-range triangle or an
FOD sweep at ``f`` Hz, and the mean rate of a sinusoid of amplitude ``u_hat``), rates within 15 %
of each other merged (their geometric mean).  The report says which rates each recording
covers (5th/50th/95th percentiles of ``v``) and the residuals per recording and per rate band
(the samples nearest to each knot in ``ln v``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from threadpoolctl import threadpool_limits

from .. import _core
from ..initial_state import burn_in_end
from ..model import State
from ..rate_model import RATE_SCALES, RateDependentPreisachModel, RateState
from .lsq import cumulative_matrix, roughness_matrix, solve_nonnegative_qp

__all__ = ["RateIdentificationReport", "identify_rate", "recording_rates"]

#: Smoothness weights tried by cross-validation (dimensionless).
LAMBDAS_SMOOTH: tuple[float, ...] = (1e-4, 1e-2, 1.0, 1e2)
LAMBDAS_RATE: tuple[float, ...] = (1e-6, 1e-4, 1e-2, 1.0, 1e2)
#: Rate-filter time constants (s) tried by cross-validation.
TAUS: tuple[float, ...] = (0.03, 0.1, 0.25, 0.5, 1.0)
#: Fraction of the fitted samples between the knots from which the interpolation scale is
#: cross-validated (below it the data cannot tell the scales apart: ``"linear"``).
MIN_BETWEEN = 0.1
#: Largest grid identify_rate accepts (dense normal equations of K (n (n-1)/2 + 1) unknowns).
MAX_RATE_LEVELS = 41


def _rec_name(rec: Any, k: int) -> str:
    meta = getattr(rec, "metadata", {}) or {}
    return str(meta.get("experiment") or meta.get("name") or f"recording {k}")


def recording_rates(u: ArrayLike, sample_time: float, tau: float) -> NDArray[np.float64]:
    """Return the filtered rate ``v`` (V/s) after each sample of an input starting at rest."""
    uu = np.ascontiguousarray(u, dtype=float)
    if uu.ndim != 1 or uu.size == 0:
        raise ValueError("u: expected a non-empty 1-D array of input samples (V)")
    return np.asarray(_core.filter_rate(uu, float(uu[0]), 0.0, float(sample_time), float(tau)))


def _moving_rate(u: NDArray[np.float64], dt: float) -> float:
    """Mean ``|du/dt|`` (V/s) over the samples where the input moves (0 if it never does)."""
    r = np.abs(np.diff(u)) / dt
    r = r[r > 0]
    return float(np.mean(r)) if r.size else 0.0


def _default_knots(means: Sequence[float]) -> NDArray[np.float64]:
    r = sorted(float(x) for x in means if x > 0)
    if not r:
        raise ValueError("recordings: no input moves; the rates cannot be identified")
    groups: list[list[float]] = [[r[0]]]
    for x in r[1:]:
        if x <= groups[-1][0] * 1.15:
            groups[-1].append(x)
        else:
            groups.append([x])
    return np.array([math.exp(float(np.mean(np.log(g)))) for g in groups])


@dataclass
class RateIdentificationReport:
    """What :func:`identify_rate` did and how well the model fits.

    Attributes
    ----------
    knots : ndarray
        Rate knots (V/s) of the tables.
    tau : float
        Rate-filter time constant (s).
    coverage : list of dict
        Per recording: name, sample time, mean and 5th/50th/95th percentile filtered rate (V/s),
        the fraction of its fitted samples nearest to each knot, samples fitted.
    residuals : list of dict
        Per recording: rms and max residual (V) of the identified model simulated over it.
    band_residuals : list of dict
        Per knot: the rms residual (V) over all fitted samples whose rate is nearest to it (in
        ``ln v``) and how many there are - which rates the data cover and how well.
    lambdas_smooth, lambdas_rate : ndarray
        Grids tried; ``cv_rms[i, j]`` the cross-validated rms error (V) of each pair.
    chosen : (float, float)
        The pair with the lowest cross-validated error.
    fit_rms : float
        Rms residual (V) of the final fit over all fitted samples (from the normal equations).
    n_samples, n_params : int
        Samples fitted and unknowns.
    nonnegative : bool
        Whether ``mu >= 0`` was imposed on every table.
    warnings : list of str
    timings : dict
    scale : str
        Interpolation between knots, ``"log"`` or ``"linear"``.
    taus : ndarray
        Rate-filter time constants tried (s).
    scales : tuple of str
        Scales tried.
    cv_tau_scale : ndarray, shape (len(taus), len(scales))
        Cross-validated rms error (V) of each ``(tau, scale)`` at the smoothness pair of the
        first search step (see :func:`identify_rate`).
    fraction_between : float
        Fraction of the fitted samples with rates between the knots (more than 5 % from
        both): the data that tell how the model behaves between the knots.

    """

    knots: NDArray[np.float64]
    tau: float
    coverage: list[dict[str, Any]]
    residuals: list[dict[str, Any]]
    band_residuals: list[dict[str, Any]]
    lambdas_smooth: NDArray[np.float64]
    lambdas_rate: NDArray[np.float64]
    cv_rms: NDArray[np.float64]
    chosen: tuple[float, float]
    fit_rms: float
    n_samples: int
    n_params: int
    nonnegative: bool
    warnings: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    scale: str = "log"
    taus: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    scales: tuple[str, ...] = ()
    cv_tau_scale: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    fraction_between: float = float("nan")

    def summary(self) -> str:
        """Human-readable summary (several lines)."""
        lines = [
            f"rate-dependent least squares: {len(self.knots)} tables at "
            + ", ".join(f"{k:.4g}" for k in self.knots)
            + f" V/s ({self.scale} scale, rate filter tau = {self.tau:g} s), "
            f"{self.n_samples} samples, {self.n_params} unknowns, mu >= 0: {self.nonnegative}",
        ]
        if self.cv_tau_scale.size > 1:
            cells = ", ".join(
                f"{t:g} s {sc} {self.cv_tau_scale[i, j] * 1e3:.3f}"
                for i, t in enumerate(self.taus)
                for j, sc in enumerate(self.scales)
            )
            lines.append(f"cross-validated rms (mV) per tau and scale: {cells}")
        if math.isfinite(self.fraction_between):
            if len(self.scales) > 1:
                how = "scale cross-validated"
            elif self.fraction_between < MIN_BETWEEN:
                how = f"{self.scale} scale: too few to cross-validate it"
            else:
                how = f"{self.scale} scale as given"
            lines.append(
                f"samples with rates between the knots: {100 * self.fraction_between:.1f} % ({how})"
            )
        lines += [
            f"cross-validation chose lambda_smooth = {self.chosen[0]:g}, lambda_rate = "
            f"{self.chosen[1]:g} (cv rms {float(np.min(self.cv_rms)) * 1e3:.3f} mV); fit rms "
            f"{self.fit_rms * 1e3:.3f} mV",
            "rates covered (filtered |du/dt|, V/s):",
        ]
        for c in self.coverage:
            lines.append(
                f"  {c['name']}: median {c['rate_p50']:.4g} (5-95 %: {c['rate_p5']:.4g} .. "
                f"{c['rate_p95']:.4g}), mean {c['rate_mean']:.4g}"
            )
        lines.append("residuals per recording (V):")
        for r in self.residuals:
            lines.append(f"  {r['name']}: rms {r['rms']:.4g}, max {r['max']:.4g}")
        lines.append("residuals per rate band (samples nearest each knot):")
        for b in self.band_residuals:
            rms = "no data" if b["n"] == 0 else f"rms {b['rms']:.4g} V"
            lines.append(f"  {b['knot']:.4g} V/s: {b['n']} samples, {rms}")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dictionary."""
        return {
            "method": "rate",
            "knots": [float(x) for x in self.knots],
            "tau": self.tau,
            "scale": self.scale,
            "taus": [float(x) for x in self.taus],
            "scales": list(self.scales),
            "cv_tau_scale": self.cv_tau_scale.tolist(),
            "fraction_between": self.fraction_between,
            "coverage": self.coverage,
            "residuals": self.residuals,
            "band_residuals": self.band_residuals,
            "lambdas_smooth": [float(x) for x in self.lambdas_smooth],
            "lambdas_rate": [float(x) for x in self.lambdas_rate],
            "cv_rms": self.cv_rms.tolist(),
            "chosen": list(self.chosen),
            "fit_rms": self.fit_rms,
            "n_samples": self.n_samples,
            "n_params": self.n_params,
            "nonnegative": self.nonnegative,
            "warnings": list(self.warnings),
            "timings": dict(self.timings),
        }


def _solve(
    H: NDArray[np.float64], g: NDArray[np.float64], nonneg: NDArray[np.bool_] | None
) -> NDArray[np.float64]:
    """Minimise ``x^T H x / 2 - g^T x`` with ``x[nonneg] >= 0`` (the rest free)."""
    m = H.shape[0]
    H = H.copy()
    H[np.diag_indices(m)] += 1e-12 * float(np.trace(H)) / m
    if nonneg is None:
        try:
            return np.asarray(cho_solve(cho_factor(H, check_finite=False), g, check_finite=False))
        except LinAlgError:
            return np.asarray(np.linalg.lstsq(H, g, rcond=None)[0])
    # eliminate the free variables (the offsets y_min_k) by their Schur complement
    fr = ~nonneg
    A = H[np.ix_(nonneg, nonneg)]
    B = H[np.ix_(nonneg, fr)]
    D = H[np.ix_(fr, fr)]
    Dinv_Bt = np.linalg.solve(D, B.T)
    Dinv_gf = np.linalg.solve(D, g[fr])
    Hr = A - B @ Dinv_Bt
    gr = g[nonneg] - B @ Dinv_gf
    Hr = 0.5 * (Hr + Hr.T)
    w, _, _, _ = solve_nonnegative_qp(Hr, gr)
    x = np.empty(m)
    x[nonneg] = w
    x[fr] = Dinv_gf - Dinv_Bt @ w
    return x


def _fraction_between_knots(vs: Sequence[NDArray[np.float64]], knots: NDArray[np.float64]) -> float:
    """Fraction of the samples whose rate lies between two knots, more than 5 % from both."""
    v = np.concatenate(list(vs)) if vs else np.zeros(0)
    if v.size == 0:
        return 0.0
    inside = np.zeros(v.size, dtype=bool)
    for a, b in zip(knots[:-1], knots[1:]):
        inside |= (v > 1.05 * a) & (v < b / 1.05)
    return float(np.mean(inside))


def _grid(
    name: str, value: float | Sequence[float] | None, default: Sequence[float]
) -> NDArray[np.float64]:
    g = np.atleast_1d(np.asarray(default if value is None else value, dtype=float))
    if g.size == 0 or g.ndim != 1 or np.any(~np.isfinite(g)) or np.any(g < 0):
        raise ValueError(f"{name}: need one value or a grid of finite values >= 0, got {value!r}")
    return g


def _cv_errors(
    Gx: NDArray[np.float64],
    bx: NDArray[np.float64],
    yy: NDArray[np.float64],
    pens: Sequence[NDArray[np.float64]],
    mask: NDArray[np.bool_] | None,
) -> NDArray[np.float64]:
    """Held-out sum of squares (V^2, summed over folds) of each penalty, fold by fold."""
    Gtot, btot = Gx.sum(axis=0), bx.sum(axis=0)
    out = np.zeros(len(pens))
    for i, pen in enumerate(pens):
        for f in range(Gx.shape[0]):
            x = _solve(Gtot - Gx[f] + pen, btot - bx[f], mask)
            out[i] += max(float(x @ Gx[f] @ x - 2.0 * x @ bx[f] + yy[f]), 0.0)
    return out


def identify_rate(
    recordings: Sequence[Any],
    levels: ArrayLike | int = 21,
    *,
    knots: ArrayLike | None = None,
    tau: float | Sequence[float] | None = None,
    scale: str | None = None,
    folds: int = 4,
    lambdas_smooth: Sequence[float] = LAMBDAS_SMOOTH,
    lambdas_rate: Sequence[float] = LAMBDAS_RATE,
    nonnegative: bool = True,
    u_range: tuple[float, float] | None = None,
    name: str = "",
) -> tuple[RateDependentPreisachModel, RateIdentificationReport]:
    """Identify a rate-dependent model from two or more recordings at different rates.

    Parameters
    ----------
    recordings : sequence of Recording
        Each with ``u`` (V), ``y`` (V) and a uniform sample time (``rec.sample_time``).  Any
        excitation: FOD sweeps, triangles, sines, noise.  Every recording is simulated from
        negative saturation and at rest (filtered rate 0); samples before its burn-in end (the
        first saturation, or the visit of both its own extremes,
        :func:`~preisach.identify.lsq.burn_in_end`) and before ``3 tau`` (the smallest ``tau``
        tried) are not fitted.
    levels : int or array_like
        Grid of the tables: a number of levels over ``u_range`` or the levels (V).  At most
        :data:`MAX_RATE_LEVELS`.
    knots : array_like, optional
        Rate knots (V/s).  Default: one per distinct mean rate of the recordings (module doc).
    tau : float or sequence of float, optional
        Rate-filter time constant (s): one value is used as given; a grid (default
        :data:`TAUS`) is searched by cross-validation.
    scale : {"log", "linear"}, optional
        Interpolation between knots (:mod:`preisach.rate_model`).  Default: chosen by
        cross-validation when at least :data:`MIN_BETWEEN` of the fitted samples have rates
        between the knots; otherwise ``"linear"``, which the thesis's three surfaces support
        (recordings at the knots' rates only cannot tell the scales apart).
    folds : int
        Cross-validation folds (contiguous blocks of every recording).
    lambdas_smooth, lambdas_rate : sequence of float
        Smoothness weights in (alpha, beta) and across rate tried by cross-validation.
    nonnegative : bool
        Impose ``mu >= 0`` on every table.
    u_range : (float, float), optional
        Input range (V) for a number of ``levels``; default the recordings' input range.
    name : str
        Name of the model.

    Returns
    -------
    model : RateDependentPreisachModel
    report : RateIdentificationReport

    Raises
    ------
    ValueError
        Fewer than two distinct rates, too many levels, bad parameters or recordings.

    Notes
    -----
    The search: the smoothness pair on the first ``(tau, scale)`` candidate (the middle
    ``tau``, linear), then every ``(tau, scale)`` at that pair, then the smoothness pair again
    at the chosen ``(tau, scale)``; every error is the K-fold held-out error of the same
    samples.

    """
    t_start = time.perf_counter()
    recs = list(recordings)
    if len(recs) < 1:
        raise ValueError("recordings: need at least one recording")
    names = [_rec_name(r, k) for k, r in enumerate(recs)]
    if isinstance(folds, bool) or int(folds) != folds or folds < 2:
        raise ValueError(f"folds: need an integer >= 2 for cross-validation, got {folds!r}")
    folds = int(folds)
    taus = _grid("tau", tau, TAUS)
    if scale is not None and scale not in RATE_SCALES:
        raise ValueError(f"scale: expected one of {RATE_SCALES} or None, got {scale!r}")
    us = [np.ascontiguousarray(r.u, dtype=float) for r in recs]
    ys = [np.ascontiguousarray(r.y, dtype=float) for r in recs]
    dts = [float(r.sample_time) for r in recs]
    for nm, u, y, dt in zip(names, us, ys, dts):
        if u.ndim != 1 or u.shape != y.shape or u.size < 2:
            raise ValueError(f"{nm}: need 1-D u and y of the same length (>= 2 samples)")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise ValueError(f"{nm}: u and y must be finite")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"{nm}: sample time must be positive, got {dt!r}")
    if np.ndim(levels) == 0:
        nl = int(levels)  # type: ignore[arg-type]
        lo, hi = (
            (float(min(u.min() for u in us)), float(max(u.max() for u in us)))
            if u_range is None
            else (float(u_range[0]), float(u_range[1]))
        )
        if not hi > lo:
            raise ValueError(f"u_range: need u_min < u_max, got ({lo}, {hi})")
        lv = np.linspace(lo, hi, nl)
    else:
        lv = np.asarray(levels, dtype=float)
    n = lv.size
    if n < 3 or n > MAX_RATE_LEVELS:
        raise ValueError(f"levels: need 3 .. {MAX_RATE_LEVELS} levels, got {n}")
    if np.any(np.diff(lv) <= 0):
        raise ValueError("levels: must be strictly increasing")
    lo, hi = float(lv[0]), float(lv[-1])
    ls = np.asarray(list(lambdas_smooth), dtype=float)
    lr = np.asarray(list(lambdas_rate), dtype=float)
    if ls.size == 0 or lr.size == 0 or np.any(ls < 0) or np.any(lr < 0):
        raise ValueError("lambdas_smooth, lambdas_rate: need non-empty grids of values >= 0")
    means = [_moving_rate(np.clip(u, lo, hi), dt) for u, dt in zip(us, dts)]
    kn = _default_knots(means) if knots is None else np.atleast_1d(np.asarray(knots, float))
    if kn.size < 2:
        raise ValueError(
            "recordings: need two or more distinct rates (mean input rates "
            + ", ".join(f"{m:.4g}" for m in means)
            + " V/s); use the classical identify for one rate"
        )
    if np.any(~np.isfinite(kn)) or np.any(kn <= 0) or np.any(np.diff(kn) <= 0):
        raise ValueError("knots: need strictly increasing positive rates (V/s)")
    K = kn.size
    p1 = n * (n - 1) // 2 + 1
    s_neg = State.negative_saturation(lo, hi)
    # the same samples for every candidate: after the burn-in and 3 x the smallest tau
    folds_of: list[NDArray[np.int32]] = []
    fitted_from: list[int] = []
    for nm, u, dt in zip(names, us, dts):
        start, _ = burn_in_end(u, lo, hi)
        start = max(start, int(math.ceil(3.0 * float(taus.min()) / dt)))
        if start >= u.size - folds:
            raise ValueError(
                f"{nm}: too few samples after the burn-in ({u.size - start}) for {folds} folds"
            )
        fold = -np.ones(u.size, dtype=np.int32)
        k = np.arange(u.size - start)
        fold[start:] = (k * folds // k.size).astype(np.int32)
        folds_of.append(fold)
        fitted_from.append(start)
    # the scale decides only between knots: cross-validate it where the data are there
    between = _fraction_between_knots(
        [
            recording_rates(np.clip(u, lo, hi), dt, float(taus[len(taus) // 2]))[st:]
            for u, dt, st in zip(us, dts, fitted_from)
        ],
        kn,
    )
    if scale is not None:
        scales: tuple[str, ...] = (scale,)
    elif between >= MIN_BETWEEN:
        scales = ("linear", "log")
    else:
        scales = ("linear",)
    # to cell masses: theta_k = T x_k, T = blockdiag(C, 1)
    C = cumulative_matrix(n)
    m = C.shape[1]
    T1 = np.zeros((p1, m + 1))
    T1[: p1 - 1, :m] = C
    T1[p1 - 1, m] = 1.0
    T = np.kron(np.eye(K), T1)
    t_eq = 0.0
    cache: dict[tuple[float, str], tuple[Any, ...]] = {}

    def equations(tv: float, sc: str) -> tuple[Any, ...]:
        """Per-fold normal equations in cell masses for one (tau, scale), cached."""
        nonlocal t_eq
        key = (tv, sc)
        if key not in cache:
            t0 = time.perf_counter()
            G = np.zeros((folds, K * p1, K * p1))
            b = np.zeros((folds, K * p1))
            yy = np.zeros(folds)
            cnt = np.zeros(folds, dtype=np.int64)
            for u, y, dt, fold in zip(us, ys, dts, folds_of):
                Gr, br, yr, _, cr, _, _ = _core.rate_normal_equations(
                    lv, s_neg, u, y, fold, folds, [float(x) for x in kn], tv, dt, 0.0, "clamp", sc
                )
                G += Gr
                b += br
                yy += yr
                cnt += cr
            Gx = np.einsum("ip,fij,jq->fpq", T, G, T, optimize=True)
            bx = np.einsum("ip,fi->fp", T, b)
            cache[key] = (Gx, bx, yy, cnt)
            t_eq += time.perf_counter() - t0
        return cache[key]

    with threadpool_limits(limits=1, user_api="blas"):
        R = roughness_matrix(lv)
        Ps1 = R.T @ R
        Pint = np.zeros((K * (m + 1), K * (m + 1)))
        for kk in range(K):
            sl = slice(kk * (m + 1), kk * (m + 1) + m)
            Pint[sl, sl] = Ps1
        # across rate: first differences of the masses (scaled like R) and of the offsets
        rscale = float(np.trace(Ps1)) / m
        D = np.zeros(((K - 1) * (m + 1), K * (m + 1)))
        for kk in range(K - 1):
            rows = slice(kk * (m + 1), (kk + 1) * (m + 1))
            D[rows, kk * (m + 1) : (kk + 1) * (m + 1)] = -np.eye(m + 1)
            D[rows, (kk + 1) * (m + 1) : (kk + 2) * (m + 1)] = np.eye(m + 1)
        Prate = D.T @ D * rscale
        nonneg = np.ones(K * (m + 1), dtype=bool)
        nonneg[m :: m + 1] = False  # y_min_k free
        mask = nonneg if nonnegative else None

        def penalties(Gx: NDArray[np.float64]) -> list[NDArray[np.float64]]:
            trG = float(np.trace(Gx.sum(axis=0)))
            s_int = trG / max(float(np.trace(Pint)), 1e-300)
            s_rate = trG / max(float(np.trace(Prate)), 1e-300)
            return [a * s_int * Pint + c * s_rate * Prate for a in ls for c in lr]

        cands = [(float(tv), sc) for tv in taus for sc in scales]
        first = (float(taus[len(taus) // 2]), scales[0])
        n_fit = 0
        # 1. smoothness pair at the first candidate
        Gx, bx, yy, cnt = equations(*first)
        n_fit = int(cnt.sum())
        sse = _cv_errors(Gx, bx, yy, penalties(Gx), mask)
        pair = int(np.argmin(sse))
        # 2. every (tau, scale) at that pair
        cv_ts = np.zeros((taus.size, len(scales)))
        for i, tv in enumerate(taus):
            for j, sc in enumerate(scales):
                Gx, bx, yy, _ = equations(float(tv), sc)
                cv_ts[i, j] = math.sqrt(
                    _cv_errors(Gx, bx, yy, [penalties(Gx)[pair]], mask)[0] / max(n_fit, 1)
                )
        # ties go to the earlier candidate: the linear scale, the smaller tau
        best = int(np.argmin(np.round(cv_ts.ravel(), 12)))
        tau_c, scale_c = cands[best]
        # 3. the smoothness pair again at the chosen (tau, scale)
        Gx, bx, yy, cnt = equations(tau_c, scale_c)
        pens = penalties(Gx)
        cv = np.sqrt(_cv_errors(Gx, bx, yy, pens, mask) / max(n_fit, 1)).reshape(ls.size, lr.size)
        bi, bj = np.unravel_index(int(np.argmin(cv)), cv.shape)
        pen = pens[int(bi) * lr.size + int(bj)]
        Gtot, btot = Gx.sum(axis=0), bx.sum(axis=0)
        x = _solve(Gtot + pen, btot, mask)
        sse_fit = float(x @ Gtot @ x - 2.0 * x @ btot + yy.sum())
    t2 = time.perf_counter()
    warnings: list[str] = []
    for axis, grid, idx in (("lambda_smooth", ls, bi), ("lambda_rate", lr, bj)):
        if grid.size > 1 and idx in (0, grid.size - 1):
            edge = "smallest" if idx == 0 else "largest"
            warnings.append(f"cross-validation chose the {edge} {axis} tried ({grid[idx]:g})")
    if taus.size > 1 and tau_c in (float(taus.min()), float(taus.max())):
        edge = "smallest" if tau_c == float(taus.min()) else "largest"
        warnings.append(f"cross-validation chose the {edge} tau tried ({tau_c:g} s)")
    tables = []
    for kk in range(K):
        xk = x[kk * (m + 1) : (kk + 1) * (m + 1)]
        W = np.zeros((n - 1, n - 1))
        W[np.tril_indices(n - 1)] = xk[:m]
        tables.append(_core.EverettTable.from_weights(lv, W, float(xk[m])))
    core = _core.RateDependentModel(tables, [float(v) for v in kn], tau_c, scale_c)
    model = RateDependentPreisachModel(
        core,
        name=name,
        metadata={
            "source": "identify_rate",
            "recordings": names,
            "lambda_smooth": float(ls[bi]),
            "lambda_rate": float(lr[bj]),
            "tau": tau_c,
            "scale": scale_c,
        },
    )
    # coverage and residuals: simulate the model over every recording
    vs = [recording_rates(np.clip(u, lo, hi), dt, tau_c) for u, dt in zip(us, dts)]
    coverage, residuals = [], []
    band_sq = np.zeros(K)
    band_n = np.zeros(K, dtype=np.int64)
    lk = np.log(kn)
    for nm, u, y, dt, v, start in zip(names, us, ys, dts, vs, fitted_from):
        sim = model.simulate(u, RateState(s_neg, 0.0), sample_time=dt)
        e = (y - sim.output)[start:]
        vv = v[start:]
        near = np.argmin(np.abs(np.log(np.maximum(vv, 1e-300))[:, None] - lk[None, :]), axis=1)
        np.add.at(band_sq, near, e * e)
        np.add.at(band_n, near, 1)
        coverage.append(
            {
                "name": nm,
                "sample_time": dt,
                "rate_mean": float(np.mean(vv)),
                "rate_p5": float(np.percentile(vv, 5)),
                "rate_p50": float(np.percentile(vv, 50)),
                "rate_p95": float(np.percentile(vv, 95)),
                "fraction_near_knot": [float(np.mean(near == q)) for q in range(K)],
                "n_fitted": int(vv.size),
            }
        )
        residuals.append(
            {"name": nm, "rms": float(np.sqrt(np.mean(e * e))), "max": float(np.max(np.abs(e)))}
        )
    bands = [
        {
            "knot": float(kn[q]),
            "n": int(band_n[q]),
            "rms": float(np.sqrt(band_sq[q] / band_n[q])) if band_n[q] else float("nan"),
        }
        for q in range(K)
    ]
    for bnd in bands:
        if bnd["n"] == 0:
            warnings.append(
                f"no fitted sample has a rate near the knot {bnd['knot']:.4g} V/s; its table "
                "is set by the smoothness across rate only"
            )
    report = RateIdentificationReport(
        knots=kn,
        tau=tau_c,
        coverage=coverage,
        residuals=residuals,
        band_residuals=bands,
        lambdas_smooth=ls,
        lambdas_rate=lr,
        cv_rms=cv,
        chosen=(float(ls[bi]), float(lr[bj])),
        fit_rms=math.sqrt(max(sse_fit, 0.0) / max(n_fit, 1)),
        n_samples=n_fit,
        n_params=int(K * (m + 1)),
        nonnegative=bool(nonnegative),
        warnings=warnings,
        timings={
            "normal_equations": t_eq,
            "solve": t2 - t_start - t_eq,
            "total": time.perf_counter() - t_start,
        },
        scale=scale_c,
        taus=taus,
        scales=scales,
        cv_tau_scale=cv_ts,
        fraction_between=between,
    )
    return model, report


def run_cli(args: Any, recs: Sequence[Any], write_json: Any) -> int:
    """``preisach identify ... --method rate``: identify, save, print the report (0 on success)."""
    from pathlib import Path

    if args.project or args.y_min_source is not None:
        raise ValueError("--project and --y-min-source do not apply to --method rate")
    if args.delay != 0:
        raise ValueError("--delay is not supported by --method rate; trim the recordings instead")
    if args.initial_state != "burn-in":
        raise ValueError("--method rate simulates every recording from its burn-in only")
    if args.plot:
        raise ValueError("--plot is not available for --method rate")
    model, report = identify_rate(
        recs, 21 if args.levels is None else args.levels, folds=args.folds, name=args.name
    )
    out = Path(args.output)
    if out.parent and not out.parent.exists():
        raise OSError(f"{out.parent}: output folder does not exist")
    model.save(out)
    print(report.summary())
    print(f"wrote {out}")
    write_json(args.json, report.to_dict())
    return 0
