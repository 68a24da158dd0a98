"""Open-loop drift sweep of thesis chapter 4 on the built-in SS15 models (Fig 4.12).

Run:  python examples/drift_sweep.py [SEEDS]

For each initialisation frequency (1, 2, 4 Hz, each with the SS15 model identified at that
frequency, Table 3.1), each initial state with output y_d = 1 V - the neutral state psi_n
(Eq 4.1-4.2), psi_a reached on an ascending branch (Eq 4.3), psi_d on a descending one (Eq 4.4) -
each noise gain K_n = 0.8 i (i = 1..7) and each seed: hold the offset 2 s, add 8 s of the
filtered uniform noise of section 4.1, and measure the differential drift ybar(8,10) - ybar(0,2).
Prints the table (mean +/- std over seeds), the slopes dy/du at each state (Appendix A) and
whether the thesis's findings hold; writes drift_sweep.png (Fig 4.12 style) and
drift_sweep.csv (one row per trial).  The thesis-scale study with 20 seeds and the closed loop
is ``python scripts/regulation_study.py`` (or ``preisach experiment drift --model ss15``).
"""

import sys

from preisach.experiments import THESIS_GAINS, regulation_sweep
from preisach.plotting import plot_drift_summary

seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
res = regulation_sweep("drift", gains=THESIS_GAINS, seeds=range(seeds), y_d=1.0)

print(f"differential drift (V), mean +/- std over {seeds} seeds:")
print(res.format_summary())
print("\nslopes at the initial states (Appendix A), V/V:")
for s in res.states:
    print(
        f"  f = {s['frequency']:g} Hz  psi_{s['state']}: offset {s['offset']:7.3f} V, "
        f"dy/du rising {s['dy_du_rising']:.4f}, falling {s['dy_du_falling']:.4f}"
    )
print("\nthesis findings (means over seeds, per frequency):")
for f in res.frequencies:
    rows = [c for c in res.comparisons() if c["frequency"] == f]
    print(
        f"  {f:g} Hz: |drift(psi_n)| smallest at {sum(c['n_smallest'] for c in rows)}/"
        f"{len(rows)} gains, psi_a up at {sum(c['a_up'] for c in rows)}, "
        f"psi_d down at {sum(c['d_down'] for c in rows)}"
    )

res.to_csv("drift_sweep.csv")
plot_drift_summary(res).savefig("drift_sweep.png", dpi=100)
print("wrote drift_sweep.csv and drift_sweep.png")
