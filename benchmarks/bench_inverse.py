"""Inverse speed: the exact inverse against the simulator, and the worst `.step()` latency.

Prints, from one run on this machine (the machine is shared: ratios measured in the same run
are what matter):
  * samples/s of PreisachModel.inverse on a random-reversal reference (201-level SS15 table,
    single thread) and of PreisachModel.simulate on the input it returns, and their ratio;
  * the latency of Inverter.step() per sample, timed inside C++ around each step (the two
    clock reads, ~20-50 ns, included): percentiles and worst over the reference, and the
    worst over full-range jumps from neutral states and deep staircases (the slowest paths:
    a whole antidiagonal piece, or many stack pieces, crossed in one step).

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
    ap.add_argument("--jump-repeats", type=int, default=21)
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
    q = np.percentile(ns, [50, 99, 99.9, 99.99, 100])
    print(
        f".step() latency on the reference ({ns.size} steps, each timed): median {q[0]:.0f} ns, "
        f"99 % {q[1]:.0f} ns, 99.9 % {q[2]:.0f} ns, 99.99 % {q[3]:.0f} ns, worst {q[4]:.0f} ns"
    )
    # The slowest paths: full-range jumps from neutral states (an antidiagonal piece crossed
    # whole) and from deep staircases (many pieces wiped out at once).  Each jump is timed
    # `repeats` times from the same state: the median is the path's cost, the maximum adds
    # whatever the OS did meanwhile (a shared machine preempts).
    rng = np.random.default_rng(2)
    starts = [model.neutral_state(float(level)) for level in np.linspace(-90, 90, 13)]
    for _ in range(6):  # decaying random oscillations: 20-40 turning points on the stack
        sim = model.simulator(model.anhysteretic_state())
        lo, hi = model.u_min, model.u_max
        for k in range(int(rng.integers(20, 40))):
            w = 0.5 * (hi - lo)
            lo, hi = lo + rng.uniform(0.02, 0.1) * w, hi - rng.uniform(0.02, 0.1) * w
            sim.step(hi if k % 2 == 0 else lo)
        starts.append(sim.state)
    medians, raw = [], []
    for state in starts:
        for target in (model.y_max - 1e-3, model.y_min + 1e-3):
            t1 = [
                float(_core.invert_timed(model._table, np.array([target]), state)[0][0])
                for _ in range(args.jump_repeats)
            ]
            medians.append(float(np.median(t1)))
            raw.append(max(t1))
    print(
        f".step() latency, full-range jumps ({len(medians)} jumps from {len(starts)} neutral and "
        f"deep-staircase states, {args.jump_repeats} times each): worst path (median of its "
        f"repeats) {max(medians):.0f} ns, worst single time {max(raw):.0f} ns; "
        f"target < 5000 ns: {'met' if max(medians) < 5000 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
