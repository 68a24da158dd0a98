"""Simulation speed: the C++ boundary-tracking simulator against a NumPy relay grid.

Prints, from one run on this machine (ratios are what matter: machines here are shared):
  * samples/s of PreisachModel.simulate on a 1e7-sample random walk (41-level table);
  * samples/s of the plain NumPy relay-grid reference (200 x 200 cells) on the same input
    (a prefix of it: the reference is too slow for all of it), its BLAS pinned to one thread
    (a fair single-core reference), and the ratio;
  * batch throughput on 1 thread and on the cores obtained, and the speed-up;
  * the same table interpolated cubically (a 4 x 4 node stencil per look-up instead of 2 x 2)
    against bilinearly: samples/s and the ratio.

Every speed-up is printed next to the cores this process obtained (``os.sched_getaffinity``;
on a shared machine other jobs take some of them).

Run:  python benchmarks/bench_simulate.py [--samples N] [--reference-samples N]
"""

from __future__ import annotations

import numpy as np
from _bench import available_cores, best_of, parser
from preisach import PreisachModel
from preisach.reference import RelayGrid
from preisach.surface import TABLE_3_1
from threadpoolctl import threadpool_limits


def random_walk(n: int, seed: int, step: float = 2.0, lo: float = -100.0, hi: float = 100.0):
    """Random walk with Gaussian steps (V), folded back into [lo, hi]."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0.0, step, n))
    span = hi - lo
    x = np.mod(x - lo, 2 * span)
    return lo + np.where(x > span, 2 * span - x, x)


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--samples", type=int, default=10_000_000)
    ap.add_argument("--reference-samples", type=int, default=5_000)
    ap.add_argument("--levels", type=int, default=41)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()

    model = PreisachModel.builtin("ss15-1hz", levels=args.levels)
    u = random_walk(args.samples, seed=1)
    s0 = model.negative_saturation()
    t_fast, _ = best_of(lambda: model.simulate(u, s0), args.repeats)
    fast = args.samples / t_fast
    cubic = model.with_interpolation("cubic")
    t_cubic, _ = best_of(lambda: cubic.simulate(u, s0), args.repeats)

    ref = RelayGrid.from_everett(TABLE_3_1[1].everett, -100.0, 100.0, 200, model.y_min)
    ur = u[: args.reference_samples]
    with threadpool_limits(limits=1, user_api="blas"):  # the reference on one core
        t_ref, _ = best_of(lambda: (ref.reset(), ref.run(ur)), 1)
    slow = ur.size / t_ref
    # Same input, same answers (up to the relay grid's discretisation).
    ref.reset()
    gap = np.abs(ref.run(ur) - model.simulate(ur, s0).output).max()

    cores = available_cores()
    runs = max(8, 2 * cores)
    per = max(args.samples // runs, 1)
    U = np.stack([random_walk(per, seed=10 + r) for r in range(runs)])
    t1, _ = best_of(lambda: model.simulate_batch(U, s0, threads=1), args.repeats)
    tn, _ = best_of(lambda: model.simulate_batch(U, s0, threads=0), args.repeats)

    print(f"model: {model}")
    print(
        f"simulate, {args.samples:.0e}-sample random walk, {args.levels} levels: "
        f"{fast / 1e6:8.1f} M samples/s"
    )
    print(
        f"NumPy relay grid 200x200 ({ref.weights.size} relays), {ur.size} samples:     "
        f"{slow / 1e6:8.4f} M samples/s   (max |difference| {gap * 1e3:.2f} mV)"
    )
    print(
        f"speed ratio simulate / relay grid: {fast / slow:,.0f}x "
        f"(both on 1 thread; {cores} cores obtained)"
    )
    print(
        f"cubic interpolation: {args.samples / t_cubic / 1e6:8.1f} M samples/s, "
        f"{t_cubic / t_fast:.2f}x the bilinear time (same table, same run)"
    )
    print(
        f"batch {runs} runs x {per} samples: 1 thread {runs * per / t1 / 1e6:.1f} M/s, "
        f"all threads {runs * per / tn / 1e6:.1f} M/s, speed-up {t1 / tn:.2f}x "
        f"on {cores} cores obtained"
    )


if __name__ == "__main__":
    main()
