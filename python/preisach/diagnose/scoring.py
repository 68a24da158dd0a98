"""Held-out scoring: cross-validation folds, pooled held-out residuals, sign-flip tests."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy import linalg, optimize

from .. import _core
from .context import Chain, Context, Fold
from .data import Mask, Rec

__all__ = [
    "ClassicalCheck",
    "FineSystem",
    "Score",
    "classical_check",
    "correlation_length",
    "fine_system",
    "heldout_score",
    "make_folds",
    "nameable_rms",
    "sign_flip_p",
]

Array = NDArray[np.float64]


@dataclass
class Score:
    """Held-out score of one chain (diagnosis recordings only)."""

    sse_blocks: Array  # SSE per held-out block
    n_blocks: Array  # samples per held-out block
    residuals: list[Array]  # held-out residual per recording (NaN where not scored)
    predictions: list[Array]  # held-out prediction per recording

    @property
    def mse(self) -> float:
        """Held-out mean-square error (V^2)."""
        return float(self.sse_blocks.sum() / max(self.n_blocks.sum(), 1))

    @property
    def rmse(self) -> float:
        """Held-out root-mean-square error (V)."""
        return math.sqrt(self.mse)

    def improvement(self, than: Score, sigma: float, seed: int = 0) -> tuple[float, float, float]:
        """Measure what this score improves on ``than``: the selection's three bars.

        Returns the relative reduction of the held-out RMSE, the held-out mean-square error
        removed in noise variances (``sigma``, V) and the one-sided sign-flip p over the
        held-out blocks (:func:`sign_flip_p`).
        """
        gain = 1.0 - self.rmse / than.rmse if than.rmse > 0 else 0.0
        expl = (than.mse - self.mse) / sigma**2 if sigma > 0 else float("inf")
        return gain, expl, sign_flip_p(than.sse_blocks - self.sse_blocks, seed=seed)


def make_folds(recs: list[Rec], scheme: str, max_groups: int = 3) -> list[Fold]:
    """Make the folds: ``"recordings"`` holds out groups of recordings, ``"blocks"`` time blocks.

    Identification recordings are always training data.
    """
    diag = [i for i, r in enumerate(recs) if not r.ident]
    if scheme == "recordings":
        k = min(len(diag), max_groups)
        groups = [diag[g::k] for g in range(k)]
        return [
            Fold(
                [r.usable & (j not in g) for j, r in enumerate(recs)],
                [r.usable & (j in g) for j, r in enumerate(recs)],
            )
            for g in groups
        ]
    if scheme == "blocks":
        return [
            Fold(
                [r.usable & ((r.fold != p) | r.ident) for r in recs],
                [r.usable & (r.fold == p) & (not r.ident) for r in recs],
            )
            for p in (0, 1)
        ]
    raise ValueError(f"cv: expected 'recordings', 'blocks' or 'auto', got {scheme!r}")


def heldout_score(ctx: Context, folds: list[Fold], chains: list[Chain], drift: bool) -> Score:
    """Pool held-out residuals: each sample is predicted by the fit of the fold that held it out."""
    nb = max(int(r.block.max()) for r in ctx.recs) + 1
    sse = np.zeros(nb)
    cnt = np.zeros(nb)
    res_all, pred_all = [], []
    for i, r in enumerate(ctx.recs):
        res = np.full(r.n, np.nan)
        pred = np.full(r.n, np.nan)
        for fold, ch in zip(folds, chains):
            m = fold.test[i]
            if not m.any():
                continue
            p = ctx.predict_one(i, ch)
            if drift:
                p = p + ctx.drift_heldout(i, r.y - p, m)
            res[m] = r.y[m] - p[m]
            pred[m] = p[m]
        ok = ~np.isnan(res)
        sse += np.bincount(r.block[ok], weights=res[ok] ** 2, minlength=nb)
        cnt += np.bincount(r.block[ok], minlength=nb)
        res_all.append(res)
        pred_all.append(pred)
    keep = cnt > 0
    return Score(sse[keep], cnt[keep], res_all, pred_all)


def sign_flip_p(d: Array, n_perm: int = 4000, seed: int = 0) -> float:
    """One-sided p-value of mean(d) > 0 by random sign flips of the block differences."""
    d = np.asarray(d, float)
    if d.size == 0 or not np.any(d):
        return 1.0
    obs = d.mean()
    rng = np.random.default_rng(seed)
    signs = rng.choice([-1.0, 1.0], size=(n_perm, d.size))
    null = (signs * np.abs(d)).mean(axis=1)
    return float((1 + np.count_nonzero(null >= obs)) / (n_perm + 1))


def nameable_rms(rmse: float, sigma: float, min_gain: float, noise_factor: float) -> float:
    """Smallest RMS (V) of held-out residual an effect must explain to pass the selection's bars.

    An effect whose fit removes a part of RMS ``e`` from a held-out residual of RMS ``rmse``
    leaves ``sqrt(rmse**2 - e**2)``: it lowers the held-out RMSE by ``min_gain`` only when
    ``e >= rmse * sqrt(1 - (1 - min_gain)**2)`` (0.436 ``rmse`` at 10 %), and explains
    ``noise_factor`` noise variances only when ``e >= sqrt(noise_factor) * sigma``.  The
    larger of the two is returned (the sign-flip test, p < ``alpha``, comes on top: it also
    needs the gain spread over the held-out blocks).  Above ``rmse`` no effect can pass:
    the residual itself is too small.
    """
    gain_part = rmse * math.sqrt(max(1.0 - (1.0 - min_gain) ** 2, 0.0))
    return float(max(gain_part, math.sqrt(max(noise_factor, 0.0)) * sigma))


def correlation_length(res: list[Array]) -> float:
    """Return the samples over which the residual stays correlated (integral scale, >= 1)."""
    lens = []
    for r in res:
        r = r[~np.isnan(r)]
        if r.size < 64:
            continue
        r = r - r.mean()
        n = min(r.size, 1 << 16)
        f = np.fft.rfft(r[:n], 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[:n]
        if ac[0] <= 0:
            continue
        ac = ac / ac[0]
        neg = np.flatnonzero(ac < 0.05)
        cut = int(neg[0]) if neg.size else n
        lens.append(max(1.0, 1.0 + 2.0 * float(ac[1:cut].sum())))
    return float(np.median(lens)) if lens else 1.0


#: levels of the fine classical model of :func:`classical_check`
CHECK_LEVELS = 61
#: weight of its density-roughness penalty (relative to the mean diagonal of the normal matrix)
CHECK_SMOOTHING = 1e-2
#: length (s) of the interleaved held-out stretches of :func:`classical_check`
CHECK_STRETCH = 0.01


def density_roughness(n: int) -> sp.csr_matrix:
    """Roughness of a Preisach density on an ``n``-level grid, as a quadratic form in theta.

    ``theta`` holds the Everett nodes E(i, j), j < i (the order of
    ``preisach._core.regressor_rows``) and the output offset.  The weight of each grid cell
    of the Preisach half-plane is the mixed second difference of the Everett nodes (the
    triangular cells on the diagonal count twice, per unit area); the roughness is the sum of
    squared differences of the weights of neighbouring cells, in alpha and in beta.  Returns
    ``D^T D`` (sparse, ``p x p``).
    """
    ii, jj = np.tril_indices(n, -1)
    p = ii.size + 1
    col = -np.ones((n, n), np.int64)
    col[ii, jj] = np.arange(ii.size)
    cell = -np.ones((n, n), np.int64)
    rows: list[int] = []
    cols: list[int] = []
    vals: list[float] = []
    r = 0
    for i in range(1, n):
        for j in range(i):
            w = 2.0 if j == i - 1 else 1.0
            for a, b, sgn in ((i, j, 1.0), (i - 1, j, -1.0), (i, j + 1, -1.0), (i - 1, j + 1, 1.0)):
                if a > b:
                    rows.append(r)
                    cols.append(int(col[a, b]))
                    vals.append(sgn * w)
            cell[i, j] = r
            r += 1
    M = sp.csr_matrix((vals, (rows, cols)), shape=(r, p))
    di: list[int] = []
    dj: list[int] = []
    for i in range(1, n):
        for j in range(i):
            for a, b in ((i + 1, j), (i, j + 1)):
                if a < n and b < a:
                    di.append(int(cell[i, j]))
                    dj.append(int(cell[a, b]))
    q = len(di)
    D = sp.csr_matrix(
        (np.r_[np.ones(q), -np.ones(q)], (np.r_[np.arange(q), np.arange(q)], np.r_[di, dj])),
        shape=(q, r),
    )
    DM = (D @ M).tocsr()
    return (DM.T @ DM).tocsr()


#: knots of the initial-state nuisance of :func:`classical_check` per recording
CHECK_STATE_KNOTS = 16
#: how far an unknown initial state's nuisance may exceed what the given model's unvisited
#: relays can make (:func:`unvisited_bound`): room for the fine model's own weights
STATE_BOUND_FACTOR = 1.5


def running_range_basis(
    u: Array, dt: float, knots: int, spacing: float
) -> tuple[Array, NDArray[np.int64]]:
    """Basis of the output change an unknown initial state makes (columns, n x k).

    With a classical Preisach model, two initial states of a recording give outputs that
    differ only by the relays the input has not yet reached: those with a threshold above
    the running maximum ``M(t)`` and below the running minimum ``m(t)``.  So the difference
    is a function of ``(M(t), m(t))``, which moves along one monotone path: a function
    ``h(s)`` of the running range ``s = M - m`` alone, an output offset once the input has
    visited both its extremes - no larger than :func:`unvisited_bound` at each knot.
    ``h`` is represented by hat functions of ``s`` on at most
    ``knots`` equal intervals of the final range; knots the input passes less than
    ``spacing`` seconds after the previous one are dropped (so that every hat is seen by
    training and held-out stretches alike).  Returns the basis and, per column, the sample
    at which its knot is first reached.
    """
    s = np.maximum.accumulate(u) - np.minimum.accumulate(u)
    top = float(s[-1])
    if top <= 0:
        return np.ones((u.size, 1)), np.array([u.size - 1], dtype=np.int64)
    kept = [0.0]
    t_prev = 0.0
    for v in np.linspace(0.0, top, knots + 1)[1:]:
        t_v = float(np.argmax(s >= v - 1e-12 * top)) * dt
        if t_v - t_prev >= spacing or v == top:
            if v == top and t_v - t_prev < spacing and len(kept) > 1:
                kept[-1] = v
            else:
                kept.append(float(v))
            t_prev = t_v
    x = np.asarray(kept)
    if x.size < 2:
        return np.ones((u.size, 1)), np.array([u.size - 1], dtype=np.int64)
    k = np.clip(np.searchsorted(x, s, side="right") - 1, 0, x.size - 2)
    w = np.clip((s - x[k]) / (x[k + 1] - x[k]), 0.0, 1.0)
    B = np.zeros((u.size, x.size))
    rows = np.arange(u.size)
    B[rows, k] = 1.0 - w
    B[rows, k + 1] = w
    at = np.searchsorted(s, x - 1e-12 * top)  # s is non-decreasing
    return B, np.minimum(at, u.size - 1)


def unresolved_start(u: Array, dt: float, stretch: float, knots: int) -> Mask:
    """Mark the samples an unknown initial state decides where no other stretch sees them.

    While the running range ``s = M - m`` grows, the input reaches relays the recording has
    not visited, and the output depends on their initial state.  The state basis
    (:func:`running_range_basis`) follows that dependence with knots one ``1 / knots`` of the
    final range apart; where ``s`` grows by more than one such interval within one
    ``stretch``-second stretch (a start-up step from rest, a first fast excursion), the
    output inside the move depends on the initial state's detail between the knots, and only
    that stretch's own samples show it: the interleaved folds cannot predict them from their
    neighbours, at any resolution.  Those stretches are marked (True), and with them a
    stretch next to one where the range grows too (the start of a step that the stretch
    boundary cut): it interpolates toward a knot only the move reaches.
    """
    n = u.size
    s = np.maximum.accumulate(u) - np.minimum.accumulate(u)
    top = float(s[-1])
    L = max(1, int(round(stretch / dt)))
    if top <= 0 or n <= 1:
        return np.zeros(n, dtype=bool)
    ends = np.minimum(np.arange(L - 1, n + L - 1, L), n - 1)  # last sample of each stretch
    grow = np.diff(np.r_[0.0, s[ends]])
    bad = grow > top / knots
    # a stretch where the range grows next to such a move interpolates toward a knot only
    # the move reaches: the same undetermined detail (blind seed-24 case 015: the first 10 ms
    # of a start-up step, 9 x the noise without a drift and 26 x with one)
    near = np.zeros_like(bad)
    near[:-1] |= bad[1:]
    near[1:] |= bad[:-1]
    bad |= near & (grow > 0)
    return np.asarray(bad[np.arange(n) // L], dtype=bool)


def unvisited_bound(model: Any, u: Array, at: NDArray[np.int64]) -> Array:
    """Largest output difference (V) two initial states can make at the samples ``at``.

    Two initial states differ only in the relays the input has not reached by then: those
    with ``alpha`` above its running maximum ``M`` and ``beta`` below its running minimum
    ``m``.  Flipping all of them changes the output by twice their mass,
    ``2 [E(u_max, u_min) - E(M, u_min) - E(u_max, m) + E(M, m)]`` with ``model``'s Everett
    function (the mass of a triangle).
    """
    M = np.maximum.accumulate(u)[at]
    m = np.minimum.accumulate(u)[at]
    hi = np.full(M.size, float(model.u_max))
    lo = np.full(M.size, float(model.u_min))
    e = model.everett
    D = e(hi, lo) - e(M, lo) - e(hi, np.minimum(hi, m)) + e(M, np.minimum(M, m))
    return np.asarray(2.0 * np.maximum(D, 0.0), dtype=float)


@dataclass
class FineSystem:
    """Normal equations of the fine classical model on interleaved stretches (two folds).

    Built by :func:`fine_system` (once per context) and :meth:`extended`.  Columns: the
    ``p`` Everett nodes and output offset of the ``levels``-level grid (order of
    ``preisach._core.regressor_rows``), then per recording its initial-state basis
    (:func:`running_range_basis`, ``n_state[i]`` columns); an extended system then has per
    recording columns of its own (:attr:`own_cols`) and last the columns all recordings
    share.  ``A[k]``/``rhs[k]`` hold the samples of fold ``k`` (0, 1: alternate stretches of
    the diagnosis recordings; 2: the identification recordings, always training).
    """

    ctx: Context
    p: int
    A: Array  # (3, P, P)
    rhs: Array  # (3, P)
    w0: Array  # the given model's Everett nodes and offset, zeros elsewhere
    Q: Array  # density roughness (p x p), scaled to trace p
    folds: list[NDArray[np.int64]]
    regs: list[sp.csr_matrix]
    feats: list[Array]  # per recording: its columns' features (state basis, own, shared)
    cols: list[NDArray[np.int64]]  # per recording: the indices of those columns
    n_state: list[int]
    nb: int  # number of time blocks
    #: bounds of every coefficient (-inf/inf where free): an unknown initial state's basis
    #: coefficients stay within what the relays not yet visited can make
    #: (:func:`unvisited_bound`)
    lo: Array
    hi: Array
    #: per recording: the indices of its own added columns (none in the base system)
    own_cols: list[NDArray[np.int64]] = field(default_factory=list)
    #: the base fits per smoothing (:meth:`fit`)
    _fits: dict[float, tuple[list[Array], Array, Array]] = field(default_factory=dict, repr=False)

    def extended(
        self, own: list[Array] | None = None, shared: list[Array] | None = None
    ) -> FineSystem:
        """Return this system with more columns: ``own`` per recording, ``shared`` by all.

        ``own[i]`` and ``shared[i]`` hold recording ``i``'s features (rows: its samples).
        Only the new rows and columns of the normal equations are computed.
        """
        recs = self.ctx.recs
        P0 = self.A.shape[1]
        widths = [0 if own is None else int(own[i].shape[1]) for i in range(len(recs))]
        offs = P0 + np.cumsum([0, *widths])
        P = int(offs[-1]) + (0 if shared is None else int(shared[0].shape[1]))
        A = np.zeros((3, P, P))
        A[:, :P0, :P0] = self.A
        rhs = np.zeros((3, P))
        rhs[:, :P0] = self.rhs
        p = self.p
        feats, cols, own_cols = [], [], []
        for i, r in enumerate(recs):
            parts = ([] if own is None else [own[i]]) + ([] if shared is None else [shared[i]])
            N = np.hstack(parts) if parts else np.zeros((r.n, 0))
            new = np.r_[int(offs[i]) : int(offs[i + 1]), int(offs[-1]) : P]
            F, old, R = self.feats[i], self.cols[i], self.regs[i]
            for k in range(3):
                m = self.folds[i] == k
                if not m.any():
                    continue
                Nm = N[m]
                A[k][:p, new] += np.asarray(R[m].T @ Nm)
                A[k][np.ix_(old, new)] += F[m].T @ Nm
                A[k][np.ix_(new, new)] += Nm.T @ Nm
                rhs[k, new] += Nm.T @ r.y[m]
            feats.append(np.hstack([F, N]))
            cols.append(np.r_[old, new])
            own_cols.append(np.arange(int(offs[i]), int(offs[i + 1])))
        for k in range(3):  # the cross blocks were filled above the diagonal only
            A[k, P0:, :P0] = A[k, :P0, P0:].T
        extra = np.full(P - P0, np.inf)
        return FineSystem(
            self.ctx,
            p,
            A,
            rhs,
            np.r_[self.w0, np.zeros(P - P0)],
            self.Q,
            self.folds,
            self.regs,
            feats,
            cols,
            self.n_state,
            self.nb,
            np.r_[self.lo, -extra],
            np.r_[self.hi, extra],
            own_cols,
        )

    def fit(self, smoothing: float) -> tuple[list[Array], Array, Array]:
        """Both folds' coefficients, held-out SSE and sample count per time block.

        Cached per ``smoothing``: the classical check and every test against it share it.
        """
        if smoothing not in self._fits:
            ws = [self.solve(k, smoothing) for k in (0, 1)]
            got = [self.heldout_sse(k, w) for k, w in enumerate(ws)]
            self._fits[smoothing] = (ws, got[0][0] + got[1][0], got[0][1] + got[1][1])
        return self._fits[smoothing]

    def solve(
        self,
        k: int,
        smoothing: float,
        keep: NDArray[np.int64] | None = None,
        add: list[tuple[int, Array]] | None = None,
    ) -> Array:
        """Return the coefficients fitted holding out fold ``k`` (zeros outside ``keep``).

        ``add``: penalty blocks ``(first column, matrix)`` added to the normal matrix.  The
        bounded coefficients (:attr:`lo`, :attr:`hi`) are solved exactly with the one
        Cholesky factor of the normal matrix: when the unconstrained solution leaves a bound,
        the free coefficients follow the bounded ones through ``Y = N^-1[:, b]`` (the
        bounded block of the inverse is the inverse of the Schur complement), and the small
        box-constrained least-squares problem in the bounded ones is solved by
        bounded-variable least squares.
        """
        N, rh = self.normal(k, smoothing)
        for c0, pen in add or []:
            N[c0 : c0 + pen.shape[0], c0 : c0 + pen.shape[0]] += pen
        P = N.shape[0]
        idx = np.arange(P) if keep is None else np.asarray(keep)
        N, rh = N[np.ix_(idx, idx)], rh[idx]
        lo, hi = self.lo[idx], self.hi[idx]
        fac = linalg.cho_factor(N, check_finite=False)
        x = linalg.cho_solve(fac, rh, check_finite=False)
        bnd = np.flatnonzero(np.isfinite(lo) | np.isfinite(hi))
        if bnd.size and np.any((x[bnd] < lo[bnd]) | (x[bnd] > hi[bnd])):
            E = np.zeros((idx.size, bnd.size))
            E[bnd, np.arange(bnd.size)] = 1.0
            Y = linalg.cho_solve(fac, E, check_finite=False)
            Yb = 0.5 * (Y[bnd] + Y[bnd].T)  # the inverse of the Schur complement S
            R = linalg.cho_factor(Yb, lower=True, check_finite=False)
            # 1/2 (c - x_b)^T S (c - x_b) = 1/2 |R^-1 (c - x_b)|^2 with Yb = R R^T
            Rinv = linalg.solve_triangular(R[0], np.eye(bnd.size), lower=True)
            sol = optimize.lsq_linear(Rinv, Rinv @ x[bnd], bounds=(lo[bnd], hi[bnd]), method="bvls")
            x = x + Y @ linalg.cho_solve(R, sol.x - x[bnd], check_finite=False)
            x[bnd] = sol.x  # exactly within the bounds, not to rounding
        w = np.zeros(P)
        w[idx] = x
        return w

    def normal(self, k: int, smoothing: float) -> tuple[Array, Array]:
        """Return the penalised normal matrix and right-hand side of the fit holding out fold k."""
        p = self.p
        N = self.A[1 - k] + self.A[2]
        scale = max(float(np.trace(N[:p, :p])) / p, 1e-300)
        N[:p, :p] += smoothing * scale * self.Q
        N[np.diag_indices(N.shape[0])] += 1e-7 * scale
        return N, self.rhs[1 - k] + self.rhs[2] + 1e-7 * scale * self.w0

    def heldout_sse(self, k: int, w: Array) -> tuple[Array, Array]:
        """SSE and sample count per time block of fold k's samples predicted by ``w``."""
        sse = np.zeros(self.nb)
        cnt = np.zeros(self.nb)
        for i, r in enumerate(self.ctx.recs):
            m = self.folds[i] == k
            if r.ident or not m.any():
                continue
            res = r.y[m] - (self.regs[i][m] @ w[: self.p] + self.feats[i][m] @ w[self.cols[i]])
            sse += np.bincount(r.block[m], weights=res**2, minlength=self.nb)
            cnt += np.bincount(r.block[m], minlength=self.nb)
        return sse, cnt


