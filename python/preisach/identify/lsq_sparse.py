"""Sparse least squares for fine tables: the Everett nodes as unknowns, conjugate gradients.

The dense solver of :mod:`preisach.identify.lsq` works on the cell masses ``w``, whose regressor
rows are dense (a sample's output sums every cell inside its boundary), and factorises
``(n (n - 1) / 2)^2`` Gram matrices: cubic time, quadratic memory, 81 levels at most.  Here the
unknowns are the Everett node values ``E`` and ``y_min`` instead, in which every sample's row has
a few nonzeros per boundary piece (``cpp/include/preisach/regressor.hpp``: about 12 on filtered
noise, whatever the grid).  So:

* the regressor is a sparse matrix ``A`` (samples x nodes, ``_core.regressor_rows``), and each
  cross-validation fold's Gram matrix ``A_k^T A_k`` is sparse (a few % dense at 201 levels);
* the smoothness penalty is the same as the dense solver's - second differences of the density
  ``v`` (and of ``kappa`` on the diagonal), :func:`roughness_sparse` - composed with the mixed
  second difference ``D`` that maps nodes to cell masses (``w = D E``), a sparse operator too,
  and weighted by the same dimensionless ``lambda`` times ``s = trace(G_w) / trace(R^T R)``;
* each penalised system is solved by conjugate gradients with a two-level preconditioner:
  Jacobi plus an exact coarse-grid correction on the nodes of a coarse grid (every k-th level,
  bilinear prolongation as the table interpolates), which removes the smooth error components
  that Jacobi alone converges on slowly.  Solves are warm-started along the ``lambda`` path and
  from the all-data fit;
* cells the input never reaches have no data (their nodes' Gram diagonal is zero): the
  smoothness prior decides them, and their number is reported.  A tiny ridge keeps every
  system positive definite, so no ``lambda`` can make a solve fail.

``mu >= 0`` is imposed after the fit by the least-squares projection to Mp
(:func:`preisach.identify.project_nonnegative`, Hildreth's method in C++), whose moved mass the
report gives; the dense solver imposes it inside the fit instead.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from .. import _core
from ..initial_state import InitialState, initial_state_for
from ..recording import SampledData
from .lsq import _cell_grid, _cells, _nodes, nearest_in_log
from .spans import FittedSpan, fitted_spans

__all__ = [
    "difference_matrix",
    "prolongation",
    "roughness_sparse",
    "solve_sparse",
]

#: Levels of the coarse grid of the two-level preconditioner (at most).
COARSE_LEVELS = 21


def roughness_sparse(levels: NDArray[np.float64]) -> sp.csr_matrix:
    """Roughness operator ``R`` on the cell masses, sparse (rows in output units).

    The rows of :func:`preisach.identify.lsq.roughness_matrix`: second differences of
    ``v = w / (h_i h_j)`` along alpha and along beta over three off-diagonal cells, and of
    ``kappa = w / h_i`` along the diagonal, times ``hbar^2`` (``hbar`` for kappa).
    """
    m, h, hbar, (ci, cj), index = _cell_grid(levels)
    dens = np.where(ci == cj, hbar / h[ci], hbar * hbar / (h[ci] * h[np.minimum(cj, m - 1)]))
    rows: list[NDArray[np.intp]] = []
    cols: list[NDArray[np.intp]] = []
    vals: list[NDArray[np.float64]] = []
    r0 = 0
    stencil = ((-1, 1.0), (0, -2.0), (1, 1.0))
    for sel, step in (
        ((ci >= 1) & (cj + 1 < ci) & (ci + 1 < m), (1, 0)),  # along alpha
        ((cj >= 1) & (cj + 1 < ci), (0, 1)),  # along beta
    ):
        k = int(np.count_nonzero(sel))
        for d, c in stencil:
            col = index[ci[sel] + d * step[0], cj[sel] + d * step[1]]
            rows.append(r0 + np.arange(k))
            cols.append(col)
            vals.append(c * dens[col])
        r0 += k
    dg = np.arange(1, m - 1)
    for d, c in stencil:
        col = index[dg + d, dg + d]
        rows.append(r0 + np.arange(dg.size))
        cols.append(col)
        vals.append(c * dens[col])
    r0 += dg.size
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(r0, ci.size),
    )


def difference_matrix(n: int) -> sp.csr_matrix:
    """``D`` with ``w = D E``: cell masses from the Everett nodes (``E(i, i) = 0``).

    ``w(k, l) = E(k + 1, l) - E(k + 1, l + 1) - E(k, l) + E(k, l + 1)`` over the cells
    ``l <= k``, nodes ``(a, b)``, ``b < a``, in row-major order (index ``a (a - 1) / 2 + b``).
    """
    ci, cj = _cells(n)
    rows, cols, vals = [], [], []
    for da, db, c in ((1, 0, 1.0), (1, 1, -1.0), (0, 0, -1.0), (0, 1, 1.0)):
        a, b = ci + da, cj + db
        ok = b < a
        rows.append(np.nonzero(ok)[0])
        cols.append(a[ok] * (a[ok] - 1) // 2 + b[ok])
        vals.append(np.full(int(ok.sum()), c))
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(ci.size, n * (n - 1) // 2),
    )


def prolongation(levels: NDArray[np.float64], coarse: NDArray[np.intp]) -> sp.csr_matrix:
    """Interpolation of ``(E, y_min)`` from the levels ``levels[coarse]`` to all ``levels``.

    The fine node ``(alpha, beta)`` gets the coarse table's value there, bilinear as
    :class:`~preisach.EverettTable` interpolates (antisymmetric extension, ``E(u, u) = 0``);
    ``y_min`` maps to ``y_min``.
    """
    lv = np.asarray(levels, dtype=float)
    n = lv.size
    cl = lv[coarse]
    nc = cl.size
    a, b = _nodes(n)
    rows, cols, vals = [], [], []

    def locate(x: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        i = np.clip(np.searchsorted(cl, x, side="right") - 1, 0, nc - 2)
        return i, (x - cl[i]) / (cl[i + 1] - cl[i])

    ia, fa = locate(lv[a])
    ib, fb = locate(lv[b])
    fine = np.arange(a.size)
    for da, wa in ((0, 1.0 - fa), (1, fa)):
        for db, wb in ((0, 1.0 - fb), (1, fb)):
            i, j, c = ia + da, ib + db, wa * wb
            lower = i > j
            upper = i < j
            hi, lo = np.where(lower, i, j), np.where(lower, j, i)
            keep = (lower | upper) & (c != 0.0)
            rows.append(fine[keep])
            cols.append((hi * (hi - 1) // 2 + lo)[keep])
            vals.append(np.where(lower, c, -c)[keep])
    pc = nc * (nc - 1) // 2
    rows.append(np.array([a.size]))
    cols.append(np.array([pc]))
    vals.append(np.array([1.0]))
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(a.size + 1, pc + 1),
    )


def _trace_cell_gram(G: sp.csr_matrix, n: int) -> float:
    """``trace(C^T G_E C)`` (the dense solver's ``trace(G_w)``) from the sparse node Gram.

    ``(C C^T)`` between nodes ``(a, b)`` and ``(a', b')`` counts the cells both triangles hold:
    ``m (m + 1) / 2`` with ``m = min(a, a') - max(b, b')`` (0 when negative).
    """
    coo = G.tocoo()
    nn = n * (n - 1) // 2
    keep = (coo.row < nn) & (coo.col < nn)
    r, c, v = coo.row[keep], coo.col[keep], coo.data[keep]
    a, b = _nodes(n)
    mm = np.maximum(np.minimum(a[r], a[c]) - np.maximum(b[r], b[c]), 0).astype(float)
    return float(np.sum(v * mm * (mm + 1) / 2))


@dataclass
class SparseRows:
    """Regressor rows of the fitted samples, by fold."""

    A: list[sp.csr_matrix]  # per fold
    y: list[NDArray[np.float64]]
    n_skipped: int
    spans: list[FittedSpan]
    warnings: list[str]
    seconds: float


def sparse_rows(
    recordings: Sequence[SampledData],
    levels: NDArray[np.float64],
    folds: int,
    policy: InitialState,
    delay: int,
    names: Sequence[str],
) -> SparseRows:
    """Rows ``r_t`` (Everett nodes and ``y_min``) of every fitted sample, split in time blocks.

    Burn-in, delay and the contiguous folds follow the dense solver
    (:func:`preisach.identify.lsq.identify_lsq_core`; the spans of
    :func:`preisach.identify.lsq.fitted_spans`).
    """
    t0 = time.perf_counter()
    lo, hi = float(levels[0]), float(levels[-1])
    p = levels.size * (levels.size - 1) // 2 + 1
    spans, warnings = fitted_spans(recordings, names, levels, policy, delay)
    blocks: list[tuple[sp.csr_matrix, NDArray[np.float64]]] = []
    for span in spans:
        n_pairs = span.u.size
        ptr, idx, val, _ = _core.regressor_rows(levels, span.u, initial_state_for((lo, hi), policy))
        A = sp.csr_matrix((val, idx.astype(np.int32), ptr), shape=(n_pairs, p))[span.start :]
        blocks.append((A, span.y[span.start :]))
    A_all = sp.vstack([blk[0] for blk in blocks], format="csr")
    y_all = np.concatenate([blk[1] for blk in blocks])
    total = y_all.size
    if total < folds:
        raise ValueError(
            f"only {total} samples to fit after the burn-in, fewer than folds = "
            f"{folds}; use longer recordings or another initial_state"
        )
    edges = [k * total // folds for k in range(folds + 1)]
    A_k = [A_all[edges[k] : edges[k + 1]] for k in range(folds)]
    y_k = [y_all[edges[k] : edges[k + 1]] for k in range(folds)]
    n_skipped = sum(span.n_samples for span in spans) - total
    return SparseRows(A_k, y_k, n_skipped, spans, warnings, time.perf_counter() - t0)


class _TwoLevel:
    """Jacobi plus an exact coarse-grid correction, as a preconditioner for CG."""

    def __init__(self, diag: NDArray[np.float64], P: sp.csr_matrix, Hc: NDArray[np.float64]):
        d = diag.copy()
        d[d <= 0] = 1.0
        self.inv_diag = 1.0 / d
        self.P = P
        self.PT = P.T.tocsr()
        self.fac = _robust_cholesky(Hc)

    def coarse(self, g: NDArray[np.float64]) -> NDArray[np.float64]:
        """Solve ``H x = g`` on the coarse grid and prolong the solution (zero without a factor)."""
        if self.fac is None:
            return np.zeros(g.size)
        return np.asarray(self.P @ cho_solve(self.fac, self.PT @ g, check_finite=False))

    def __call__(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.inv_diag * r + self.coarse(r)


class _Operator:
    """``H = G_all - G_out + c P + ridge I`` applied without forming it."""

    def __init__(
        self,
        G: sp.csr_matrix,
        G_out: sp.csr_matrix | None,
        PE: sp.csr_matrix,
        c: float,
        ridge: float,
    ) -> None:
        self.G, self.G_out, self.PE, self.c, self.ridge = G, G_out, PE, c, ridge

    def __matmul__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        y = self.G @ x
        if self.G_out is not None:
            y -= self.G_out @ x
        y += self.c * (self.PE @ x)
        y += self.ridge * x
        return np.asarray(y)


def _robust_cholesky(H: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool] | None:
    """Cholesky factor of ``H``, with an increasing ridge when round-off makes it indefinite."""
    scale = float(np.trace(H)) / max(H.shape[0], 1)
    if not (scale > 0 and math.isfinite(scale)):
        return None
    for ridge in (0.0, 1e-12, 1e-10, 1e-8, 1e-6):
        try:
            fac: tuple[NDArray[np.float64], bool] = cho_factor(
                H + ridge * scale * np.eye(H.shape[0]), check_finite=False
            )
            return fac
        except LinAlgError:
            continue
    return None


def _pcg(
    H: _Operator,
    g: NDArray[np.float64],
    M: _TwoLevel,
    x0: NDArray[np.float64],
    energy_tol: float,
    max_iter: int,
) -> tuple[NDArray[np.float64], int, bool]:
    """Preconditioned conjugate gradients on ``H x = g`` from ``x0``.

    Stops when ``r^T M^-1 r`` - the preconditioner's estimate of the squared error in the
    energy norm, which is the excess sum of squared residuals of the fit - is below
    ``energy_tol`` (output units squared).
    """
    x = x0.copy()
    r = g - H @ x
    z = M(r)
    d = z.copy()
    rz = float(r @ z)
    for it in range(max_iter):
        if rz <= energy_tol:
            return x, it, True
        Hd = H @ d
        dHd = float(d @ Hd)
        if not dHd > 0.0:
            return x, it, False
        step = rz / dHd
        x += step * d
        r -= step * Hd
        z = M(r)
        rz_new = float(r @ z)
        d *= rz_new / rz
        d += z
        rz = rz_new
    return x, max_iter, rz <= energy_tol


@dataclass
class SparseFit:
    """Result of :func:`solve_sparse`."""

    theta: NDArray[np.float64]  # (E nodes, y_min)
    lambdas: NDArray[np.float64]
    cv_sse: NDArray[np.float64]  # (len(lambdas), folds)
    count: NDArray[np.int64]
    chosen: float
    scale: float
    fit_sse: float
    iterations: int
    converged: bool
    unobserved_nodes: int
    timings: dict[str, float]


def solve_sparse(
    rows: SparseRows,
    levels: NDArray[np.float64],
    lambdas: Sequence[float],
    refine: bool,
    tol: float = 1e-9,
    max_iter: int = 3000,
) -> SparseFit:
    """Cross-validate ``lambda`` over the folds and fit on all samples (unconstrained).

    Every solve stops when its excess sum of squares is below ``tol`` times the output's
    variance sum ``sum (y - mean y)^2`` (so the fit's RMS error is within about
    ``sqrt(tol)`` of the output's standard deviation of the exact minimiser's).
    """
    t0 = time.perf_counter()
    n = levels.size
    folds = len(rows.A)
    Gk = [(A.T @ A).tocsr() for A in rows.A]
    bk = [np.asarray(A.T @ y) for A, y in zip(rows.A, rows.y)]
    yy = np.array([float(y @ y) for y in rows.y])
    count = np.array([y.size for y in rows.y], dtype=np.int64)
    G = Gk[0].copy()
    for k in range(1, folds):
        G = G + Gk[k]
    G = G.tocsr()
    b = np.sum(bk, axis=0)
    ysum = sum(float(y.sum()) for y in rows.y)
    energy_tol = tol * max(float(yy.sum()) - ysum * ysum / max(int(count.sum()), 1), 1e-300)
    t1 = time.perf_counter()
    D = difference_matrix(n)
    R = roughness_sparse(levels)
    RD = (R @ D).tocsr()
    PE = sp.block_diag([RD.T @ RD, sp.csr_matrix((1, 1))], format="csr")
    trP = float(R.multiply(R).sum())  # trace(R^T R), as the dense solver scales lambda
    scale = _trace_cell_gram(G, n) / trP if trP > 0 else 0.0
    diagG = G.diagonal()
    unobserved = int(np.count_nonzero(diagG[:-1] <= 0))
    ridge = 1e-10 * float(diagG.sum()) / diagG.size
    nc = min(COARSE_LEVELS, n)
    coarse = np.unique(np.round(np.linspace(0, n - 1, nc)).astype(np.intp))
    Pc = prolongation(levels, coarse)
    # coarse-grid pieces, once: P^T G_k P per fold, P^T PE P, P^T P
    PcT = Pc.T.tocsr()
    Gc_k = [np.asarray((PcT @ (Gk[k] @ Pc)).todense()) for k in range(folds)]
    Gc = np.sum(Gc_k, axis=0)
    Pc_pen = np.asarray((PcT @ (PE @ Pc)).todense())
    Pc_eye = np.asarray((PcT @ Pc).todense())
    diag_k = [Gk[k].diagonal() for k in range(folds)]
    diag_pen = PE.diagonal()
    iters = 0
    ok_all = True

    def solve(k: int | None, lam: float, x0: NDArray[np.float64] | None) -> NDArray[np.float64]:
        """Fit without fold ``k`` (all samples when None) at ``lam``, from ``x0``."""
        nonlocal iters, ok_all
        c = lam * scale
        G_out = None if k is None else Gk[k]
        g = b if k is None else b - bk[k]
        H = _Operator(G, G_out, PE, c, ridge)
        dg = diagG + c * diag_pen + ridge
        Hc = Gc + c * Pc_pen + ridge * Pc_eye
        if k is not None:
            dg = dg - diag_k[k]
            Hc = Hc - Gc_k[k]
        M = _TwoLevel(dg, Pc, Hc)
        start = x0 if x0 is not None else M.coarse(g)
        x, it, ok = _pcg(H, g, M, start, energy_tol, max_iter)
        iters += it
        ok_all &= ok
        return x

    full: dict[float, NDArray[np.float64]] = {}
    sse: dict[float, NDArray[np.float64]] = {}

    def evaluate(values: Sequence[float]) -> None:
        for lam in values:
            lam = float(lam)
            if lam in sse:
                continue
            near = nearest_in_log(full, lam)
            x_all = solve(None, lam, None if near is None else full[near])
            full[lam] = x_all
            row = np.zeros(folds)
            for k in range(folds):
                th = solve(k, lam, x_all)
                row[k] = max(float(th @ (Gk[k] @ th) - 2.0 * th @ bk[k] + yy[k]), 0.0)
            sse[lam] = row

    evaluate(list(lambdas))
    if refine:
        best = min(sse, key=lambda v: float(sse[v].sum()))
        evaluate([best / 10.0, best * 10.0])
    lam_arr = np.array(sorted(sse))
    cv = np.array([sse[v] for v in lam_arr])
    chosen = float(lam_arr[int(np.argmin(cv.sum(axis=1)))])
    t2 = time.perf_counter()
    theta = full[chosen]
    fit_sse = max(float(theta @ (G @ theta) - 2.0 * theta @ b + yy.sum()), 0.0)
    return SparseFit(
        theta=theta,
        lambdas=lam_arr,
        cv_sse=cv,
        count=count,
        chosen=chosen,
        scale=scale,
        fit_sse=fit_sse,
        iterations=iters,
        converged=ok_all,
        unobserved_nodes=unobserved,
        timings={"normal_equations": rows.seconds + (t1 - t0), "cross_validation": t2 - t1},
    )
