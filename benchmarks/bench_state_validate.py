"""Cost per boundary piece of checking a state: ``State::validate`` on a long staircase.

``State::validate`` runs whenever a state is built or enters the C++ core (a Simulator, a
regressor, a batch...).  This times ``_core.State(u_min, u_max, u, b0, v, antidiag)`` from
arrays for a state with many pieces (a staircase of shrinking reversals) and for a one-piece
state, and prints the difference per piece: validation plus copying the piece, in ns.

Run:  python benchmarks/bench_state_validate.py [--pieces N] [--repeats N]
"""

from __future__ import annotations

import time

import numpy as np
from _bench import available_cores, parser
from preisach import PreisachModel, _core


def best_of(fn, repeats: int, inner: int) -> float:
    """Best time (s) of one call over ``repeats`` runs of ``inner`` calls."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t0) / inner)
    return best


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--pieces", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()

    model = PreisachModel.builtin("ss15-1hz", levels=41)
    # alternating maxima and minima closing in on 0 V: every reversal stays in the memory
    k = np.arange(args.pieces)
    amp = 99.0 * (1.0 - k / args.pieces)
    extrema = np.where(k % 2 == 0, amp, -amp)
    big = model.state_from_extrema(extrema.tolist())
    small = model.state_from_extrema([50.0])
    n_big, n_small = len(big.b0), len(small.b0)
    lo, hi = model.u_min, model.u_max

    def build(st: _core.State) -> tuple:
        return (lo, hi, st.input, st.b0, st.v, st.antidiag)

    big_args, small_args = build(big), build(small)
    t_big = best_of(lambda: _core.State(*big_args), args.repeats, 20)
    t_small = best_of(lambda: _core.State(*small_args), args.repeats, 2000)
    cores = available_cores()
    per_piece = (t_big - t_small) / (n_big - n_small) * 1e9
    print(f"cores obtained: {cores} (single-threaded measurement)")
    print(f"State from arrays, {n_big} pieces: {t_big * 1e6:.1f} us")
    print(f"State from arrays, {n_small} piece(s): {t_small * 1e6:.2f} us")
    print(f"per piece: {per_piece:.2f} ns (validate + copy)")


if __name__ == "__main__":
    main()
