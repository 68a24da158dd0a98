"""Synthetic data the least-squares tests share: a random table and an input that excites it."""

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
