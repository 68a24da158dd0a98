"""Randomised proof of diagnosis on concealed effects: confusion matrix and false-alarm rate.

Every case is a virtual device (the SS15 1 Hz model) with ONE small effect - or none - measured
with white noise and 14-bit quantisation (see :mod:`preisach.diagnose.cases` for the
generators and why their functional forms differ from the candidates'): an FOD
identification sweep plus wiping-out, CML, multi-frequency sine, step-and-hold and filtered
noise experiments.  A model is identified from the sweep (Mayergoyz, FOD grid), the other
experiments are diagnosed with the sweep given as identification data, and the verdict, the
held-out improvement and the fitted parameters are compared with the truth.

Randomised per case: the effect's parameters (inside the generator), its size (the RMS of the
part no classical model can absorb, ``--size-min``..``--size-max`` times the noise), the noise
level (0.7-1.5 mV), the experiments' frequencies and phases, and the noise realisation.

    python scripts/diagnosis_study.py --per-kind 10 --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any


def run_case(job: dict[str, Any]) -> dict[str, Any]:
    """One randomised case: effect size and noise level drawn from the case's seed."""
    import numpy as np
    from preisach.diagnose.cases import run_case as run

    rng = np.random.default_rng(job["seed"] + 100_003)
    size = float(rng.uniform(job["size_min"], job["size_max"]))
    sigma = float(rng.uniform(0.7e-3, 1.5e-3))
    return run(
        job["kind"],
        generator=job["generator"],
        seed=job["seed"],
        effect_size=size,
        sigma=sigma,
        scale=job["scale"],
        cv=job["cv"],
    )


def _rig_check(k: str, p: dict[str, float], t: dict[str, Any]) -> str:
    """Fitted vs true parameters for a case of the virtual rig's blocks."""
    tp = t["params"]
    blocks = {b["kind"]: b for b in tp.get("input_blocks", []) + tp.get("output_blocks", [])}
    if k == "rate_dependence":
        true = f"rig input lag {1e3 * blocks['input_lag']['time_constant']:.3f} ms"
        if "tau" in p:
            return f"input lag {1e3 * p['tau']:.3f} ms ({true})"
        return ", ".join(f"{n} {v:.3g}" for n, v in p.items()) + f" ({true})"
    if k == "structural_resonance":
        m = blocks["structural_mode"]
        return (
            f"f_n {p['f_n']:.1f} Hz (truth {m['frequency']:.1f}), zeta {p['zeta']:.3f} "
            f"(truth {m['damping']:.3f}), participation {p['participation']:.2f} (truth 1)"
        )
    if k == "creep":
        cs = [v for n, v in p.items() if n.startswith("c_")]
        c = blocks["creep"]
        return (
            f"creep {100 * sum(cs) / max(len(cs), 1):.2f} %/decade (truth {100 * c['rate']:.2f} "
            f"%/decade, {c['tau_min']:.2g}-{c['tau_max']:.2g} s)"
        )
    if k == "delay":
        form = "+".join(f"{b['kind']} {b.get('samples', b.get('length'))}" for b in blocks.values())
        return (
            f"tau {1e3 * p['tau']:.3f} ms (truth lag {1e3 * tp['lag']:.3f} ms: {form} "
            f"at {1e6 * tp['block_sample_time']:.0f} us)"
        )
    if k == "sensor_drift":
        d = blocks["offset_drift"]
        return (
            f"rate {1e3 * p['rate']:+.2f} mV/s (truth {1e3 * d['rate']:+.2f} mV/s "
            f"+ random walk {1e3 * d['sigma']:.2f} mV/sqrt(s))"
        )
    if k == "non_congruence":
        return (
            f"feedback a {p['a']:+.2f} V/V, c {p['c']:+.2f} V/V "
            f"(truth moving gain {tp['moving_gain']:+.2f} V/V)"
        )
    return ""


