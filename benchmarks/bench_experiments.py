"""Speed of the regulation experiments: the full closed-loop sweep of chapter 5.

Prints, from one run on this machine (shared: the ratios are what matter):
  * the wall time of the full closed-loop sweep - 3 frequencies x 3 initial states x 7 noise
    gains x 20 seeds = 1260 trials of 12 s at 1 kHz (the target is under 10 s), including
    building the models, reaching the initial states and generating the noise;
  * the same at the thesis's sample times (0.5 ms for the 4 Hz initialisation);
  * the loop throughput (samples/s) of the C++ PI loop on 1 thread and on all cores, and of
    the same loop written in Python with Simulator.step + PIController.update, and the ratios;
  * the wall time of the full open-loop drift sweep.

Run:  python benchmarks/bench_experiments.py [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from preisach.experiments import (
    ClosedLoopProtocol,
    ModelPlant,
    closed_loop_trials,
    drive_to_state,
    regulation_sweep,
    ss15_plants,
)
from preisach.experiments.protocol import _cached_noise


def timed(fn, repeats: int):
    """Best wall time of `repeats` runs, each with a cold noise cache."""
    best, out = np.inf, None
    for _ in range(repeats):
        _cached_noise.cache_clear()
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def python_loop(plant: ModelPlant, init, u_open: np.ndarray, cfg) -> None:
    sim = plant.model.simulator(init.state)
    pi = cfg.controller()
    c = 0.0
    for k, base in enumerate(u_open):
        y = sim.step(base + cfg.input_gain * c)
        c = pi.update(cfg.setpoint - y) if k >= cfg.enable_at else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="best of N runs (default 3)")
    args = ap.parse_args()
    cores = os.cpu_count()
    print(f"machine: {cores} cores")

    def full_sweep(sample_time):
        return regulation_sweep("closed-loop", ss15_plants(sample_time), seeds=range(20))

    t_1k, res = timed(lambda: full_sweep(1e-3), args.repeats)
    n_trials = len(res.rows)
    samples = n_trials * 12_000
    print(
        f"closed-loop sweep, 3 f x 3 states x 7 gains x 20 seeds = {n_trials} trials of 12 s "
        "at 1 kHz: "
        f"{t_1k:.2f} s wall ({samples / t_1k / 1e6:.1f} M loop samples/s overall; target < 10 s)"
    )
    t_th, _ = timed(lambda: full_sweep(None), args.repeats)
    print(f"same sweep at the thesis sample times (0.5 ms at 4 Hz): {t_th:.2f} s wall")

    # Loop throughput alone: 140 trials from one initial state (1 Hz, psi_a).
    plant1 = ModelPlant(ss15_plants(1e-3)[1.0].model, 1e-3, threads=1)
    plantn = ModelPlant(plant1.model, 1e-3, threads=0)
    init = drive_to_state(plant1, "a", 1.0, 1.0)
    gains = [0.8 * (i % 7 + 1) for i in range(140)]
    seeds = [i // 7 for i in range(140)]
    t1, _ = timed(
        lambda: closed_loop_trials(plant1, init, gains, seeds, keep_traces=False), args.repeats
    )
    tn, _ = timed(
        lambda: closed_loop_trials(plantn, init, gains, seeds, keep_traces=False), args.repeats
    )
    rate1, raten = 140 * 12_000 / t1, 140 * 12_000 / tn
    proto = ClosedLoopProtocol()
    cfg = proto.pi_config(1.0, 1e-3)
    u_open = proto.open_inputs(init.offset, [1.6], [0], 1e-3)[0]
    tp, _ = timed(lambda: python_loop(plant1, init, u_open, cfg), 1)
    ratep = 12_000 / tp
    print(
        "C++ PI loop, 140 trials x 12000 samples incl. noise and metrics: "
        f"1 thread {rate1 / 1e6:.1f} M samples/s, "
        f"{cores} threads {raten / 1e6:.1f} M samples/s (speed-up {raten / rate1:.2f}x)"
    )
    print(
        "same loop in Python (Simulator.step + PIController.update per sample): "
        f"{ratep / 1e6:.3f} M samples/s; "
        f"C++ batch is {raten / ratep:.0f}x faster"
    )
    t_d, _ = timed(
        lambda: regulation_sweep("drift", ss15_plants(1e-3), seeds=range(20)), args.repeats
    )
    print(f"open-loop drift sweep, 1260 trials of 10 s at 1 kHz: {t_d:.2f} s wall")


if __name__ == "__main__":
    main()
