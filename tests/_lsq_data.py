"""Synthetic devices and inputs the identification and diagnosis tests share."""

from __future__ import annotations

import numpy as np
from preisach import PreisachModel


def grid_model(levels: np.ndarray, seed: int) -> PreisachModel:
    """A model on ``levels`` with random positive cell masses (0.01 .. 0.1) and y_min -0.7."""
    rng = np.random.default_rng(seed)
    w = np.tril(rng.uniform(0.01, 0.1, (levels.size - 1, levels.size - 1)))
    return PreisachModel.from_weights(levels, w, y_min=-0.7)


def rich_input(n: int, seed: int, step: float = 0.08) -> np.ndarray:
    """A reflected random walk on [-1, 1] that touches both ends: it excites every cell."""
    rng = np.random.default_rng(seed)
    return np.clip(1.1 * np.sin(np.cumsum(rng.normal(0.0, step, n))), -1.0, 1.0)


def gaussian_model(n: int = 201) -> PreisachModel:
    """A smooth, steep classical device on [-10, 10] V tabulated at ``n`` levels.

    Gaussian density in r = (alpha - beta) / 2 (0.6 +/- 1.4 V) and c = (alpha + beta) / 2
    (-1 +/- 2.2 V), 16 V of output: steep for a 21-level grid, like the blind devices.
    """
    lv = np.linspace(-10.0, 10.0, n)
    a, b = np.meshgrid(lv, lv, indexing="ij")
    r, c = 0.5 * (a - b), 0.5 * (a + b)
    mu = np.exp(-0.5 * ((r - 0.6) / 1.4) ** 2 - 0.5 * ((c + 1.0) / 2.2) ** 2)
    mu = np.where(a > b, mu, 0.0)
    e = np.cumsum(np.cumsum(mu[:, ::-1], axis=1)[:, ::-1], axis=0)  # b <= beta <= alpha <= a
    return PreisachModel.from_everett(
        lambda x, z: (16.0 / e[-1, 0]) * e[np.searchsorted(lv, x), np.searchsorted(lv, z)], lv
    )
