"""Held-out scoring: cross-validation folds, pooled held-out residuals, sign-flip tests."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .context import Chain, Context, Fold
from .data import Rec

__all__ = ["Score", "correlation_length", "heldout_score", "make_folds", "sign_flip_p"]

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
