"""Speed of diagnosis: six 10-20 s recordings at 1 kHz (the issue's target: under 60 s).

A concealed-delay case of the package's own generator with every experiment lasting at least
10 s (multi-sine, step-and-hold and noise 15 s), plus its 20 s FOD identification sweep;
timed with and without the identification data (which makes every candidate refit the
Preisach weights), on this machine, in one run.

    python benchmarks/bench_diagnose.py
"""

from __future__ import annotations

import os
import time

from preisach.diagnose import diagnose
from preisach.studies.diagnosis_cases import make_case


def main() -> None:
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # diagnose() pins BLAS to one thread too
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(
        f"cores obtained: {cores}; load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} "
        "(1 / 5 / 15 min; wall times stretch with the load, CPU times much less)"
    )
    t0 = time.perf_counter()
    case = make_case("delay", seed=5, scale=1.5, min_duration=10.0, effect_size=4.0)
    t_case = time.perf_counter() - t0
    n = [len(r.u) for r in case.recordings]
    print(
        f"recordings: {len(n)}, {', '.join(f'{k / 1000:.1f}' for k in n)} s at 1 kHz "
        f"({sum(n)} samples); identification sweep {len(case.identification.u) / 1000:.0f} s; "
        f"case generated in {t_case:.1f} s"
    )
    model = case.identify()
    for label, ident in (
        ("with the identification sweep (base refitted)", case.identification),
        ("without it (given model fixed)", None),
    ):
        t0, c0 = time.perf_counter(), time.process_time()
        rep = diagnose(model, case.recordings, identification=ident)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        now = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(
            f"diagnose {label}: {dt:.1f} s wall, {cpu:.1f} s CPU ({cpu / dt:.2f} cores busy on "
            f"average; load now {now:.1f}), "
            f"{sum(n) / dt / 1e3:.1f} k samples/s, "
            f"verdict {rep.verdict}, "
            f"held-out RMSE {1e3 * rep.rmse_before:.3g} -> {1e3 * rep.rmse_after:.3g} mV "
            f"({'under' if dt < 60 else 'OVER'} the 60 s target)"
        )


if __name__ == "__main__":
    main()
