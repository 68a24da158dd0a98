"""Identification speed (issue 3 targets), measured in one run on this machine.

Prints:
  * identification of a 21-level FOD sweep recording (Fig 3.17: 1 Hz, 1 kHz sampling, 20 001
    samples, 2 mV noise and 14-bit quantisation) by identify_fod - finding the FOD curves, the C++
    Mayergoyz table and the residuals on the recording - plus its parts, with and without the
    projection to mu >= 0, and identify_surface for comparison (target: under 1 s);
  * least squares (identify_lsq) on 1e5 samples of filtered noise with a 41-level table: total
    time with the default lambda search and 5-fold cross-validation, and its stages (target:
    under 10 s), and the rate of the C++ normal-equation accumulation against the simulator.
  * the scaling of least squares (issue 16): identify_lsq with the sparse solver (Everett nodes,
    conjugate gradients) on filtered noise over a grid of table sizes at fixed samples and of
    sample counts at fixed levels, the dense solver beside it where it fits, the exponents of
    time ~ cells^a and time ~ samples^b fitted in this run, and the issue's targets: 41 levels
    from 1e5 samples (< 1 s) and, with --big, 201 levels (20 100 parameters) from 1e6 samples
    (< 30 s, < 4 GB; peak resident memory of the process is printed).
BLAS is held to one thread (threadpoolctl) and the cores this process may use are printed.
The machine is shared with other jobs, so each figure is the best of --repeats runs, and the
load average is printed beside it.

Run:  python benchmarks/bench_identify.py [--repeats N] [--samples N] [--levels N] [--big]
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np
from _bench import available_cores, best_of, parser
from preisach import PreisachModel, Recording, _core
from preisach.identify import find_fod_curves, identify_fod, identify_lsq, identify_surface
from preisach.noise import uniform_filtered_noise
from preisach.waveforms import fod_sweep
from threadpoolctl import threadpool_limits

LSB = 10.0 / 2**14


def measured(model: PreisachModel, u: np.ndarray, seed: int, state=None) -> Recording:
    rng = np.random.default_rng(seed)
    y = model.simulate(u, model.negative_saturation() if state is None else state).output
    y = np.clip(np.round((y + rng.normal(0.0, 2e-3, y.size)) / LSB) * LSB, -5.0, 5.0 - LSB)
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3)


def cpu_of(fn) -> tuple[float, float, object]:
    """Wall and CPU seconds of one call (CPU: this process's work, whatever the load)."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--levels", type=int, default=41)
    ap.add_argument("--big", action="store_true", help="also 201 levels from 1e6 samples")
    ap.add_argument("--skip-fod", action="store_true", help="only the least-squares parts")
    args = ap.parse_args()
    cores = available_cores()
    print(f"cores available: {cores}; BLAS threads: 1; load average {os.getloadavg()[0]:.1f}")
    with threadpool_limits(limits=1, user_api="blas"):
        if not args.skip_fod:
            fod_and_dense(args)
        scaling(args)


def noise_recording(truth: PreisachModel, n: int) -> Recording:
    u = np.clip(
        1.3 * uniform_filtered_noise(n * 1e-3, 100.0, seed=5, cutoff=3.0, hold_time=0.1),
        -100.0,
        100.0,
    )
    return measured(truth, u, 2)


def scaling(args: argparse.Namespace) -> None:
    """Sparse least squares against table size and sample count; exponents; the targets."""
    truth = PreisachModel.builtin("ss15-1hz")
    print("\nleast-squares scaling (sparse solver, lambdas 'auto', 5 folds, filtered noise)")
    print("  (wall seconds, and CPU seconds of this process: the work, whatever the load)")
    print(
        f"  {'levels':>6} {'params':>7} {'samples':>8} {'sparse wall':>11} {'cpu':>6} "
        f"{'dense wall':>10} {'cpu':>6} {'CV rms mV':>9} {'CG it':>6}"
    )
    rows = []
    base = 100_000
    rec = noise_recording(truth, base)
    for lv in (21, 41, 81, 121):
        t_sp, c_sp, rep = cpu_of(lambda lv=lv: identify_lsq(rec, lv, solver="sparse"))
        t_de = c_de = float("nan")
        if lv <= 41:
            t_de, c_de, _ = cpu_of(lambda lv=lv: identify_lsq(rec, lv, solver="dense"))
        q = rep.lsq
        rows.append((lv, q.n_params, base, t_sp, c_sp))
        print(
            f"  {lv:>6} {q.n_params:>7} {base:>8} {t_sp:>11.2f} {c_sp:>6.2f} {t_de:>10.2f} "
            f"{c_de:>6.2f} {min(q.cv_rms) * 1e3:>9.4f} {q.solver_iterations:>6}"
        )
    for n in (25_000, 50_000, 200_000):
        r = noise_recording(truth, n)
        t_sp, c_sp, rep = cpu_of(lambda r=r: identify_lsq(r, 41, solver="sparse"))
        rows.append((41, rep.lsq.n_params, n, t_sp, c_sp))
        print(
            f"  {41:>6} {rep.lsq.n_params:>7} {n:>8} {t_sp:>11.2f} {c_sp:>6.2f} {'':>10} "
            f"{'':>6} {min(rep.lsq.cv_rms) * 1e3:>9.4f} {rep.lsq.solver_iterations:>6}"
        )
    for k, what in ((3, "wall"), (4, "CPU")):
        by_p = [(r[1], r[k]) for r in rows if r[2] == base]
        by_n = [(r[2], r[k]) for r in rows if r[0] == 41]
        a = np.polyfit(np.log([p for p, _ in by_p]), np.log([t for _, t in by_p]), 1)[0]
        b = np.polyfit(np.log([n for n, _ in by_n]), np.log([t for _, t in by_n]), 1)[0]
        print(
            f"  fitted scaling ({what} time): ~ parameters^{a:.2f} at 1e5 samples, "
            f"~ samples^{b:.2f} at 41 levels (dense solver: parameters^3, memory parameters^2)"
        )
    t41 = min(r[3] for r in rows if r[0] == 41 and r[2] == base)
    t41d, _ = best_of(lambda: identify_lsq(rec, 41), max(1, args.repeats - 1))
    print(
        f"  41 levels from 1e5 samples: default solver {t41d:.2f} s, sparse {t41:.2f} s   "
        f"target < 1 s: {'met' if t41d < 1.0 else 'MISSED'} (load "
        f"{os.getloadavg()[0]:.1f})"
    )
    c0 = time.process_time()
    identify_lsq(rec, 41)
    print(
        f"    (CPU time of that fit: {time.process_time() - c0:.2f} s: the work, whatever the load)"
    )
    if args.big:
        big = noise_recording(truth, 1_000_000)
        c0 = time.process_time()
        t_big, rep = best_of(lambda: identify_lsq(big, 201), 1)
        cpu_big = time.process_time() - c0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
        print(
            f"  201 levels ({rep.lsq.n_params} parameters) from 1e6 samples: {t_big:.1f} s "
            f"(stages {', '.join(f'{k} {v:.1f} s' for k, v in rep.lsq.timings.items())}), "
            f"peak resident memory {peak:.2f} GB   targets < 30 s: "
            f"{'met' if t_big < 30 else 'MISSED'}, < 4 GB: {'met' if peak < 4 else 'MISSED'} "
            f"(load {os.getloadavg()[0]:.1f}); CPU time {cpu_big:.1f} s"
        )
        print(
            f"  chosen lambda {rep.lsq.chosen_lambda:.3g}, CG iterations "
            f"{rep.lsq.solver_iterations}, projection to Mp moved "
            f"{100 * rep.projection.fraction_moved if rep.projection else 0.0:.2g} % of the mass"
        )


def fod_and_dense(args: argparse.Namespace) -> None:
    """The FOD timings and the dense least-squares stages (issue 3)."""
    truth = PreisachModel.builtin("ss15-1hz")
    sweep = measured(truth, fod_sweep().u, 1)
    print(f"FOD sweep recording: {len(sweep)} samples (21 levels, 1 Hz, 1 kHz)")
    t_find, fd = best_of(lambda: find_fod_curves(sweep), args.repeats)
    t_may, _ = best_of(lambda: _core.mayergoyz(fd.levels, fd.y_grid, "fill"), args.repeats)
    t_fod, _ = best_of(lambda: identify_fod(sweep), args.repeats)
    t_proj, _ = best_of(lambda: identify_fod(sweep, project=True), args.repeats)
    t_surf, _ = best_of(lambda: identify_surface(sweep), args.repeats)
    print(f"  find_fod_curves                 {t_find * 1e3:9.1f} ms")
    print(f"  C++ Mayergoyz (21 levels)       {t_may * 1e3:9.3f} ms")
    print(
        f"  identify_fod (all, residuals)   {t_fod * 1e3:9.1f} ms   target < 1000 ms: "
        f"{'met' if t_fod < 1.0 else 'MISSED'} ({t_fod / 1.0:.3f} of the budget)"
    )
    print(f"  identify_fod, project=True      {t_proj * 1e3:9.1f} ms")
    print(
        f"  identify_surface (201 levels)   {t_surf * 1e3:9.1f} ms   ({t_surf / t_fod:.1f} x fod)"
    )

    n = args.samples
    u = np.clip(
        1.3 * uniform_filtered_noise(n * 1e-3, 100.0, seed=5, cutoff=3.0, hold_time=0.1),
        -100.0,
        100.0,
    )
    noise = measured(truth, u, 2)
    print(
        f"\nleast squares: {n} samples of filtered noise, {args.levels}-level table "
        f"({args.levels * (args.levels - 1) // 2 + 1} parameters), lambdas 'auto', 5 folds"
    )
    t_lsq, (model, rep) = best_of(
        lambda: identify_lsq(noise, args.levels), max(1, args.repeats - 1)
    )
    q = rep.lsq
    print(
        f"  identify_lsq total              {t_lsq:9.2f} s    target < 10 s: "
        f"{'met' if t_lsq < 10.0 else 'MISSED'} ({t_lsq / 10.0:.2f} of the budget)"
    )
    for stage, sec in q.timings.items():
        print(f"    {stage:<29} {sec:9.3f} s")
    print(
        f"  lambdas tried {len(q.lambdas)}, chosen {q.chosen_lambda:.3g}, fit rms "
        f"{q.fit_rms * 1e3:.3f} mV, cells at 0: {q.n_zero}"
    )
    lv = model.levels
    fold = (np.arange(n) * 5 // n).astype(np.int32)
    t_ne, _ = best_of(
        lambda: _core.normal_equations(lv, noise.u, noise.y, model.negative_saturation(), fold, 5),
        args.repeats,
    )
    t_sim, _ = best_of(lambda: model.simulate(noise.u, model.negative_saturation()), args.repeats)
    print(
        f"  C++ normal equations            {n / t_ne / 1e6:9.2f} M samples/s "
        f"({t_ne / t_sim:.1f} x the time of simulating the same input)"
    )


if __name__ == "__main__":
    main()
