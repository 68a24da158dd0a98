"""Inverse speed: the exact inverse against the simulator, and the worst `.step()` latency.

Prints, from one run on this machine (the machine is shared: ratios measured in the same run
are what matter):
  * samples/s of PreisachModel.inverse on a random-reversal reference (201-level SS15 table,
    single thread) and of PreisachModel.simulate on the input it returns, and their ratio;
  * the latency of Inverter.step() per sample, timed inside C++ around each step (the two
    clock reads, ~20-50 ns, included): median, 99.9 % and worst over the reference, and the
    worst over full-range jumps from neutral states (the slowest path: a quadratic piece per
    grid line crossed).

Run:  python benchmarks/bench_inverse.py [--samples N] [--repeats R]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # BLAS pinned before numpy loads

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from preisach import PreisachModel, _core  # noqa: E402


def random_reversals(model: PreisachModel, n: int, seed: int) -> np.ndarray:
    """Reference output (V): ramps between random turning points inside the output range."""
    rng = np.random.default_rng(seed)
    lo, hi = model.y_min, model.y_max
    margin = 0.02 * (hi - lo)
    parts, total, y0 = [], 0, 0.5 * (lo + hi)
    while total < n:
        y1 = rng.uniform(lo + margin, hi - margin)
        m = int(rng.integers(20, 2000))
        parts.append(np.linspace(y0, y1, m, endpoint=False))
        total += m
        y0 = y1
    return np.concatenate(parts)[:n]


def best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--samples", type=int, default=5_000_000)
    ap.add_argument("--levels", type=int, default=201)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"cores obtained: {cores} (of {os.cpu_count()}); BLAS threads pinned to 1")

    model = PreisachModel.builtin("ss15-1hz", levels=args.levels)
    y_ref = random_reversals(model, args.samples, seed=1)
    s0 = model.anhysteretic_state()
    r = model.inverse(y_ref, s0)
    assert r.unreachable == 0, r.unreachable
    t_inv = best_of(lambda: model.inverse(y_ref, s0), args.repeats)
    t_sim = best_of(lambda: model.simulate(r.input, s0), args.repeats)
    inv_rate, sim_rate = args.samples / t_inv, args.samples / t_sim
    print(
        f"inverse : {inv_rate / 1e6:7.2f} M samples/s  ({args.samples} samples, "
        f"{args.levels} levels, random reversals, max |y - y_ref| = {r.max_error:.1e} V)"
    )
    print(f"simulate: {sim_rate / 1e6:7.2f} M samples/s  (the same input)")
    print(f"inverse / simulate time ratio: {t_inv / t_sim:.2f}")

    ns, _ = _core.invert_timed(model._table, y_ref[:1_000_000], s0)
    q = np.percentile(ns, [50, 99.9, 100])
    print(
        f".step() latency on the reference: median {q[0]:.0f} ns, 99.9 % {q[1]:.0f} ns, "
        f"worst {q[2]:.0f} ns"
    )
    worst = 0.0
    for level in np.linspace(-90, 90, 13):
        state = model.neutral_state(float(level))
        for target in (model.y_max - 1e-3, model.y_min + 1e-3):
            ns1, _ = _core.invert_timed(model._table, np.array([target]), state)
            worst = max(worst, float(ns1[0]))
    print(f".step() latency, full-range jump from a neutral state: worst {worst:.0f} ns")


if __name__ == "__main__":
    main()
