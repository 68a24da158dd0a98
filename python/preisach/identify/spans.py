"""The samples of each recording a least-squares fit uses: delay pairing and burn-in.

Shared by the dense (:mod:`preisach.identify.lsq`) and the sparse
(:mod:`preisach.identify.lsq_sparse`) solver.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..initial_state import InitialState, burn_in_end, check_policy
from ..recording import SampledData

__all__ = ["FittedSpan", "fitted_spans"]


@dataclass(frozen=True)
class FittedSpan:
    """The samples of one recording a least-squares fit uses.

    ``u[start:]`` (V) and ``y[start:]`` (output units) are fitted; ``u`` holds the input
    samples that have a delayed output, ``y`` the outputs paired with them
    (``y[k]`` is the recording's ``y[k + delay]``); the samples before ``start`` only set
    the state (the burn-in).
    """

    name: str
    u: NDArray[np.float64]
    y: NDArray[np.float64]
    n_samples: int
    start: int
    exact_state: bool

    @property
    def n_used(self) -> int:
        """Number of fitted samples."""
        return int(self.u.size - self.start)


def fitted_spans(
    recordings: Sequence[SampledData],
    names: Sequence[str],
    levels: NDArray[np.float64],
    policy: InitialState,
    delay: int,
) -> tuple[list[FittedSpan], list[str]]:
    """Pair each recording's input with its delayed output and find its burn-in.

    Returns the spans and warnings (a recording whose input never saturates leaves the
    relays it never switches at -1: a constant output offset).  Shared by the dense and the
    sparse solver.
    """
    lo, hi = float(levels[0]), float(levels[-1])
    pol = check_policy(policy)
    spans: list[FittedSpan] = []
    warnings: list[str] = []
    for name, rec in zip(names, recordings):
        u = np.asarray(rec.u, dtype=float)
        y = np.asarray(rec.y, dtype=float)
        n_pairs = u.size - delay
        if n_pairs < 1:
            raise ValueError(f"{name}: {u.size} samples are too few for delay = {delay}")
        start, exact = 0, True
        if pol == "burn-in":
            start, exact = burn_in_end(u[:n_pairs], lo, hi)
            if not exact:
                warnings.append(
                    f"{name}: the input stays inside the table range ({float(u.min()):.6g} .. "
                    f"{float(u.max()):.6g} V of {lo:.6g} .. {hi:.6g} V) and never saturates; "
                    "relays it never switches are assumed at -1 (a constant output offset)"
                )
        # start < n_pairs: the burn-in ends at a sample of the recording
        spans.append(
            FittedSpan(
                name=name,
                u=np.ascontiguousarray(u[:n_pairs]),
                y=np.ascontiguousarray(y[delay : delay + n_pairs]),
                n_samples=int(u.size),
                start=int(start),
                exact_state=bool(exact),
            )
        )
    return spans, warnings