def _param_check(r: dict[str, Any]) -> str:
    """Fitted vs true parameter, in words, for a correct verdict."""
    t, p = r["truth"], r.get("params", {})
    k = r["kind"]
    if t.get("generator") == "rig":
        return _rig_check(k, p, t)
    if k == "delay":
        return f"tau {1e3 * p['tau']:.3f} ms (truth lag {1e3 * t['strength']:.3f} ms)"
    if k == "structural_resonance":
        return (
            f"f_n {p['f_n']:.2f} Hz (truth {t['params']['f_n']:.2f}), zeta {p['zeta']:.3f} "
            f"(truth {t['params']['zeta']:.3f}), m {p['participation']:.3f} "
            f"(truth {t['strength']:.3f})"
        )
    if k == "creep":
        cs = [v for n, v in p.items() if n.startswith("c_")]
        return (
            f"creep {100 * sum(cs) / max(len(cs), 1):.2f} %/decade (truth log law "
            f"{100 * t['strength']:.2f} %/decade)"
        )
    if k == "non_congruence":
        return (
            f"feedback a {p['a']:+.2f} V/V, c {p['c']:+.2f} V/V (truth tanh gain "
            f"{t['strength']:+.2f} V/V: linear {t['strength']:+.2f}, cubic "
            f"{-4 * t['strength'] / 3:+.2f} V/V)"
        )
    if k == "sensor_drift":
        return (
            f"p-p {1e3 * p['peak_to_peak']:.2f} mV (truth amplitude {1e3 * t['strength']:.2f} mV)"
        )
    if k == "rate_dependence":
        return ", ".join(f"{n} {v:.3g}" for n, v in p.items())
    return ""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--per-kind", type=int, default=10, help="cases per kind (default 10)")
    from preisach.diagnose.cases import EFFECT_KINDS

    ap.add_argument("--kinds", default=",".join(("none", *EFFECT_KINDS)))
    ap.add_argument(
        "--scale", type=float, default=0.5, help="duration scale of the experiments (1: 20 s sweep)"
    )
    ap.add_argument("--size-min", type=float, default=2.0, help="smallest effect size (x noise)")
    ap.add_argument("--size-max", type=float, default=5.0, help="largest effect size (x noise)")
    ap.add_argument("--cv", default="auto")
    ap.add_argument(
        "--generator",
        default="own",
        choices=("own", "rig"),
        help="truth: this package's own generators (forms unlike the candidates) "
        "or the virtual rig's blocks",
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed0", type=int, default=1000)
    ap.add_argument("--json", default="", help="write every case's result here")
    a = ap.parse_args(argv)
    kinds = a.kinds.split(",")
    jobs = [
        {
            "kind": k,
            "seed": a.seed0 + 17 * i + 1000 * j,
            "scale": a.scale,
            "cv": a.cv,
            "generator": a.generator,
            "size_min": a.size_min,
            "size_max": a.size_max,
        }
        for j, k in enumerate(kinds)
        for i in range(a.per_kind)
    ]
    t0 = time.perf_counter()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    results: list[dict[str, Any]] = [{} for _ in jobs]

    def done(i: int, r: dict[str, Any]) -> None:
        results[i] = r
        n = sum(bool(x) for x in results)
        print(
            f"[{n}/{len(jobs)} {time.perf_counter() - t0:5.0f} s] {r['kind']} seed {r['seed']} "
            f"-> {r['verdict']}",
            file=sys.stderr,
            flush=True,
        )

    if a.workers > 1:
        with ProcessPoolExecutor(a.workers) as ex:
            futures = {ex.submit(run_case, j): i for i, j in enumerate(jobs)}
            for f in as_completed(futures):
                done(futures[f], f.result())
    else:
        for i, j in enumerate(jobs):
            done(i, run_case(j))
    wall = time.perf_counter() - t0
    labels = list(dict.fromkeys(["none", *kinds, *[r["verdict"] for r in results]]))
    print(
        f"diagnosis study ({a.generator} generator): {len(results)} cases, scale {a.scale}, "
        "effect size "
        f"{a.size_min}-{a.size_max} x noise, cv={a.cv}, {wall:.0f} s wall "
        f"({sum(r['seconds'] for r in results) / len(results):.1f} s per case)"
    )
    print("\nconfusion matrix (rows: truth, columns: verdict)")
    w = max(len(x) for x in labels) + 1
    print(" " * w + "".join(f"{x[:10]:>11}" for x in labels) + "   correct")
    for k in kinds:
        row = [r for r in results if r["kind"] == k]
        cnt = [sum(r["verdict"] == v for r in row) for v in labels]
        ok = sum(r["verdict"] == k for r in row)
        print(f"{k:<{w}}" + "".join(f"{c:>11}" for c in cnt) + f"   {ok}/{len(row)}")
    nulls = [r for r in results if r["kind"] == "none"]
    if nulls:
        fa = sum(r["verdict"] != "none" for r in nulls)
        print(
            "\nfalse-alarm rate (null cases with an effect reported): "
            f"{fa}/{len(nulls)} = {fa / len(nulls):.0%}"
        )
    found = [r for r in results if r["kind"] != "none" and r["verdict"] == r["kind"]]
    if found:
        g = [r["gain"] for r in found]
        print(
            "held-out RMSE reduction when the right effect is found: "
            f"median {100 * sorted(g)[len(g) // 2]:.0f} %, "
            f"min {100 * min(g):.0f} %, >= 30 % in {sum(x >= 0.3 for x in g)}/{len(g)}"
        )
    print("\nper case (truth, size, verdict, held-out gain, fitted vs true parameters):")
    for r in results:
        gain = f"{100 * r['gain']:5.0f} %" if r["effects"] else "      "
        extra = _param_check(r) if r["verdict"] == r["kind"] and r["kind"] != "none" else ""
        more = f" (+{','.join(r['effects'][1:])})" if len(r["effects"]) > 1 else ""
        print(
            f"  {r['kind']:<21} seed {r['seed']:>5} size {r['size']:4.1f} -> "
            f"{r['verdict']:<21}{more:<14} {gain}  {extra}"
        )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
