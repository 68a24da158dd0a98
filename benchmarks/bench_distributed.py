"""Studies on Dask: speed-up from 1 to N local workers and the overhead per task, in one run.

Prints, from one run on this machine (machines here are shared: the ratios matter):
  * the cores this process may use;
  * a regulation sweep (closed loop, the three SS15 models, psi_n/psi_a/psi_d, seven gains,
    ``--seeds`` seeds: 63 tasks) run serially, then on a Dask ``LocalCluster`` of 1, 2, ... N
    single-threaded workers (the cluster started beforehand, not timed), with the speed-up over
    one worker and a check that every run equals the serial one bit for bit;
  * the overhead per task: ``--tiny`` empty tasks on the N-worker cluster, wall time per task.

Run:  python benchmarks/bench_distributed.py [--workers N] [--seeds S] [--tiny K]
"""

from __future__ import annotations

import json
import os
import time

from _bench import parser

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS pinned: workers and reference alike
os.environ.setdefault("OMP_NUM_THREADS", "1")


def _empty(task: int) -> int:
    return task


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--workers", type=int, default=0, help="most workers (default: the cores)")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--tiny", type=int, default=400, help="empty tasks for the overhead")
    args = ap.parse_args()

    from distributed import Client, LocalCluster
    from preisach.execution import available_cores, run_tasks
    from preisach.experiments import regulation_sweep
    from preisach.experiments.plant import ss15_plants

    cores = available_cores()
    top = args.workers or cores
    print(f"cores obtained: {cores} (os.sched_getaffinity); workers up to {top}")
    # one C++ thread per plant: a worker is one core, so the serial run is one core too
    plants = {f: p for f, p in ss15_plants().items()}
    for p in plants.values():
        p.threads = 1
    kw = {"seeds": range(args.seeds)}

    def sweep(**extra: object) -> tuple[float, str]:
        t0 = time.perf_counter()
        res = regulation_sweep("closed-loop", plants, **kw, **extra)  # type: ignore[arg-type]
        return time.perf_counter() - t0, json.dumps(res.to_dict(), sort_keys=True)

    t_serial, ref = sweep()
    print(f"closed-loop sweep, 63 tasks x {args.seeds} seeds: serial {t_serial:7.2f} s")
    t_one = None
    for n in range(1, top + 1):
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
        try:
            sweep(client=client)  # warm-up: workers import preisach, plants scattered
            t, out = sweep(client=client)
            t_one = t if n == 1 else t_one
            same = "identical" if out == ref else "DIFFERENT"
            print(
                f"  Dask LocalCluster, {n} worker(s): {t:7.2f} s   speed-up over 1 worker "
                f"{(t_one or t) / t:5.2f}x   vs serial {t_serial / t:5.2f}x   result {same}"
            )
            if n == top:
                t0 = time.perf_counter()
                run_tasks(_empty, list(range(args.tiny)), client=client)
                dt = time.perf_counter() - t0
                print(
                    f"overhead per task ({args.tiny} empty tasks on {n} workers): "
                    f"{1e3 * dt / args.tiny:.2f} ms"
                )
        finally:
            client.close()
            cluster.close()


if __name__ == "__main__":
    main()
