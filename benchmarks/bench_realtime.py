"""Real-time pacing of the trial runner at 1 kHz on the virtual SS15 (not a test).

Runs a 60 s trial (60 000 samples) paced against absolute deadlines and reports, from the
recording's ``lateness`` column (actual start of each sample minus its deadline):
percentiles of the sample-time error, of the sample-to-sample interval error, and the missed
deadlines (a sample whose I/O ended after the next deadline).  The machine is shared, so
the figures move between runs.

    python benchmarks/bench_realtime.py [--seconds 60] [--rate 1000] [--priority 0]
"""

from __future__ import annotations

import argparse
import os
import tempfile

import numpy as np
from preisach import Recording, daq


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=1000.0, help="samples per second")
    ap.add_argument("--priority", type=int, default=0, help="SCHED_FIFO priority (0: normal)")
    ap.add_argument("--spin", type=float, default=2e-4, help="busy-wait before deadlines (s)")
    args = ap.parse_args()
    ts = 1.0 / args.rate
    n = int(round(args.seconds * args.rate))
    rig = daq.virtual_ss15("ss15-1hz", sample_time=ts, output_blocks=[{"kind": "structural_mode"}])
    u = 50 * np.sin(2 * np.pi * 1.0 * np.arange(n) * ts)
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "rt.csv")
        res = daq.run_trial(
            rig,
            u,
            path,
            sample_time=ts,
            realtime=True,
            priority=args.priority,
            spin=args.spin,
            safety=daq.SafetyLimits(max_consecutive_missed=-1),
        )
        rec = Recording.load(path)
    late = rec.columns["lateness"][: res.samples] * 1e6
    interval = np.diff(late)
    q = [50, 90, 99, 99.9, 100]
    print(
        f"real-time pacing: {res.samples} samples at {args.rate:g} Hz "
        f"({res.elapsed:.2f} s wall clock for {res.samples * ts:.2f} s planned), "
        f"spin {args.spin * 1e6:.0f} us, priority: {res.priority}; {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    print(
        "  sample-time error (start - deadline), us: "
        + ", ".join(f"p{p:g} {v:.1f}" for p, v in zip(q, np.percentile(late, q)))
    )
    print(
        "  interval error |dt - T|, us:             "
        + ", ".join(f"p{p:g} {v:.1f}" for p, v in zip(q, np.percentile(np.abs(interval), q)))
    )
    print(
        f"  samples later than 100 us: {np.count_nonzero(late > 100)}, later than 500 us: "
        f"{np.count_nonzero(late > 500)}"
    )
    print(
        f"  missed deadlines (I/O ended after the next deadline): {res.missed_deadlines} of "
        f"{res.samples} ({100 * res.missed_deadlines / max(res.samples, 1):.3f} %), "
        f"max lateness {res.max_lateness * 1e6:.0f} us"
    )
    idx = np.asarray(res.missed)  # the first 1024 missed samples
    runs = np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1) if idx.size else []
    longest = max((r.size for r in runs), default=0)
    print(
        f"  longest run of deadlines missed in a row: {longest} (default abort budget: "
        f"{daq.SafetyLimits().max_consecutive_missed})"
    )
    print(f"  recording: {len(rec)} rows, end_status {rec.metadata['end_status']!r}")


if __name__ == "__main__":
    main()
