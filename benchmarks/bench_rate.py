"""Speed of the rate-dependent simulator against the classical one, measured in one run.

Prints samples/s of PreisachModel.simulate (ss15-1hz) and of RateDependentPreisachModel
.simulate (ss15-rate: 3 tables, the filter and the ln-rate basis every sample) on the same
inputs, and their ratio (target >= 0.30), for

  * a random walk (Gaussian steps: the filtered rate wanders across the knots), and
  * a 2 Hz triangle sweep (constant rate on a knot: the basis needs no logarithm),

plus the K = 1 rate model (the overhead of the rate machinery alone).  BLAS is pinned to one
thread (the simulators do not use it); the cores this process may use are printed.

Run:  python benchmarks/bench_rate.py [--samples N] [--levels N] [--repeats R]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from preisach import PreisachModel  # noqa: E402
from preisach.rate_model import RateDependentPreisachModel, triangle_rate  # noqa: E402


def random_walk(n: int, seed: int, step: float = 2.0, lo: float = -100.0, hi: float = 100.0):
    """Random walk with Gaussian steps (V), folded back into [lo, hi]."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0.0, step, n))
    span = hi - lo
    x = np.mod(x - lo, 2 * span)
    return lo + np.where(x > span, 2 * span - x, x)


def triangle(n: int, freq: float, dt: float, amp: float = 100.0):
    """Full-range triangle at ``freq`` Hz sampled every ``dt`` s."""
    ph = np.mod(np.arange(n) * dt * freq, 1.0)
    return amp * (4.0 * np.abs(ph - 0.5) - 1.0)


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
    ap.add_argument("--samples", type=int, default=4_000_000)
    ap.add_argument("--levels", type=int, default=201)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"cores available to this process: {cores} (BLAS threads pinned to 1)")
    classical = PreisachModel.builtin("ss15-1hz", levels=args.levels)
    rate = RateDependentPreisachModel.builtin("ss15-rate", levels=args.levels)
    one = RateDependentPreisachModel.from_models([classical], [400.0], rate.tau)
    print(f"classical: {classical}")
    print(f"rate:      {rate}")
    dt = 1e-3
    inputs = {
        "random walk (2 V steps)": random_walk(args.samples, seed=1),
        "2 Hz triangle (800 V/s)": triangle(args.samples, 2.0, dt),
    }
    for label, u in inputs.items():
        v0 = triangle_rate(2.0) if "triangle" in label else 0.0
        s0 = classical.negative_saturation()
        r0, o0 = rate.negative_saturation(v0), one.negative_saturation(v0)
        t_c = best_of(lambda u=u, s0=s0: classical.simulate(u, s0), args.repeats)
        t_r = best_of(lambda u=u, r0=r0: rate.simulate(u, r0, sample_time=dt), args.repeats)
        t_1 = best_of(lambda u=u, o0=o0: one.simulate(u, o0, sample_time=dt), args.repeats)
        n = u.size
        print(f"{label}, {n:.0e} samples, {args.levels} levels:")
        print(f"  classical simulate      {n / t_c / 1e6:7.1f} M samples/s")
        print(
            f"  rate model, K = 3       {n / t_r / 1e6:7.1f} M samples/s   "
            f"ratio {t_c / t_r:.2f} of classical"
        )
        print(
            f"  rate model, K = 1       {n / t_1 / 1e6:7.1f} M samples/s   "
            f"ratio {t_c / t_1:.2f} of classical"
        )


if __name__ == "__main__":
    main()
