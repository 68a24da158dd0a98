"""Least-squares identification of the Everett table from arbitrary recordings.

The output of a Preisach model is linear in its Everett table: for a given input history every
sample is ``y_t = r_t . theta`` with ``theta = (E(i, j) for j < i, y_min)`` (see
``cpp/include/preisach/regressor.hpp``).  So the table can be fitted to *any* recording - sines,
noise, minor loops, FOD sweeps - using every sample, not only the grid crossings of FOD curves.

Formulation
-----------
* **Parameters.**  The relay masses ``w`` of the grid cells (``n (n - 1) / 2`` of them: the
  off-diagonal cells and the diagonal half-cells that hold kappa) and the output at negative
  saturation ``y_min`` (V, free).  The Everett table is ``E = C w`` (cumulative sums over the
  triangle ``T(alpha, beta)``), so ``mu >= 0`` is simply ``w >= 0``.
* **Normal equations** are accumulated in C++ (``preisach._core.normal_equations``, GIL
  released) per cross-validation fold, in the Everett nodes, and mapped to ``(w, y_min)`` here:
  ``G_w = C^T G_E C``.  The ``samples x parameters`` matrix is never formed.
* **Smoothness.**  ``lambda * s * ||R w||^2`` with ``R`` the second differences of the density
  ``v = w / (h_i h_j)`` along alpha and along beta, and of ``kappa = w / h`` along the diagonal,
  scaled by the mean level spacing so that every row is in volts (the same roughness the gap
  fill of the Mayergoyz identifier minimises).  ``s = trace(G_w) / trace(R^T R)`` makes
  ``lambda`` dimensionless.
* **Bounds.**  ``w >= 0`` (``nonnegative=True``): the quadratic programme is solved exactly by
  block principal pivoting (Kim and Park, 2011) on the reduced Hessian (``y_min`` eliminated by
  its Schur complement), warm-started along the ``lambda`` path.
* **lambda by K-fold cross-validation over contiguous time blocks.**  The fitted samples of all
  recordings, in order, are split into ``folds`` contiguous blocks of equal size; for every
  ``lambda`` the model is fitted without one block and scored on it, with the input history
  always complete (a block is left out of the residuals, not out of the simulation).  The
  ``lambda`` with the lowest cross-validated RMS error is used for the final fit on all samples.
  ``lambdas="auto"`` tries ``1e-8, 1e-6, ..., 1e2`` and then the decades on either side of the
  best of those; the held-out error of a block comes from the fold's normal equations,
  ``theta^T G_k theta - 2 theta^T b_k + y_k^T y_k``, so no sample is simulated twice.

Initial state
-------------
A recording's initial state is unknown.  Policies (``initial_state``):

* ``"burn-in"`` (default): every recording is simulated from negative saturation and the samples
  before its *burn-in end* are not fitted.  The burn-in ends at the first sample where the input
  reaches ``u_min`` or ``u_max`` of the table (the state is then exact: a saturation) or, if
  earlier, where the input has visited both its own minimum and maximum: from then on every
  relay the recording can still switch is set by the input alone (wiping-out), and the relays it
  never switches (``alpha`` above its maximum and ``beta`` below its minimum) are assumed at -1.
  That assumption is exact when the recording reaches either end of the table's range (always
  true for the recording(s) that set the default levels); otherwise the report warns.
* ``"negative"``, ``"positive"``, ``"anhysteretic"`` or a :class:`~preisach.State`: every sample
  is fitted from that state.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from threadpoolctl import threadpool_limits

from .. import _core
from .._progress import ProgressBar, progress_bar
from ..initial_state import InitialState, burn_in_end, check_policy, initial_state_for
from ..recording import SampledData
from .spans import FittedSpan, fitted_spans

__all__ = [
    "LsqDetails",
    "burn_in_end",
    "roughness_matrix",
    "solve_nonnegative_qp",
]

#: Coarse grid of the dimensionless smoothness weight lambda for ``lambdas="auto"``: every two
#: decades; the decades next to the best one are then tried as well.
COARSE_LAMBDAS: tuple[float, ...] = (1e-8, 1e-6, 1e-4, 1e-2, 1.0, 1e2)
#: Largest table the dense solver accepts (its Gram matrices are (n(n-1)/2 + 1)^2 doubles).
MAX_LEVELS = 81
#: Largest table of the sparse solver (the built-in models' resolution is 201 levels).
MAX_SPARSE_LEVELS = 401
#: ``solver="auto"`` uses the dense solver up to this many levels, the sparse one beyond.
DENSE_UP_TO = 41


@dataclass
class LsqDetails:
    """How a least-squares identification went (part of the identification report).

    Attributes
    ----------
    lambdas : ndarray
        Smoothness weights tried (dimensionless, see the module docstring).
    cv_rms : ndarray
        Cross-validated RMS error (V) for each ``lambda``.
    cv_fold_rms : ndarray, shape (len(lambdas), folds)
        RMS error (V) on each held-out block.
    chosen_lambda : float
        The ``lambda`` of the final fit (lowest ``cv_rms``).
    folds : int
        Number of contiguous blocks.
    fold_sizes : ndarray of int
        Fitted samples per block.
    n_samples : int
        Samples fitted (after burn-in and delay).
    n_skipped : int
        Samples not fitted (burn-in, and the last ``delay`` samples of each recording).
    n_params : int
        Cell masses plus the offset.
    n_zero : int
        Cell masses at the bound ``w = 0`` in the final fit.
    fit_rms : float
        RMS residual (V) of the final fit on all fitted samples.
    penalty_scale : float
        ``s = trace(G_w) / trace(R^T R)``.
    nonnegative : bool
        Whether ``w >= 0`` was imposed.
    initial_state : str
        The policy used.
    delay : float
        Output delay (samples) used (fractional when estimated so).
    solver_iterations : int
        Block-pivoting iterations of the final fit (dense), or conjugate-gradient iterations of
        all solves (sparse).
    timings : dict of str to float
        Wall-clock seconds per stage (``normal_equations``, ``transform``, ``cross_validation``,
        ``final_fit``).
    solver : str
        ``"dense"`` (cell masses, exact ``mu >= 0`` inside the fit) or ``"sparse"`` (Everett
        nodes by conjugate gradients, :mod:`preisach.identify.lsq_sparse`; ``mu >= 0`` by the
        projection to Mp afterwards).
    unobserved_nodes : int
        Everett nodes no fitted sample depends on (the input never reaches their part of the
        table): the smoothness prior alone sets them.
    n_nodes : int
        Everett nodes of the table.

    """

    lambdas: NDArray[np.float64]
    cv_rms: NDArray[np.float64]
    cv_fold_rms: NDArray[np.float64]
    chosen_lambda: float
    folds: int
    fold_sizes: NDArray[np.int64]
    n_samples: int
    n_skipped: int
    n_params: int
    n_zero: int
    fit_rms: float
    penalty_scale: float
    nonnegative: bool
    initial_state: str
    delay: float
    solver_iterations: int
    timings: dict[str, float] = field(default_factory=dict)
    solver: str = "dense"
    unobserved_nodes: int = 0
    n_nodes: int = 0

    def summary_lines(self, units: str = "V") -> list[str]:
        """Lines of the identification report (errors in the output ``units``)."""
        lines = [
            f"  least squares: {self.n_samples} samples fitted ({self.n_skipped} not: "
            f"burn-in/delay), {self.n_params} parameters, {self.n_zero} masses at 0, "
            f"initial state '{self.initial_state}', delay {self.delay:g}",
            f"  solver: {self.solver}"
            + (
                " (cell masses, mu >= 0 inside the fit)"
                if self.solver == "dense"
                else " (Everett nodes, conjugate gradients; mu >= 0 by projection)"
            )
            + f", {self.solver_iterations} iterations",
            f"  smoothness lambda by {self.folds}-fold CV over time blocks: chosen "
            f"{self.chosen_lambda:.3g}; fit rms {self.fit_rms:.4g} {units}",
            f"    lambda     CV rms ({units})",
        ]
        for lv, cv in zip(self.lambdas, self.cv_rms):
            mark = "  <-" if lv == self.chosen_lambda else ""
            lines.append(f"    {lv:<10.3g} {cv:.5g}{mark}")
        if self.unobserved_nodes:
            lines.append(
                f"  {self.unobserved_nodes} of {self.n_nodes} Everett nodes are not reached by the "
                "input (no sample depends on them): the smoothness prior sets them"
            )
        return lines

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            "lambdas": self.lambdas.tolist(),
            "cv_rms": self.cv_rms.tolist(),
            "cv_fold_rms": self.cv_fold_rms.tolist(),
            "chosen_lambda": self.chosen_lambda,
            "folds": self.folds,
            "fold_sizes": self.fold_sizes.tolist(),
            "n_samples": self.n_samples,
            "n_skipped": self.n_skipped,
            "n_params": self.n_params,
            "n_zero": self.n_zero,
            "fit_rms": self.fit_rms,
            "penalty_scale": self.penalty_scale,
            "nonnegative": self.nonnegative,
            "initial_state": self.initial_state,
            "delay": self.delay,
            "solver_iterations": self.solver_iterations,
            "timings": dict(self.timings),
            "solver": self.solver,
            "unobserved_nodes": self.unobserved_nodes,
            "n_nodes": self.n_nodes,
        }


# ------------------------------------------------------------------------------------------
# linear algebra on the grid
# ------------------------------------------------------------------------------------------
def _cells(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Cells (i, j), j <= i <= n - 2, in row-major order of the lower triangle."""
    i, j = np.tril_indices(n - 1)
    return i, j


