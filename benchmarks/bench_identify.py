"""Identification speed (issue 3 targets), measured in one run on this machine.

Prints:
  * identification of a 21-level FOD sweep recording (Fig 3.17: 1 Hz, 1 kHz sampling, 20 001
    samples, 2 mV noise and 14-bit quantisation) by identify_fod - finding the FOD curves, the C++
    Mayergoyz table and the residuals on the recording - plus its parts, with and without the
    projection to mu >= 0, and identify_surface for comparison (target: under 1 s);
  * least squares (identify_lsq) on 1e5 samples of filtered noise with a 41-level table: total
    time with the default lambda search and 5-fold cross-validation, and its stages (target:
    under 10 s), and the rate of the C++ normal-equation accumulation against the simulator.
The machine is shared with other jobs, so each figure is the best of --repeats runs.

Run:  python benchmarks/bench_identify.py [--repeats N] [--samples N] [--levels N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from preisach import PreisachModel, Recording, _core
from preisach.identify import find_fod_curves, identify_fod, identify_lsq, identify_surface
from preisach.noise import uniform_filtered_noise
from preisach.waveforms import fod_sweep

LSB = 10.0 / 2**14


def measured(model: PreisachModel, u: np.ndarray, seed: int, state=None) -> Recording:
    rng = np.random.default_rng(seed)
    y = model.simulate(u, model.negative_saturation() if state is None else state).output
    y = np.clip(np.round((y + rng.normal(0.0, 2e-3, y.size)) / LSB) * LSB, -5.0, 5.0 - LSB)
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3)


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--levels", type=int, default=41)
    args = ap.parse_args()

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
