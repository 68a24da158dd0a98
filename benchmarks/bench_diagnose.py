"""Speed of diagnosis: six 10-20 s recordings at 1 kHz (the issue's target: under 60 s).

A concealed-delay case of the package's own generator with every experiment lasting at least
10 s (multi-sine, step-and-hold and noise 15 s), plus its 20 s FOD identification sweep;
timed with and without the identification data (which makes every candidate refit the
Preisach weights), on this machine, in one run.

The non-congruence candidate's start-value scan (805 linear feedback gains and zeros, each a
profiled least-squares fit of the weights) runs in one C++ call
(:meth:`preisach.diagnose.problem.Problem.linear_feedback_scan`) where it applies; on the
first such scan of the run the same points are also evaluated the previous way (one Python
evaluation per point, :meth:`~preisach.diagnose.problem.Problem.sse_many`), timed and compared
(that extra evaluation is left out of the diagnosis times below).

    python benchmarks/bench_diagnose.py
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from preisach.diagnose import diagnose
from preisach.diagnose.problem import Problem
from preisach.studies.diagnosis_cases import make_case

_scan = Problem.linear_feedback_scan
_scans: dict[str, Any] = {"n": 0, "wall": 0.0, "cpu": 0.0, "extra": 0.0, "extra_cpu": 0.0}
_scans["compared"] = None


def _timed_scan(self: Problem, gains: np.ndarray, zeros: np.ndarray) -> np.ndarray | None:
    """:meth:`Problem.linear_feedback_scan`, timed; the first one compared with sse_many."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = _scan(self, gains, zeros)
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    if out is None:
        return out
    _scans["n"] += 1
    _scans["wall"] += dt
    _scans["cpu"] += cpu
    if _scans["compared"] is None:
        t1, c1 = time.perf_counter(), time.process_time()
        xs = [np.array([a, 0.0, 0.0, z]) for a, z in zip(gains, zeros)]
        old = np.array(self.sse_many(xs, coarse=True))
        dt_old, cpu_old = time.perf_counter() - t1, time.process_time() - c1
        _scans["extra"] += time.perf_counter() - t1
        _scans["extra_cpu"] += time.process_time() - c1
        m = 161
        same = all(
            int(np.argmin(old[k : k + m])) == int(np.argmin(out[k : k + m]))
            for k in range(0, old.size, m)
        )
        _scans["compared"] = (
            f"feedback gain scan, {gains.size} points: one C++ call {dt:.2f} s wall / "
            f"{cpu:.2f} s CPU, per-point Python evaluation {dt_old:.2f} s / {cpu_old:.2f} s CPU "
            f"({cpu_old / max(cpu, 1e-9):.1f} x the CPU, {dt_old / max(dt, 1e-9):.1f} x the wall "
            f"time); largest relative SSE difference {float(np.max(np.abs(old - out) / old)):.1g}, "
            f"best gain per zero level {'the same' if same else 'DIFFERENT'}"
        )
    return out


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
    Problem.linear_feedback_scan = _timed_scan  # type: ignore[method-assign]
    try:
        for label, ident in (
            ("with the identification sweep (base refitted)", case.identification),
            ("without it (given model fixed)", None),
        ):
            _scans.update(n=0, wall=0.0, cpu=0.0, extra=0.0, extra_cpu=0.0)
            t0, c0 = time.perf_counter(), time.process_time()
            rep = diagnose(model, case.recordings, identification=ident)
            dt = time.perf_counter() - t0 - _scans["extra"]
            cpu = time.process_time() - c0 - _scans["extra_cpu"]
            now = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
            print(
                f"diagnose {label}: {dt:.1f} s wall, {cpu:.1f} s CPU ({cpu / dt:.2f} cores busy "
                f"on average; load now {now:.1f}), "
                f"{sum(n) / dt / 1e3:.1f} k samples/s, "
                f"verdict {rep.verdict}, "
                f"held-out RMSE {1e3 * rep.rmse_before:.3g} -> {1e3 * rep.rmse_after:.3g} mV "
                f"({'under' if dt < 60 else 'OVER'} the 60 s target); "
                f"{_scans['n']} feedback gain scans in C++: {_scans['wall']:.1f} s wall"
            )
            if _scans["extra"]:
                print(f"  {_scans['compared']}")
    finally:
        Problem.linear_feedback_scan = _scan  # type: ignore[method-assign]


if __name__ == "__main__":
    main()