def _nodes(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Everett nodes (a, b), b < a, in row-major order (index a (a - 1) / 2 + b)."""
    return np.tril_indices(n, -1)


def _cell_grid(
    levels: ArrayLike,
) -> tuple[
    int,
    NDArray[np.float64],
    float,
    tuple[NDArray[np.intp], NDArray[np.intp]],
    NDArray[np.intp],
]:
    """Return what the roughness operators index: ``(m, h, hbar, cells, index)``.

    ``m`` cells per side, the level spacings ``h`` (V) and their mean ``hbar``, the cells
    ``(ci, cj)`` (:func:`_cells`), and ``index[i, j]``: the column of cell ``(i, j)`` (-1
    above the diagonal).
    """
    lv = np.asarray(levels, dtype=float)
    m = lv.size - 1
    cells = _cells(lv.size)
    index = -np.ones((m, m), dtype=np.intp)
    index[cells] = np.arange(cells[0].size)
    return m, np.diff(lv), float((lv[-1] - lv[0]) / m), cells, index


def cumulative_matrix(n: int) -> NDArray[np.float64]:
    """``C`` with ``E_nodes = C @ w_cells``: ``E(a, b) = sum of w(k, l), b <= l <= k <= a - 1``."""
    a, b = _nodes(n)
    k, l = _cells(n)  # noqa: E741
    return ((k[None, :] <= a[:, None] - 1) & (l[None, :] >= b[:, None])).astype(float)


def _apply_Tt(X: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """``T^T X`` for ``X`` over ``(Everett nodes, y_min)`` rows: ``C^T`` by cumulative sums.

    ``(C^T x)(k, l) = sum of x(a, b) over a >= k + 1, b <= l``.
    """
    a, b = _nodes(n)
    ci, cj = _cells(n)
    nn = a.size
    full = np.zeros((n, n, X.shape[1]))
    full[a, b] = X[:nn]
    np.cumsum(full, axis=1, out=full)  # b <= l
    full = np.flip(np.cumsum(np.flip(full, 0), axis=0), 0)  # a >= k + 1
    out = np.empty((ci.size + 1, X.shape[1]))
    out[:-1] = full[ci + 1, cj]
    out[-1] = X[nn]
    return out


def _transform_gram(G: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """``T^T G T`` for a symmetric Gram matrix over ``(Everett nodes, y_min)``."""
    H = _apply_Tt(G, n)  # T^T G
    return _apply_Tt(np.ascontiguousarray(H.T), n)  # T^T (T^T G)^T = T^T G T


def roughness_matrix(levels: ArrayLike) -> NDArray[np.float64]:
    """Roughness operator ``R`` on the cell masses (rows in volts; see the module docstring).

    Rows: second differences of ``v = w / (h_i h_j)`` along alpha and along beta over three
    off-diagonal cells, and of ``kappa = w / h_i`` along the diagonal, each multiplied by
    ``hbar^2`` (``hbar`` for kappa), ``hbar`` the mean level spacing.

    Parameters
    ----------
    levels : array_like, shape (n,)
        Increasing levels (V).

    Returns
    -------
    ndarray, shape (rows, n (n - 1) / 2)

    """
    m, h, hbar, (ci, cj), index = _cell_grid(levels)

    def dens(i: int, j: int) -> float:
        return float(hbar / h[i] if i == j else hbar * hbar / (h[i] * h[j]))

    rows: list[list[tuple[int, float]]] = []
    for i in range(m):
        for j in range(i):
            if i >= 1 and j + 1 < i and i + 1 < m:
                rows.append(
                    [
                        (index[i - 1, j], dens(i - 1, j)),
                        (index[i, j], -2 * dens(i, j)),
                        (index[i + 1, j], dens(i + 1, j)),
                    ]
                )
            if j >= 1 and j + 1 < i:
                rows.append(
                    [
                        (index[i, j - 1], dens(i, j - 1)),
                        (index[i, j], -2 * dens(i, j)),
                        (index[i, j + 1], dens(i, j + 1)),
                    ]
                )
    for i in range(1, m - 1):
        rows.append(
            [
                (index[i - 1, i - 1], dens(i - 1, i - 1)),
                (index[i, i], -2 * dens(i, i)),
                (index[i + 1, i + 1], dens(i + 1, i + 1)),
            ]
        )
    R = np.zeros((len(rows), ci.size))
    for r, row in enumerate(rows):
        for c, v in row:
            R[r, c] += v
    return R


def robust_cholesky(H: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """Cholesky factor (``scipy.linalg.cho_factor`` form) of a symmetric semidefinite ``H``.

    Gram matrices of data that leave cells unobserved (an input that never reaches part of the
    table), with a small smoothness weight, are singular up to round-off, and a plain Cholesky
    fails on them.  A ridge of ``1e-12, 1e-10, ..., 1e-4`` times the mean diagonal is added
    until the factorisation succeeds: the ridge pulls the unobserved directions to zero while
    the smoothness penalty decides them, and changes the observed ones by that relative amount
    at most.  A matrix with a non-finite or non-positive diagonal raises ValueError.
    """
    m = H.shape[0]
    scale = float(np.trace(H)) / max(m, 1)
    if not (math.isfinite(scale) and scale > 0.0):
        raise ValueError(
            "normal equations: the data determine no parameter (zero or non-finite Gram)"
        )
    for ridge in (0.0, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4):
        Hr = H if ridge == 0.0 else H + (ridge * scale) * np.eye(m)
        try:
            fac: tuple[NDArray[np.float64], bool] = cho_factor(Hr, check_finite=False)
            return fac
        except LinAlgError:
            continue
    raise ValueError("normal equations: not positive definite even with a 1e-4 relative ridge")


def solve_nonnegative_qp(
    H: NDArray[np.float64],
    g: NDArray[np.float64],
    free: NDArray[np.bool_] | None = None,
    max_iter: int = 500,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], int, bool]:
    """Minimise ``x^T H x / 2 - g^T x`` subject to ``x >= 0`` (``H`` symmetric positive definite).

    Block principal pivoting (Kim and Park, "Fast nonnegative matrix factorization", SIAM J.
    Sci. Comput. 33, 2011, Algorithm 1, with its backup rule): solve with the bound set ``B``
    held at zero, exchange every variable that violates the KKT conditions at once, and fall
    back to single exchanges when the number of violations stops falling.

    ``H`` is factorised once.  With ``x0 = H^-1 g`` and ``Z = H^-1 E_B`` (columns of ``H^-1``,
    cached), the solution with ``x_B = 0`` is ``x = x0 - Z nu``, ``Z_B nu = x0_B``, and the
    gradient on ``B`` is ``-nu``; an exchange costs a few triangular solves and a small dense
    solve instead of a new factorisation.

    Parameters
    ----------
    H : ndarray, shape (m, m)
        Symmetric positive definite Hessian.
    g : ndarray, shape (m,)
        Linear term.
    free : ndarray of bool, optional
        Initial free set (warm start); default all free (the unconstrained solution first).
    max_iter : int
        Iteration limit.

    Returns
    -------
    x : ndarray
        The minimiser (exactly zero on the bound set).
    free : ndarray of bool
        Final free set.
    iterations : int
    converged : bool
        ``False`` if ``max_iter`` was reached (``x`` is then the last iterate clipped at 0).

    """
    m = g.size
    F = np.ones(m, dtype=bool) if free is None else free.copy()
    fac = robust_cholesky(H)
    x0 = cho_solve(fac, g, check_finite=False)
    cols: dict[int, NDArray[np.float64]] = {}  # j -> column j of H^-1
    xscale = float(np.max(np.abs(x0))) if m else 0.0
    gscale = float(np.max(np.abs(g))) if m else 0.0
    best, backup = m + 1, 3
    converged = False
    x = x0.copy()
    it = 0
    while it < max_iter:
        it += 1
        bound = np.nonzero(~F)[0]
        nu = np.zeros(0)
        if bound.size:
            missing = [int(j) for j in bound if int(j) not in cols]
            if missing:
                E = np.zeros((m, len(missing)))
                E[missing, np.arange(len(missing))] = 1.0
                Zm = cho_solve(fac, E, check_finite=False)
                for k, j in enumerate(missing):
                    cols[j] = Zm[:, k]
            Z = np.column_stack([cols[int(j)] for j in bound])
            S = Z[bound, :]
            try:
                nu = cho_solve(cho_factor(S, check_finite=False), x0[bound], check_finite=False)
            except LinAlgError:
                nu = np.linalg.lstsq(S, x0[bound], rcond=None)[0]
            x = x0 - Z @ nu
            x[bound] = 0.0
        else:
            x = x0.copy()
        grad_b = -nu  # gradient H x - g on the bound set
        bad = F & (x < -1e-12 * xscale)
        if bound.size:
            bad[bound] = grad_b < -1e-12 * gscale
        nbad = int(np.count_nonzero(bad))
        if nbad == 0:
            converged = True
            break
        if nbad < best:
            best, backup = nbad, 3
            F ^= bad
        elif backup > 0:
            backup -= 1
            F ^= bad
        else:
            k = int(np.nonzero(bad)[0][-1])
            F[k] = not F[k]
    np.maximum(x, 0.0, out=x)
    x[~F] = 0.0
    return x, F, it, converged


# ------------------------------------------------------------------------------------------
# the identifier
# ------------------------------------------------------------------------------------------
@dataclass
class _Prepared:
    levels: NDArray[np.float64]
    gram: NDArray[np.float64]  # (K, p, p) in (w, y_min)
    rhs: NDArray[np.float64]  # (K, p)
    yy: NDArray[np.float64]  # (K,)
    count: NDArray[np.int64]  # (K,)
    n_skipped: int
    spans: list[FittedSpan]
    warnings: list[str]
    timings: dict[str, float]
    unobserved_nodes: int = 0


def _prepare(
    recordings: Sequence[SampledData],
    levels: NDArray[np.float64],
    folds: int,
    policy: InitialState,
    delay: int,
    names: Sequence[str],
) -> _Prepared:
    lo, hi = float(levels[0]), float(levels[-1])
    spans, warnings = fitted_spans(recordings, names, levels, policy, delay)
    total = sum(span.n_used for span in spans)
    if total < folds:
        raise ValueError(
            f"only {total} samples to fit after the burn-in, fewer than folds = "
            f"{folds}; use longer recordings or another initial_state"
        )
    # contiguous blocks over the concatenated fitted samples
    t0 = time.perf_counter()
    n_nodes = levels.size * (levels.size - 1) // 2
    p = n_nodes + 1
    G = np.zeros((folds, p, p))
    b = np.zeros((folds, p))
    yy = np.zeros(folds)
    cnt = np.zeros(folds, dtype=np.int64)
    g0 = 0
    for span in spans:
        fold = -np.ones(span.u.size, dtype=np.int32)
        k = np.arange(span.n_used)
        fold[span.start :] = ((g0 + k) * folds // total).astype(np.int32)
        g0 += span.n_used
        s0 = initial_state_for((lo, hi), policy)
        Gr, br, yr, _, cr, _ = _core.normal_equations(
            levels, span.u, span.y, s0, fold, folds, "clamp"
        )
        G += Gr
        b += br
        yy += yr
        cnt += cr
    t1 = time.perf_counter()
    # to (w, y_min): G_w = T^T G T with T = blockdiag(C, 1), by cumulative sums
    Gw = np.stack([_transform_gram(G[k], levels.size) for k in range(folds)])
    bw = np.stack([_apply_Tt(b[k][:, None], levels.size)[:, 0] for k in range(folds)])
    t2 = time.perf_counter()
    n_skipped = sum(span.n_samples for span in spans) - total
    return _Prepared(
        levels,
        Gw,
        bw,
        yy,
        cnt,
        n_skipped,
        spans,
        warnings,
        {"normal_equations": t1 - t0, "transform": t2 - t1},
        int(np.count_nonzero(np.diagonal(G.sum(axis=0))[:-1] <= 0.0)),
    )


@dataclass
class _Reduced:
    """Normal equations with y_min eliminated (Schur complement), before the penalty."""

    H: NDArray[np.float64]  # (m, m)
    g: NDArray[np.float64]  # (m,)
    hwc: NDArray[np.float64]  # (m,) coupling of the masses to y_min
    hcc: float  # number of samples (the y_min diagonal)
    gc: float


def _reduce(H: NDArray[np.float64], g: NDArray[np.float64]) -> _Reduced:
    m = H.shape[0] - 1
    hwc = H[:m, m].copy()
    hcc = float(H[m, m])
    Hr = H[:m, :m] - np.outer(hwc, hwc / hcc)
    gr = g[:m] - hwc * (g[m] / hcc)
    return _Reduced(Hr, gr, hwc, hcc, float(g[m]))


def _fit(
    red: _Reduced,
    P: NDArray[np.float64],
    lam: float,
    nonneg: bool,
    free: NDArray[np.bool_] | None,
) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None, int, bool]:
    """Penalised fit of theta = (w, y_min) from a reduced system."""
    m = red.g.size
    Hr = red.H + lam * P
    Hr[np.diag_indices(m)] += 1e-13 * float(np.trace(Hr)) / m  # keeps Hr definite
    if nonneg:
        w, free_out, it, ok = solve_nonnegative_qp(Hr, red.g, free)
    else:
        w = cho_solve(robust_cholesky(Hr), red.g, check_finite=False)
        free_out, it, ok = None, 1, True
    c = (red.gc - red.hwc @ w) / red.hcc
    return np.append(w, c), free_out, it, ok


def identify_lsq_core(
    recordings: Sequence[SampledData],
    levels: NDArray[np.float64],
    *,
    lambdas: str | Sequence[float],
    folds: int,
    initial_state: InitialState,
    delay: int,
    nonnegative: bool,
    names: Sequence[str],
    progress: bool = False,
    solver: str = "auto",
) -> tuple[NDArray[np.float64], float, LsqDetails, list[FittedSpan], list[str]]:
    """Cell masses, y_min and the details of a least-squares identification (no model built).

    Returns ``(w (cells, output units), y_min, details, spans, warnings)``; see
    :func:`identify_lsq`.  With the sparse solver ``w`` may hold negative masses (the caller
    projects the model to Mp when ``nonnegative``).  ``progress`` shows a bar over the
    cross-validation fits (dense solver).
    """
    if solver not in ("auto", "dense", "sparse"):
        raise ValueError(f"solver: expected 'auto', 'dense' or 'sparse', got {solver!r}")
    if solver == "auto":
        solver = "dense" if levels.size <= DENSE_UP_TO else "sparse"
    if solver == "dense" and levels.size > MAX_LEVELS:
        raise ValueError(
            f"levels: at most {MAX_LEVELS} levels for the dense least-squares solver (its "
            f"normal equations are dense), got {levels.size}; use solver='sparse'"
        )
    if levels.size > MAX_SPARSE_LEVELS:
        raise ValueError(
            f"levels: at most {MAX_SPARSE_LEVELS} levels for least squares, got {levels.size}"
        )
    if levels.size < 3:
        raise ValueError(f"levels: need at least 3 levels, got {levels.size}")
    if isinstance(folds, bool) or int(folds) != folds or folds < 2:
        raise ValueError(f"folds: need an integer >= 2 for cross-validation, got {folds!r}")
    folds = int(folds)
    auto = isinstance(lambdas, str)
    if auto and lambdas != "auto":
        raise ValueError(f"lambdas: expected 'auto' or a sequence of values >= 0, got {lambdas!r}")
    lam = np.array(COARSE_LAMBDAS if auto else list(lambdas), dtype=np.float64)
    if lam.ndim != 1 or lam.size == 0 or not np.all(np.isfinite(lam)) or np.any(lam < 0):
        raise ValueError("lambdas: need 'auto' or a non-empty sequence of finite values >= 0")
    if isinstance(delay, bool) or int(delay) != delay or delay < 0:
        raise ValueError(f"delay: need an integer number of samples >= 0, got {delay!r}")
    delay = int(delay)
    if solver == "sparse":
        with threadpool_limits(limits=1, user_api="blas"):
            return _solve_sparse(
                recordings, levels, lam, auto, folds, nonnegative, initial_state, delay, names
            )
    n_fits = 1 + folds * (lam.size + (2 if auto else 0)) + 1  # sums, CV fits, final fit
    with progress_bar(n_fits, "least squares", enabled=progress, unit="fit", leave=False) as bar:
        prep = _prepare(recordings, levels, folds, initial_state, delay, names)
        bar.update(1)
        # The solves below are many factorisations of at most ~2000 x 2000 matrices: a threaded
        # BLAS gains little on them, and on a busy machine its spinning threads cost a lot
        # (measured: 0.67 s single-threaded vs 21.9 s with OpenBLAS threads at load 4 on 2
        # cores).
        with threadpool_limits(limits=1, user_api="blas"):
            return _solve(prep, levels, lam, auto, folds, nonnegative, initial_state, delay, bar)


def nearest_in_log(tried: Iterable[float], lam: float) -> float | None:
    """Return the weight in ``tried`` nearest to ``lam`` on a log scale (``None``: none tried).

    A fit at ``lam`` starts from that one's solution (warm start); zero counts as 1e-300.
    """
    return min(
        tried,
        key=lambda x: abs(math.log10(x + 1e-300) - math.log10(lam + 1e-300)),
        default=None,
    )


def _solve(
    prep: _Prepared,
    levels: NDArray[np.float64],
    lam: NDArray[np.float64],
    auto: bool,
    folds: int,
    nonnegative: bool,
    initial_state: InitialState,
    delay: int,
    bar: ProgressBar,
) -> tuple[NDArray[np.float64], float, LsqDetails, list[FittedSpan], list[str]]:
    """Cross-validate the smoothness weight and fit (the body of :func:`identify_lsq_core`)."""
    R = roughness_matrix(levels)
    P = R.T @ R
    Gtot = prep.gram.sum(axis=0)
    btot = prep.rhs.sum(axis=0)
    m = P.shape[0]
    trP = float(np.trace(P))
    scale = float(np.trace(Gtot[:m, :m])) / trP if trP > 0 else 0.0
    Ps = P * scale
    t0 = time.perf_counter()
    reduced = [_reduce(Gtot - prep.gram[k], btot - prep.rhs[k]) for k in range(folds)]
    sse: dict[float, NDArray[np.float64]] = {}
    free_sets: dict[float, list[NDArray[np.bool_] | None]] = {}

    def evaluate(values: Iterable[float]) -> None:
        for lv in values:
            lv = float(lv)
            if lv in sse:
                continue
            near = nearest_in_log(free_sets, lv)
            warm = free_sets[near] if near is not None else [None] * folds
            row = np.zeros(folds)
            frees: list[NDArray[np.bool_] | None] = []
            for k in range(folds):
                theta, fr, _, _ = _fit(reduced[k], Ps, lv, nonnegative, warm[k])
                frees.append(fr)
                Gk, bk = prep.gram[k], prep.rhs[k]
                row[k] = max(float(theta @ (Gk @ theta) - 2.0 * theta @ bk + prep.yy[k]), 0.0)
                bar.update(1)
            sse[lv] = row
            free_sets[lv] = frees

    evaluate(lam)
    if auto:  # refine: the decades on either side of the best coarse value
        tried = sorted(sse)
        best_lv = min(tried, key=lambda x: float(sse[x].sum()))
        evaluate([best_lv / 10.0, best_lv * 10.0])
    lam = np.array(sorted(sse))
    cv_sse = np.array([sse[x] for x in lam])
    t1 = time.perf_counter()
    cv_rms = np.sqrt(cv_sse.sum(axis=1) / prep.count.sum())
    fold_rms = np.sqrt(cv_sse / np.maximum(prep.count, 1)[None, :])
    best = int(np.argmin(cv_rms))
    theta, free, iters, ok = _fit(
        _reduce(Gtot, btot), Ps, float(lam[best]), nonnegative, free_sets[float(lam[best])][0]
    )
    t2 = time.perf_counter()
    if bar.total is not None:  # a refinement value already tried was not refitted
        bar.update(bar.total - bar.n)
    warnings = list(prep.warnings)
    if not ok:
        warnings.append(
            "the non-negative least-squares solver hit its iteration limit; the "
            "masses were clipped at zero"
        )
    if best in (0, lam.size - 1) and lam.size > 1:
        edge = "smallest" if best == 0 else "largest"
        warnings.append(
            f"cross-validation chose the {edge} lambda tried ({lam[best]:.3g}); "
            "extend the lambdas grid"
        )
    sse_fit = float(theta @ Gtot @ theta - 2.0 * theta @ btot + prep.yy.sum())
    n_fit = int(prep.count.sum())
    if n_fit < m + 1:
        warnings.append(
            f"only {n_fit} samples were fitted for {m + 1} parameters (cell masses and the "
            "offset): the fit is underdetermined, so its rms residual says nothing about the "
            "model (the smoothness penalty decides most of the table); record more samples or "
            "use fewer levels"
        )
    w = theta[:-1]
    details = LsqDetails(
        lambdas=lam,
        cv_rms=cv_rms,
        cv_fold_rms=fold_rms,
        chosen_lambda=float(lam[best]),
        folds=folds,
        fold_sizes=prep.count.copy(),
        n_samples=n_fit,
        n_skipped=prep.n_skipped,
        n_params=m + 1,
        n_zero=int(np.count_nonzero(w == 0.0)),
        fit_rms=math.sqrt(max(sse_fit, 0.0) / n_fit),
        penalty_scale=scale,
        nonnegative=bool(nonnegative),
        initial_state=check_policy(initial_state),
        delay=delay,
        solver_iterations=int(iters),
        timings={**prep.timings, "cross_validation": t1 - t0, "final_fit": t2 - t1},
        solver="dense",
        unobserved_nodes=prep.unobserved_nodes,
        n_nodes=levels.size * (levels.size - 1) // 2,
    )
    return w, float(theta[-1]), details, prep.spans, warnings


def _solve_sparse(
    recordings: Sequence[SampledData],
    levels: NDArray[np.float64],
    lam: NDArray[np.float64],
    auto: bool,
    folds: int,
    nonnegative: bool,
    initial_state: InitialState,
    delay: int,
    names: Sequence[str],
) -> tuple[NDArray[np.float64], float, LsqDetails, list[FittedSpan], list[str]]:
    """Run the sparse solver: the branch of :func:`identify_lsq_core` (no bounds inside the fit)."""
    from .lsq_sparse import difference_matrix, solve_sparse, sparse_rows

    rows = sparse_rows(recordings, levels, folds, initial_state, delay, names)
    fit = solve_sparse(rows, levels, [float(x) for x in lam], auto)
    warnings = list(rows.warnings)
    if not fit.converged:
        warnings.append(
            "conjugate gradients stopped at their iteration limit on some solve; the fit is "
            "approximate"
        )
    best = int(np.argmin(fit.cv_sse.sum(axis=1)))
    if best in (0, fit.lambdas.size - 1) and fit.lambdas.size > 1:
        edge = "smallest" if best == 0 else "largest"
        warnings.append(
            f"cross-validation chose the {edge} lambda tried ({fit.chosen:.3g}); "
            "extend the lambdas grid"
        )
    n_fit = int(fit.count.sum())
    m = levels.size * (levels.size - 1) // 2
    if n_fit < m + 1:
        warnings.append(
            f"only {n_fit} samples were fitted for {m + 1} parameters (Everett nodes and the "
            "offset): the fit is underdetermined, so its rms residual says nothing about the "
            "model (the smoothness penalty decides most of the table); record more samples or "
            "use fewer levels"
        )
    w = np.asarray(difference_matrix(levels.size) @ fit.theta[:-1])
    details = LsqDetails(
        lambdas=fit.lambdas,
        cv_rms=np.sqrt(fit.cv_sse.sum(axis=1) / n_fit),
        cv_fold_rms=np.sqrt(fit.cv_sse / np.maximum(fit.count, 1)[None, :]),
        chosen_lambda=fit.chosen,
        folds=folds,
        fold_sizes=fit.count.copy(),
        n_samples=n_fit,
        n_skipped=rows.n_skipped,
        n_params=m + 1,
        n_zero=int(np.count_nonzero(w <= 0.0)),
        fit_rms=math.sqrt(fit.fit_sse / n_fit),
        penalty_scale=fit.scale,
        nonnegative=bool(nonnegative),
        initial_state=check_policy(initial_state),
        delay=delay,
        solver_iterations=fit.iterations,
        timings=fit.timings,
        solver="sparse",
        unobserved_nodes=fit.unobserved_nodes,
        n_nodes=m,
    )
    return w, float(fit.theta[-1]), details, rows.spans, warnings


def weights_matrix(levels: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Arrange cell masses as the ``(n-1, n-1)`` lower-triangular matrix of ``from_weights``."""
    n = levels.size
    W = np.zeros((n - 1, n - 1))
    ci, cj = _cells(n)
    W[ci, cj] = w
    return W
