"""Speed of the rate-dependent simulator against the classical one, measured in one run.

Prints samples/s of PreisachModel.simulate (ss15-1hz) and of RateDependentPreisachModel
.simulate (ss15-rate: 3 tables, the filter and the rate basis every sample) on the same
inputs, and their ratio (target >= 0.30), for

  * a random walk (Gaussian steps: the filtered rate wanders across the knots), and
  * a 2 Hz triangle sweep (constant rate on a knot: the basis needs no logarithm),

for ss15-rate interpolating in ln(rate) (the built-in) and in the rate itself (what
identify_rate chooses from two sweep rates), plus the K = 1 rate model (the overhead of the
rate machinery alone).  BLAS is pinned to one thread (the simulators do not use it); the cores
this process may use are printed.

Run:  python benchmarks/bench_rate.py [--samples N] [--levels N] [--repeats R]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from _bench import available_cores, best_of, parser  # noqa: E402
from bench_simulate import random_walk  # noqa: E402
from preisach import PreisachModel  # noqa: E402
from preisach.rate_model import RateDependentPreisachModel, triangle_rate  # noqa: E402


def triangle(n: int, freq: float, dt: float, amp: float = 100.0) -> np.ndarray:
    """Full-range triangle at ``freq`` Hz sampled every ``dt`` s."""
    ph = np.mod(np.arange(n) * dt * freq, 1.0)
    return amp * (4.0 * np.abs(ph - 0.5) - 1.0)


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--samples", type=int, default=4_000_000)
    ap.add_argument("--levels", type=int, default=201)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()

    print(f"cores available to this process: {available_cores()} (BLAS threads pinned to 1)")
    classical = PreisachModel.builtin("ss15-1hz", levels=args.levels)
    rates = {
        "rate model, K = 3, ln v": RateDependentPreisachModel.builtin("ss15-rate", args.levels),
        "rate model, K = 3, v   ": RateDependentPreisachModel.builtin(
            "ss15-rate", args.levels, scale="linear"
        ),
    }
    tau = rates["rate model, K = 3, ln v"].tau
    rates["rate model, K = 1      "] = RateDependentPreisachModel.from_models(
        [classical], [400.0], tau
    )
    print(f"classical: {classical}")
    dt = 1e-3
    inputs = {
        "random walk (2 V steps)": random_walk(args.samples, seed=1),
        "2 Hz triangle (800 V/s)": triangle(args.samples, 2.0, dt),
    }
    for label, u in inputs.items():
        v0 = triangle_rate(2.0) if "triangle" in label else 0.0
        s0 = classical.negative_saturation()
        t_c, _ = best_of(lambda u=u, s0=s0: classical.simulate(u, s0), args.repeats)
        n = u.size
        print(f"{label}, {n:.0e} samples, {args.levels} levels:")
        print(f"  classical simulate      {n / t_c / 1e6:7.1f} M samples/s")
        for name, m in rates.items():
            r0 = m.negative_saturation(v0)
            t_r, _ = best_of(
                lambda u=u, m=m, r0=r0: m.simulate(u, r0, sample_time=dt), args.repeats
            )
            print(f"  {name} {n / t_r / 1e6:7.1f} M samples/s   ratio {t_c / t_r:.2f} of classical")


if __name__ == "__main__":
    main()