def fine_system(
    ctx: Context,
    *,
    levels: int = CHECK_LEVELS,
    stretch: float = CHECK_STRETCH,
    state_knots: int = CHECK_STATE_KNOTS,
) -> FineSystem:
    """Return the normal equations of :func:`classical_check`'s fine classical model.

    Assembled once per context and these settings (kept in ``ctx.fine_systems``); an
    effect's columns are added with :meth:`FineSystem.extended`.  See :class:`FineSystem`.
    """
    key = (int(levels), float(stretch), int(state_knots))
    if key not in ctx.fine_systems:
        ctx.fine_systems[key] = _assemble_fine_system(ctx, *key)
    fs: FineSystem = ctx.fine_systems[key]
    return fs


def release_fine_systems(ctx: Context, levels: int) -> None:
    """Forget :func:`fine_system`'s normal equations on ``levels``, for grids used once.

    Their memory is about 0.6 GB on 101 levels.
    """
    for key in [k for k in ctx.fine_systems if k[0] == int(levels)]:
        del ctx.fine_systems[key]


def _assemble_fine_system(
    ctx: Context, levels: int, stretch: float, state_knots: int
) -> FineSystem:
    """Assemble :func:`fine_system`'s normal equations."""
    n = int(levels)
    lv = np.linspace(ctx.model.u_min, ctx.model.u_max, n)
    p = n * (n - 1) // 2 + 1
    # an unknown initial state is free within what the relays not yet visited can make
    # (unvisited_bound, with room for the fine weights: STATE_BOUND_FACTOR); a known one (a
    # saturation, a given state) leaves only the recording's own offset - a function of the
    # running range there, or an unbounded one on an unknown state, would be freedom no
    # initial state gives, enough to follow a slow drift while the range grows (blind seed
    # 16 case 017: a random-walk drift that gained 40 % on held-out blocks added only 0.03
    # noise variances to the unbounded fine model and was refused; with the bound it is named)
    state: list[Array] = []
    bounds: list[Array] = []
    for r in ctx.recs:
        if r.history is None:
            state.append(np.ones((r.n, 1)))
            bounds.append(np.array([np.inf]))
        else:
            B, at = running_range_basis(r.u, r.dt, state_knots, 4.0 * stretch)
            state.append(B)
            bd = STATE_BOUND_FACTOR * unvisited_bound(ctx.model, r.u, at)
            bounds.append(np.maximum(bd, 1e-9 * max(ctx.y_span, 1e-12)))  # a box, not a point
    offs = np.cumsum([0] + [B.shape[1] for B in state])
    q = int(offs[-1])
    P = p + q
    A = np.zeros((3, P, P))
    rhs = np.zeros((3, P))
    folds: list[NDArray[np.int64]] = []
    regs: list[sp.csr_matrix] = []
    feats: list[Array] = []
    cols_of: list[NDArray[np.int64]] = []
    for i, r in enumerate(ctx.recs):
        if r.ident:
            fold = np.where(r.usable, 2, -1)
        else:
            L = max(1, int(round(stretch / r.dt)))
            use = r.usable
            if r.history is not None:  # what the unknown initial state alone decides
                use = use & ~unresolved_start(r.u, r.dt, stretch, state_knots)
            fold = np.where(use, (np.arange(r.n) // L) % 2, -1)
        s0 = ctx.state(i, ctx.given)
        g, b, _, _, _, _ = _core.normal_equations(
            lv, r.u, r.y, s0, fold.astype(np.int32), 3, "clamp"
        )
        indptr, idx, data, _ = _core.regressor_rows(lv, r.u, s0, "clamp")
        R = sp.csr_matrix((data, idx.astype(np.int64), indptr), shape=(r.n, p))
        B = state[i]
        cols = np.arange(p + int(offs[i]), p + int(offs[i + 1]))
        folds.append(fold)
        regs.append(R)
        feats.append(B)
        cols_of.append(cols)
        for k in range(3):
            m = fold == k
            if not m.any():
                continue
            Bm = B[m]
            A[k, :p, :p] += g[k]
            A[k][:p, cols] += np.asarray(R[m].T @ Bm)
            A[k][np.ix_(cols, cols)] += Bm.T @ Bm
            rhs[k, :p] += b[k]
            rhs[k, cols] += Bm.T @ r.y[m]
    for k in range(3):  # the cross blocks were filled above the diagonal only
        A[k, p:, :p] = A[k, :p, p:].T
    a, bb = np.meshgrid(lv, lv, indexing="ij")
    e = ctx.model.everett(a, np.minimum(a, bb))
    ii, jj = np.tril_indices(n, -1)
    w0 = np.concatenate([e[ii, jj], [ctx.model.y_min], np.zeros(q)])
    Q = density_roughness(n).toarray()
    Q *= p / max(float(np.trace(Q)), 1e-300)
    nb = max(int(r.block.max()) for r in ctx.recs) + 1
    lo, hi = np.full(P, -np.inf), np.full(P, np.inf)
    for i, bd in enumerate(bounds):
        c = p + int(offs[i]) + np.arange(bd.size)
        lo[c], hi[c] = -bd, bd
    return FineSystem(
        ctx,
        p,
        A,
        rhs,
        w0,
        Q,
        folds,
        regs,
        feats,
        cols_of,
        [B.shape[1] for B in state],
        nb,
        lo,
        hi,
        [np.zeros(0, np.int64) for _ in ctx.recs],
    )


@dataclass
class ClassicalCheck:
    """Outcome of :func:`classical_check`."""

    ratio: float  # held-out RMS of the fine classical model / noise
    rmse: float  # its held-out RMSE (V)
    levels: int
    smoothing: float
    stretch: float  # length (s) of the interleaved held-out stretches
    seconds: float
    sse_blocks: Array  # held-out SSE per time block of the recordings (as in Score)

    def as_dict(self) -> dict[str, float | int]:
        """JSON-ready fields."""
        return {
            "ratio": self.ratio,
            "heldout_rmse": self.rmse,
            "levels": self.levels,
            "smoothing": self.smoothing,
            "stretch_s": self.stretch,
            "seconds": self.seconds,
        }


def classical_check(
    ctx: Context,
    sigma: float,
    *,
    levels: int = CHECK_LEVELS,
    smoothing: float = CHECK_SMOOTHING,
    stretch: float = CHECK_STRETCH,
    state_knots: int = CHECK_STATE_KNOTS,
) -> ClassicalCheck:
    """How close the best-resolved classical Preisach model comes to the diagnosis recordings.

    A classical (rate-independent, congruent, memoryless between reversals) Preisach model
    on a fine ``levels``-level grid over the model's input range, its density kept smooth by
    a roughness penalty (:func:`density_roughness`, weight ``smoothing`` relative to the
    mean diagonal of the normal matrix; a ridge of 1e-7 toward the given model's Everett
    function fixes what nothing constrains), with each recording's unknown initial state
    free (the chosen one plus :func:`running_range_basis`, whose coefficients stay within
    1.5 x what the relays not yet visited can make, :func:`unvisited_bound`; a recording
    whose initial state is known gets its own output offset only), is fitted by least
    squares to
    the identification recordings and every other ``stretch``-second stretch of the
    diagnosis recordings, and predicts the stretches in between (two folds, each sample
    predicted by the fit that did not see it).

    Interleaved stretches much shorter than the experiments' features test *resolution*:
    the held-out samples lie between training samples on the same branches, so a residual
    that a finer classical model explains drops to the noise, while a missing effect that
    no rate-independent, congruent model can produce (creep or drift while the input holds,
    rate dependence across experiments, a delay, ringing) stays.  The time-block folds of
    the selection instead hold out whole seconds, whose reversal points a fine grid has not
    seen - the right test for an effect, too harsh for the base's resolution.  What an
    effect's own columns add to this model is :func:`beyond_classical`.
    """
    t0 = time.perf_counter()
    fs = fine_system(ctx, levels=levels, stretch=stretch, state_knots=state_knots)
    _, sse_b, cnt_b = fs.fit(smoothing)
    rmse = math.sqrt(float(sse_b.sum()) / max(float(cnt_b.sum()), 1.0))
    ratio = rmse / sigma if sigma > 0 else float("inf")
    seconds = time.perf_counter() - t0
    return ClassicalCheck(
        ratio,
        rmse,
        int(levels),
        float(smoothing),
        float(stretch),
        seconds,
        sse_b[cnt_b > 0],
    )


@dataclass
class BeyondClassical:
    """Outcome of :func:`beyond_classical`."""

    gain: float  # held-out MSE lowered by the columns, in noise variances
    p: float  # one-sided sign-flip p over the recordings' time blocks
    ratio_classical: float  # held-out RMS / noise, fine classical model
    ratio_with: float  # held-out RMS / noise, with the columns
    coef: Array  # the columns' coefficients (the mean of the two folds' fits)
    curves: list[Array]  # what the columns make (V), per recording
    seconds: float

    def passes(self, bar: float, alpha: float = 0.01) -> bool:
        """Whether the columns add at least ``bar`` noise variances at level ``alpha``."""
        return bool(self.gain >= bar and self.p < alpha)


def beyond_classical(
    ctx: Context,
    sigma: float,
    columns: list[Array] | None = None,
    *,
    own: list[Array] | None = None,
    own_penalties: list[Array] | None = None,
    levels: int = CHECK_LEVELS,
    smoothing: float = CHECK_SMOOTHING,
    stretch: float = CHECK_STRETCH,
    state_knots: int = CHECK_STATE_KNOTS,
    seed: int = 0,
    penalty: Array | None = None,
    kept: list[Array] | None = None,
) -> BeyondClassical:
    """Measure what an effect's own columns add to :func:`classical_check`'s fine model.

    ``columns``: per recording, the features (one column each, shared by all recordings) of
    an effect whose output is linear in its coefficients - a static curve of the output, a
    calibration, rate-dependent Everett increments; ``own``: per recording, columns of its
    own (a sensor drift's spline in time, which wanders differently in every recording).
    Both models, without and with them, are fitted by least squares exactly as the fine
    classical model is (to the identification recordings and every other ``stretch``-second
    stretch of the diagnosis recordings, each recording's unknown initial state free) and
    predict the stretches in between (two folds).  What the columns gain there is what no
    classical model makes: a candidate whose held-out gain on the selection's time blocks a
    fine classical model explains as well was explaining the base's resolution or its
    initial states, not its own physics.  ``penalty``: the effect's own regularisation of
    the shared coefficients (``m x m``, relative to the mean diagonal of their normal
    matrix), e.g. a smoothness across rate; ``own_penalties``: per recording, the penalty
    (absolute, V^-2 units of the normal matrix) of its own columns.  ``kept``: per recording,
    what the effects already kept make (columns shared by all recordings, a free scale each),
    in both models - the effect must add to the fine model *and* them, and what they explain
    is not left in the blocks the sign-flip test compares.  ``sigma`` is the noise (V).
    :attr:`BeyondClassical.coef` holds the added coefficients (own, then shared).
    """
    t0 = time.perf_counter()
    base = fine_system(ctx, levels=levels, stretch=stretch, state_knots=state_knots)
    if kept is not None:
        base = base.extended(shared=kept)
    _, sse0, cnt = base.fit(smoothing)
    fs = base.extended(own=own, shared=columns)
    P0, P = base.A.shape[1], fs.A.shape[1]
    m = 0 if columns is None else int(columns[0].shape[1])
    fixed = [(int(c[0]), pen) for c, pen in zip(fs.own_cols, own_penalties or []) if c.size]
    sse1 = np.zeros(fs.nb)
    w_mean = np.zeros(P)
    for k in (0, 1):
        add = list(fixed)
        if penalty is not None and m:
            block = fs.A[1 - k, P - m :, P - m :] + fs.A[2, P - m :, P - m :]
            add.append((P - m, penalty * max(float(np.trace(block)) / m, 1e-300)))
        w = fs.solve(k, smoothing, add=add)
        sse1 += fs.heldout_sse(k, w)[0]
        w_mean += 0.5 * w
    tot = max(float(cnt.sum()), 1.0)
    mse0, mse1 = float(sse0.sum()) / tot, float(sse1.sum()) / tot
    pos = sigma > 0
    n_old = [base.feats[i].shape[1] for i in range(len(ctx.recs))]
    return BeyondClassical(
        (mse0 - mse1) / sigma**2 if pos else float("inf"),
        sign_flip_p((sse0 - sse1)[cnt > 0], seed=seed),
        math.sqrt(mse0) / sigma if pos else float("inf"),
        math.sqrt(mse1) / sigma if pos else float("inf"),
        w_mean[P0:],
        [F[:, n:] @ w_mean[c[n:]] for F, c, n in zip(fs.feats, fs.cols, n_old)],
        time.perf_counter() - t0,
    )
