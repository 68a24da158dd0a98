"""Identification study (issue 3): virtual SS15 round trips and the yan9a piezo data.

1. Round trip on the virtual SS15, for the built-in 1, 2 and 4 Hz models: record the FOD sweep of
   Fig 3.17 at that frequency (21 levels, 1 kHz) with 2 mV noise and 14-bit quantisation over
   +-5 V, identify by Mayergoyz (fod), Mayergoyz projected to mu >= 0, the square-root surface
   and least squares, and predict held-out experiments recorded the same way: the wiping-out test
   (Fig 3.6), the CML test (Fig 3.13) and filtered noise (from the anhysteretic state).
2. Least squares against FOD identification on held-out data, over several noise seeds, and least
   squares from a noise excitation instead of the FOD sweep.
3. Real data: yan9a-piezo (../shared/data), least squares on the first 60 %, verified on the last
   40 %, for several table sizes and output delays; the Preisach property tests on the data.

Run:  python scripts/identify_study.py [--seeds N] [--out DIR] [--scheduler S] [--store DIR]
(``--scheduler local:4`` or ``tcp://HOST:8786`` runs part 2's seeds on Dask workers).
With --out, the report figures (Figs 3.18-3.44 analogues) and verification plots are written there.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from preisach import PreisachModel, Recording
from preisach.execution import add_scheduler_argument, run_tasks
from preisach.identify import identify_fod, identify_lsq, identify_surface
from preisach.noise import uniform_filtered_noise
from preisach.verify import congruency_metric, verify, wiping_out_metric
from preisach.waveforms import cml_input, fod_sweep, wiping_out_input

LSB = 10.0 / 2**14
ROOT = Path(__file__).resolve().parents[1]
YAN9A = (
    Path(os.environ.get("PREISACH_DATA") or ROOT.parent / "shared" / "data")
    / "yan9a-piezo"
    / "Model_Vi_Do.dat"
)


def measured(
    model: PreisachModel, u: np.ndarray, name: str, rng: np.random.Generator, state=None
) -> Recording:
    y = model.simulate(u, model.negative_saturation() if state is None else state).output
    y = np.clip(np.round((y + rng.normal(0.0, 2e-3, y.size)) / LSB) * LSB, -5.0, 5.0 - LSB)
    return Recording.from_arrays(u=u, y=y, sample_time=1e-3, experiment=name)


def experiments(truth: PreisachModel, f: float, rng: np.random.Generator) -> list[Recording]:
    noise = np.clip(
        20.0
        + uniform_filtered_noise(
            15.0, 85.0, seed=int(rng.integers(1 << 30)), cutoff=5.0, hold_time=0.05
        ),
        -100.0,
        100.0,
    )
    return [
        measured(truth, wiping_out_input(f).u, "wiping-out", rng),
        measured(truth, cml_input(f).u, "cml", rng),
        measured(truth, noise, "noise", rng, truth.anhysteretic_state()),
    ]


def held_out(model: PreisachModel, tests: list[Recording]) -> list[tuple[float, float]]:
    rows = (
        verify(model, tests[:2], initial_state="negative").rows
        + verify(model, tests[2], initial_state="anhysteretic").rows
    )
    return [(r.max_pct, r.rms_pct) for r in rows]


def round_trips(out: Path | None) -> None:
    print("1. Round trip on the virtual SS15 (max / rms error in % of the output range)")
    print(
        f"{'model':<9} {'method':<12} {'time s':>7} {'neg':>4}   {'wiping-out':>15} {'cml':>15} "
        f"{'noise':>15}"
    )
    for name, f in (("ss15-1hz", 1.0), ("ss15-2hz", 2.0), ("ss15-4hz", 4.0)):
        truth = PreisachModel.builtin(name)
        rng = np.random.default_rng(int(f))
        sweep = measured(truth, fod_sweep(frequency=f).u, "fod sweep", rng)
        tests = experiments(truth, f, rng)
        runs = {
            "fod": (identify_fod, {}),
            "fod+project": (identify_fod, {"project": True}),
            "surface": (identify_surface, {"frequency": f}),
            "lsq": (identify_lsq, {}),
        }
        for method, (fn, kwargs) in runs.items():
            t0 = time.perf_counter()
            model, rep = fn(sweep, **kwargs)
            dt = time.perf_counter() - t0
            cells = " ".join(f"{a:6.3f} /{b:6.3f}" for a, b in held_out(model, tests))
            print(f"{name:<9} {method:<12} {dt:>7.3f} {rep.negative_cells:>4}   {cells}")
            if out is not None and f == 1.0:
                rep.plot().savefig(out / f"report_{name}_{method}.png", dpi=90)
            if method == "fod+project":
                p = rep.projection
                print(
                    f"{'':<9} {'':<12} projection: {p.n_negative} negative cells, moved "
                    f"{p.mass_moved * 1e3:.2f} mV = {100 * p.fraction_moved:.2f} % of the mass, "
                    f"max node change {p.max_node_change * 1e3:.2f} mV"
                )
            if method == "surface":
                s = rep.surface_fit.surface
                print(
                    f"{'':<9} {'':<12} surface: xbar4 {s.xbar4:.3g} xbar5 {s.xbar5:.3g} x7 "
                    f"{s.x7:.3g} x8 {s.x8:.3g} x9 {s.x9:.4g}"
                )


def _lsq_vs_fod_seed(seed: int, *, truth: PreisachModel) -> dict[str, list[tuple[float, float]]]:
    """One noise seed of part 2 (a task: the same numbers on any scheduler)."""
    rng = np.random.default_rng(100 + seed)
    sweep = measured(truth, fod_sweep().u, "fod sweep", rng)
    tests = experiments(truth, 1.0, rng)
    u = np.clip(
        1.3 * uniform_filtered_noise(30.0, 100.0, seed=200 + seed, cutoff=3.0, hold_time=0.1),
        -100.0,
        100.0,
    )
    excitation = measured(truth, u, "noise excitation", rng)
    fits = {
        "fod (21 levels)": identify_fod(sweep)[0],
        "surface": identify_surface(sweep)[0],
        "lsq, FOD sweep (41)": identify_lsq(sweep)[0],
        "lsq, FOD sweep (21)": identify_lsq(sweep, 21)[0],
        "lsq, 30 s noise (41)": identify_lsq(excitation)[0],
    }
    return {k: held_out(m, tests) for k, m in fits.items()}


def lsq_vs_fod(seeds: int, scheduler: str, store: str | None) -> None:
    print(
        f"\n2. Least squares vs FOD identification on held-out data ({seeds} noise seeds, "
        "ss15-1hz, 1 Hz): mean max % / mean rms % of the output range"
    )
    truth = PreisachModel.builtin("ss15-1hz")
    per_seed = run_tasks(
        _lsq_vs_fod_seed,
        list(range(seeds)),
        keys=[f"seed-{s}" for s in range(seeds)],
        scheduler=scheduler,
        shared={"truth": truth},
        store=store,
        store_tag="identify_study lsq_vs_fod",
        progress=True,
        desc="identification seeds",
    )
    acc: dict[str, list[list[tuple[float, float]]]] = {}
    for res in per_seed:
        for k, v in res.items():
            acc.setdefault(k, []).append(v)
    print(f"{'identification':<22} {'wiping-out':>15} {'cml':>15} {'noise':>15}")
    for k, runs in acc.items():
        a = np.asarray(runs)  # (seeds, experiments, 2)
        cells = " ".join(f"{a[:, e, 0].mean():6.3f} /{a[:, e, 1].mean():6.3f}" for e in range(3))
        print(f"{k:<22} {cells}")


def yan9a(out: Path | None) -> None:
    print("\n3. Real data: yan9a-piezo (least squares on the first 60 %, held-out last 40 %)")
    if not YAN9A.exists():
        print(f"   {YAN9A} not found: skipped")
        return
    d = np.loadtxt(YAN9A)
    u, y = d[:, 0], d[:, 4]
    t = np.arange(u.size) * 0.005
    cut = int(0.6 * u.size)
    whole = Recording.from_arrays(t=t, u=u, y=y, sample_time=0.005, experiment="yan9a")
    train = Recording.from_arrays(
        t=t[:cut], u=u[:cut], y=y[:cut], sample_time=0.005, experiment="identification (60 %)"
    )
    test = Recording.from_arrays(
        t=t[cut:], u=u[cut:], y=y[cut:], sample_time=0.005, experiment="held-out (40 %)"
    )
    print(
        f"   {u.size} samples, output range {np.ptp(y):.2f} (sensor units), "
        f"{cut} identify / {u.size - cut} held out"
    )
    print(
        f"   {'levels':>6} {'delay':>5} {'lambda':>8} {'fit rms':>8} {'held-out max':>13} "
        f"{'rms':>8} {'time s':>7}"
    )
    for levels in (11, 21, 41):
        for delay in (0, 1, 2):
            t0 = time.perf_counter()
            model, rep = identify_lsq(train, levels, delay=delay)
            dt = time.perf_counter() - t0
            r = verify(model, test, delay=delay).rows[0]
            print(
                f"   {levels:>6} {delay:>5} {rep.lsq.chosen_lambda:>8.2g} {rep.lsq.fit_rms:>8.4f} "
                f"{r.max_error:>7.3f} ={r.max_pct:>5.2f}% {r.rms_pct:>7.3f}% {dt:>7.2f}"
            )
            if out is not None and levels == 21 and delay == 1:
                rep.plot().savefig(out / "report_yan9a_lsq.png", dpi=90)
                verify(model, test, delay=1).plot().savefig(out / "verify_yan9a.png", dpi=90)
    wo, cml = wiping_out_metric(whole), congruency_metric(whole)
    print("   " + wo.table().splitlines()[0])
    print("   " + cml.table().splitlines()[0])


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", type=int, default=5, help="noise seeds of part 2 (default 5)")
    ap.add_argument("--out", type=Path, default=None, help="folder for figures")
    add_scheduler_argument(ap)
    args = ap.parse_args()
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    round_trips(args.out)
    lsq_vs_fod(args.seeds, args.scheduler, args.store)
    yan9a(args.out)


if __name__ == "__main__":
    main()
