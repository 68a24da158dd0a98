"""The regulation study of chapters 4-5 on the built-in SS15 models, with statistics over seeds.

Runs, at the thesis's settings (y_d = 1 V, K_n = 0.8 i for i = 1..7, 1/2/4 Hz initialisation
with the model identified at that frequency, 1 ms sampling and 0.5 ms at 4 Hz, K_p = 1.5,
K_i = 30, noise peak 0.5 V at the DAQ connector = 7.06 V of amplifier input):

  1. the neutral locus of each model, its inverse at y_d and the Mp check;
  2. the initial states psi_n, psi_a, psi_d: offset, output at t_1 and the slopes of Appendix A
     (one-sided dy/du, secants over the noise peak at K_n = 1.6, and the output left behind by
     one excursion up-and-back / down-and-back);
  3. the open-loop drift sweep (Fig 4.12): mean +/- std over seeds, and the thesis's claims;
  4. the closed-loop sweep (Figs 5.5-5.7): n_c mean +/- std, claims, and Table 5.1's percentages;
  5. sensitivity of the verdicts to choices the thesis leaves open (units of the noise and
     gains, error averaging, landing tolerance, cycles of the psi_n sinusoid).

Every claim is checked on the means over seeds and, paired by seed (same noise), as the fraction
of seeds on which it holds.  Nothing is tuned: a claim that fails is printed as failing.

Run:  python scripts/regulation_study.py [--seeds 20] [--out DIR]
With --out, the figures (Figs 4.6-4.8, 4.9-4.11, 4.12, 5.2-5.4, 5.5-5.7, paired differences) and
the tidy tables (CSV, JSON) are written to DIR.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from preisach.experiments import (
    SS15_INPUT_GAIN,
    ClosedLoopProtocol,
    DriftProtocol,
    SweepResult,
    regulation_sweep,
    ss15_plants,
)
from preisach.neutral import check_mp, neutral_locus


def claims(res: SweepResult) -> list[str]:
    """One line per thesis claim, with the per-gain evidence."""
    comp = res.comparisons()
    lines = []
    for f in res.frequencies:
        rows = [c for c in comp if c["frequency"] == f]
        n_ok = sum(c["n_smallest"] for c in rows)
        fa = min(c["frac_n_below_a"] for c in rows)
        fd = min(c["frac_n_below_d"] for c in rows)
        what = "|drift(psi_n)| smallest" if res.experiment == "drift" else "n_c(psi_n) smallest"
        line = (
            f"  f = {f:g} Hz: {what} at {n_ok}/{len(rows)} gains (means over seeds); "
            f"paired by seed, psi_n below psi_a on >= {fa:.0%} and below psi_d on >= {fd:.0%} "
            "of seeds at every gain"
        )
        if res.experiment == "drift":
            up = sum(c["a_up"] for c in rows)
            down = sum(c["d_down"] for c in rows)
            line += f"; psi_a drifts up at {up}/{len(rows)}, psi_d down at {down}/{len(rows)} gains"
        lines.append(line)
    return lines


def verdict(res: SweepResult, freqs: list[float]) -> bool:
    comp = [c for c in res.comparisons() if c["frequency"] in freqs]
    ok = all(c["n_smallest"] for c in comp)
    if res.experiment == "drift":
        ok = ok and all(c["a_up"] and c["d_down"] for c in comp)
    return ok


def print_states(res: SweepResult) -> None:
    print(
        f"{'f':>3} {'state':>6} {'offset V':>9} {'y(t1) V':>8} {'dy/du+':>8} {'dy/du-':>8} "
        f"{'sec+':>7} {'sec-':>7} {'res_up mV':>9} {'res_dn mV':>9}"
    )
    for s in res.states:
        print(
            f"{s['frequency']:>3g} {'psi_' + s['state']:>6} {s['offset']:>9.4f} {s['y_end']:>8.4f} "
            f"{s['dy_du_rising']:>8.5f} {s['dy_du_falling']:>8.5f} {s['secant_rising']:>7.4f} "
            f"{s['secant_falling']:>7.4f} {1e3 * s['residual_up']:>9.2f} "
            f"{1e3 * s['residual_down']:>9.2f}"
        )
        if "exact_dy_du_rising" in s:
            print(
                f"{'':>3} {'(exact psi_n^l)':>24} {'':>8} {s['exact_dy_du_rising']:>8.5f} "
                f"{s['exact_dy_du_falling']:>8.5f}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="noise seeds per cell (default 20)")
    ap.add_argument("--out", type=Path, help="write figures and tables to this folder")
    args = ap.parse_args()
    seeds = range(args.seeds)
    t0 = time.perf_counter()

    print("== 1. Neutral locus N(l) (Eq 2.18) and Mp ==")
    plants = ss15_plants()
    for p in plants.values():
        m = p.model
        loc = neutral_locus(m)
        l_inv = loc.inverse(1.0)
        print(
            f"{m.name}: N {'monotone' if loc.monotone else 'NOT monotone'} "
            f"on {loc.l.size} offsets, "
            f"N_inv(1 V) = {l_inv:.4f} V; {check_mp(m)}; with tolerance 1e-5 V: "
            f"{'in Mp' if check_mp(m, 1e-5).in_mp else 'not in Mp'}"
        )

    print("\n== 2./3. Open-loop drift (thesis §4.2, Fig 4.12): ybar(8,10) - ybar(0,2) in V ==")
    drift = regulation_sweep("drift", plants, seeds=seeds)
    print(
        "Initial states (Appendix A: one-sided slopes dy/du in V/V at t_1; secants and "
        "one-excursion "
        f"residuals over the noise peak at K_n = 1.6, {drift.config['slope_amplitude']:.2f} V):"
    )
    print_states(drift)
    print(f"\nDrift, mean +/- std over {args.seeds} seeds:")
    print(drift.format_summary())
    print("Claims (thesis: |drift(psi_n)| < |drift(psi_a)|, |drift(psi_d)|; psi_a up, psi_d down):")
    print("\n".join(claims(drift)))

    print("Secondary observations of §4.3:")
    for k in ("a", "d"):
        grow = all(
            np.all(np.diff([abs(drift.values(f, k, g).mean()) for g in drift.gains]) > 0)
            for f in drift.frequencies
        )
        by_f = [abs(drift.values(f, k, max(drift.gains)).mean()) for f in drift.frequencies]
        print(
            f"  |drift(psi_{k})| grows with K_n at every frequency: {'yes' if grow else 'NO'}; "
            "at K_n = "
            f"{max(drift.gains):g} it is "
            + ", ".join(f"{v:.4f} V ({f:g} Hz)" for v, f in zip(by_f, drift.frequencies))
            + (
                " - larger at higher frequency"
                if np.all(np.diff(by_f) > 0)
                else " - NOT ordered by frequency"
            )
        )

    print(
        "\n== 4. Closed-loop PI (thesis §5.1, Figs 5.5-5.7): n_c = ||u_cn - ubar_c||_2 in DAQ V =="
    )
    closed = regulation_sweep("closed-loop", plants, seeds=seeds)
    print(
        f"n_c, mean +/- std over {args.seeds} seeds (sample-vector 2-norm; 4 Hz runs at 0.5 ms "
        "so its "
        "n_c carries a factor ~sqrt(2) against 1 and 2 Hz):"
    )
    print(closed.format_summary())
    print(
        "Claims (thesis: n_c(psi_n) below n_c(psi_a), n_c(psi_d) at 1 and 2 Hz; at 4 Hz the "
        "advantage "
        "disappears above K_n = 4.0):"
    )
    print("\n".join(claims(closed)))
    print(
        "\nTable 5.1 layout: 100 (n_c(psi_x) - n_c(psi_n)) / n_c(psi_n), from the means over seeds "
        "(thesis Table 5.1 is experimental, 0-18 %):"
    )
    print(closed.format_percentage_table())
    gap = {
        f: [
            100
            * (closed.values(f, "a", g).mean() - closed.values(f, "d", g).mean())
            / closed.values(f, "d", g).mean()
            for g in closed.gains
        ]
        for f in closed.frequencies
    }
    print(
        "n_c(psi_a) relative to n_c(psi_d) (thesis: about equal at 1 Hz, apart at 2 Hz): "
        + "; ".join(f"{f:g} Hz {min(v):+.1f} .. {max(v):+.1f} %" for f, v in gap.items())
    )
    err = [r["error_final"] for r in closed.rows]
    print(
        "Output error over the last second (after the noise): "
        f"max |y_d - y| = {np.max(np.abs(err)):.2e} V"
    )

    print("\n== 5. Sensitivity of the verdicts to choices the thesis leaves open ==")
    variants = [
        # A 14x weaker loop is still removing the landing error (up to 0.03 V) during the
        # noise, which swamps n_c; land within 0.001 V so that n_c measures the noise again.
        (
            "noise and PI gains in model-input volts (input_gain = 1; landing tolerance 0.001 V)",
            DriftProtocol(input_gain=1.0),
            ClosedLoopProtocol(input_gain=1.0),
            {"tolerance": 0.001},
        ),
        (
            "error averaged over 25 ms (the thesis's experiments)",
            None,
            ClosedLoopProtocol(average_window=0.025),
            {},
        ),
        (
            "landing tolerance 0.001 V instead of 0.03 V",
            DriftProtocol(),
            ClosedLoopProtocol(),
            {"tolerance": 0.001},
        ),
        (
            "psi_n reached with 4 instead of 10 cycles",
            DriftProtocol(),
            ClosedLoopProtocol(),
            {"cycles": 4},
        ),
        ("1 ms sampling at 4 Hz as well", DriftProtocol(), ClosedLoopProtocol(), {"_ts": 1e-3}),
    ]
    for name, dp, cp, opts in variants:
        ts = opts.pop("_ts", None)
        pl = ss15_plants(ts) if ts else plants
        parts = []
        if dp is not None:
            d = regulation_sweep(
                "drift", pl, seeds=seeds, protocol=dp, init_options=opts, trace=None
            )
            parts.append(
                f"drift claims hold at {'all' if verdict(d, [1.0, 2.0, 4.0]) else 'NOT all'} "
                "gains and frequencies"
            )
        c = regulation_sweep(
            "closed-loop", pl, seeds=seeds, protocol=cp, init_options=opts, trace=None
        )
        c4 = [x for x in c.comparisons() if x["frequency"] == 4.0]
        parts.append(
            f"n_c(psi_n) smallest at 1 and 2 Hz: {'yes' if verdict(c, [1.0, 2.0]) else 'NO'}, "
            f"at 4 Hz on {sum(x['n_smallest'] for x in c4)}/{len(c4)} gains"
        )
        pct = c.percentage_table()
        lo = min(min(r[k] for k in r if k[0] in "ad" and "_" in k) for r in pct)
        hi = max(max(r[k] for k in r if k[0] in "ad" and "_" in k) for r in pct)
        parts.append(f"Table 5.1 percentages {lo:.1f} .. {hi:.1f} %")
        print(f"- {name}: " + "; ".join(parts))

    print(
        f"\n(input_gain {SS15_INPUT_GAIN:g} V/V, {args.seeds} seeds, "
        f"total {time.perf_counter() - t0:.1f} s)"
    )

    if args.out:
        out = args.out
        out.mkdir(parents=True, exist_ok=True)
        figs = {
            "fig4_6-8_initial_states.png": drift.plot_initial_states(),
            "fig4_9-11_drift_traces.png": drift.plot_traces(),
            "fig4_12_drift.png": drift.plot(),
            "drift_paired_differences.png": drift.plot_differences(),
            "fig5_2-4_closed_loop_traces.png": closed.plot_traces(),
            "fig5_5-7_control_effort.png": closed.plot(),
            "fig5_10-12_effort_differences.png": closed.plot_differences(),
        }
        for name, fig in figs.items():
            fig.savefig(out / name, dpi=120)
        drift.to_csv(str(out / "drift.csv"))
        closed.to_csv(str(out / "closed_loop.csv"))
        (out / "drift.json").write_text(json.dumps(drift.to_dict(), indent=1))
        (out / "closed_loop.json").write_text(json.dumps(closed.to_dict(), indent=1))
        print(f"wrote {len(figs)} figures and the tables to {out}")


if __name__ == "__main__":
    main()
