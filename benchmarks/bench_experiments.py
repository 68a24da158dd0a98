"""Speed of the regulation experiments: the full closed-loop sweep of chapter 5.

Prints, from one run on this machine (shared: the ratios are what matter):
  * the wall time of the full closed-loop sweep - 3 frequencies x 3 initial states x 7 noise
    gains x 20 seeds = 1260 trials of 12 s at 1 kHz (the target is under 10 s), including
    building the models, reaching the initial states and generating the noise;
  * the same at the thesis's sample times (0.5 ms for the 4 Hz initialisation);
  * the loop throughput (samples/s) of the C++ PI loop on 1 thread and on all cores, and of
    the same loop written in Python with Simulator.step + PIController.update, and the ratios;
  * the wall time of the full open-loop drift sweep;
  * closed_loop_trials with BLAS as the process has it and held to one thread (interleaved):
    it calls no BLAS, so the ratio should be 1.

Run:  python benchmarks/bench_experiments.py [--repeats N] [--loop-only]
"""

from __future__ import annotations

import os

import numpy as np
from _bench import available_cores, best_of, parser
from preisach.experiments import (
    ClosedLoopProtocol,
    ModelPlant,
    closed_loop_trials,
    drive_to_state,
    regulation_sweep,
    ss15_plants,
)
from preisach.experiments.protocol import _cached_noise
from threadpoolctl import threadpool_info, threadpool_limits


def timed(fn, repeats: int):
    """Best wall time of `repeats` runs, each with a cold noise cache."""
    return best_of(fn, repeats, before=_cached_noise.cache_clear)


def blas_threads() -> int:
    """BLAS threads this process runs with (threadpoolctl; 0 when no BLAS was found)."""
    return max((p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"), default=0)


def blas_ab(fn, repeats: int) -> tuple[float, float]:
    """Best times of ``fn`` as the process runs it and with BLAS held to one thread.

    The two are interleaved, so a change of the machine's load hits both alike.
    """
    free, one = np.inf, np.inf
    for _ in range(repeats):
        free = min(free, timed(fn, 1)[0])
        with threadpool_limits(limits=1, user_api="blas"):
            one = min(one, timed(fn, 1)[0])
    return free, one


def python_loop(plant: ModelPlant, init, u_open: np.ndarray, cfg) -> None:
    sim = plant.model.simulator(init.state)
    pi = cfg.controller()
    c = 0.0
    for k, base in enumerate(u_open):
        y = sim.step(base + cfg.input_gain * c)
        c = pi.update(cfg.setpoint - y) if k >= cfg.enable_at else 0.0


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--repeats", type=int, default=3, help="best of N runs (default 3)")
    ap.add_argument(
        "--loop-only", action="store_true", help="only the loop throughput and the BLAS check"
    )
    args = ap.parse_args()
    cores = available_cores()
    print(
        f"cores obtained: {cores} (of {os.cpu_count()}); BLAS threads: {blas_threads()}; "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    if not args.loop_only:
        sweeps(args.repeats)
    loop(args.repeats, cores)


def sweeps(repeats: int) -> None:
    """The full closed-loop sweep at 1 kHz and at the thesis sample times; the drift sweep."""

    def full_sweep(sample_time):
        return regulation_sweep("closed-loop", ss15_plants(sample_time), seeds=range(20))

    t_1k, res = timed(lambda: full_sweep(1e-3), repeats)
    n_trials = len(res.rows)
    samples = n_trials * 12_000
    print(
        f"closed-loop sweep, 3 f x 3 states x 7 gains x 20 seeds = {n_trials} trials of 12 s "
        "at 1 kHz: "
        f"{t_1k:.2f} s wall ({samples / t_1k / 1e6:.1f} M loop samples/s overall; target < 10 s)"
    )
    t_th, _ = timed(lambda: full_sweep(None), repeats)
    print(f"same sweep at the thesis sample times (0.5 ms at 4 Hz): {t_th:.2f} s wall")
    t_d, _ = timed(lambda: regulation_sweep("drift", ss15_plants(1e-3), seeds=range(20)), repeats)
    print(f"open-loop drift sweep, 1260 trials of 10 s at 1 kHz: {t_d:.2f} s wall")


def loop(repeats: int, cores: int) -> None:
    """Loop throughput alone: 140 trials from one initial state (1 Hz, psi_a)."""
    plant1 = ModelPlant(ss15_plants(1e-3)[1.0].model, 1e-3, threads=1)
    plantn = ModelPlant(plant1.model, 1e-3, threads=0)
    init = drive_to_state(plant1, "a", 1.0, 1.0)
    gains = [0.8 * (i % 7 + 1) for i in range(140)]
    seeds = [i // 7 for i in range(140)]

    def trials(plant):
        return lambda: closed_loop_trials(plant, init, gains, seeds, keep_traces=False)

    t1, _ = timed(trials(plant1), repeats)
    tn, _ = timed(trials(plantn), repeats)
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
    # closed_loop_trials calls no BLAS (the Eq 5.3 effort norm is a pairwise sum): holding
    # BLAS to one thread around it must not matter, on a quiet or a loaded machine
    free, one = blas_ab(trials(plantn), repeats)
    print(
        f"closed_loop_trials, 140 trials: BLAS as the process has it ({blas_threads()} "
        f"threads) {free:.3f} s, held to 1 thread {one:.3f} s (ratio {free / one:.2f})"
    )


if __name__ == "__main__":
    main()
