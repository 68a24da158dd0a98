"""Blind proof of diagnosis: concealed-effect cases written by someone who never saw its code.

The cases come from ``scripts/blind/blind_generator.py`` (written from physical descriptions of
each effect only, apart from the candidates' code): every case folder holds an identification
sweep ``id.csv`` and experiment CSVs, and the truth sits in ``OUTDIR/truth/<case>.json``
(``kinds``: one effect, two mixed, or ``["none"]``).  This script runs the command line exactly
as a user would, per case:

    preisach identify id.csv -o m.npz
    preisach diagnose m.npz EXPERIMENTS... --json r.json                    (pass "default")
    preisach diagnose m.npz EXPERIMENTS... --json r.json --identification id.csv   ("sweep")
    preisach diagnose m.npz EXPERIMENTS... --json r.json --no-stored-identification ("bare")

``default`` uses the identification recordings the model file carries (``preisach identify``
stores them), so it refits the weights with every candidate; ``sweep`` gives the same sweep
explicitly (it should agree with ``default``); ``bare`` is a model from elsewhere, without its
identification data.  A verdict is right when it names one of the case's kinds (``none`` for a
null case); for mixtures the second kind found is counted too.  ``unexplained`` is counted
apart: not right, but not a wrong name either.  Printed: the confusion matrix per pass, right
per kind, false alarms on nulls, the held-out gain when right.

    python scripts/blind/blind_generator.py OUTDIR ...     (see scripts/blind/README.md)
    python scripts/blind2/generator.py OUTDIR ...          (a second one: scripts/blind2/README.md)
    python scripts/blind_study.py OUTDIR [--passes default,bare] [--workers 2] [--work DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

KINDS = (
    "none",
    "rate_dependence",
    "structural_resonance",
    "creep",
    "delay",
    "sensor_drift",
    "non_congruence",
)
VERDICTS = (*KINDS, "gain_offset", "sensor_nonlinearity", "unexplained")
# Other generators' words for the same kinds (scripts/blind2 was written apart, in its own words).
KIND_ALIASES = {
    "rate": "rate_dependence",
    "resonance": "structural_resonance",
    "drift": "sensor_drift",
    "noncongruence": "non_congruence",
}


def truth_kinds(path: Path) -> list[str]:
    """The kinds a truth file names, in diagnosis's vocabulary."""
    kinds = json.loads(path.read_text())["kinds"]
    return [KIND_ALIASES.get(k, k) for k in kinds]


PASS_ARGS = {
    "default": [],
    "sweep": ["--identification", "{id}"],
    "bare": ["--no-stored-identification"],
}


CLI: list[str] = [sys.executable, "-m", "preisach.cli"]


def _cli(*args: str) -> list[str]:
    return [*CLI, *args]


def run_case(case: Path, truth: dict[str, Any], work: Path, passes: list[str]) -> dict[str, Any]:
    """Identify and diagnose one case through the CLI; the verdicts and gains per pass."""
    work.mkdir(parents=True, exist_ok=True)
    ident = case / "id.csv"
    exps = sorted(str(p) for p in case.glob("*.csv") if p.name != "id.csv")
    model = work / "m.npz"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    out: dict[str, Any] = {"case": case.name, "kinds": truth["kinds"], "passes": {}}
    t0 = time.perf_counter()
    r = subprocess.run(
        _cli("identify", str(ident), "-o", str(model)), capture_output=True, text=True, env=env
    )
    if r.returncode != 0:
        out["error"] = f"identify failed: {r.stderr.strip()[-300:]}"
        return out
    for name in passes:
        rj = work / f"r_{name}.json"
        extra = [a.format(id=str(ident)) for a in PASS_ARGS[name]]
        t1 = time.perf_counter()
        r = subprocess.run(
            _cli("diagnose", str(model), *exps, "--json", str(rj), "-q", *extra),
            capture_output=True,
            text=True,
            env=env,
        )
        if r.returncode != 0:
            out["passes"][name] = {"error": r.stderr.strip()[-300:]}
            continue
        rep = json.loads(rj.read_text())
        out["passes"][name] = _outcome(rep)
        out["passes"][name]["seconds"] = time.perf_counter() - t1
    out["seconds"] = time.perf_counter() - t0
    return out


def _outcome(rep: dict[str, Any]) -> dict[str, Any]:
    """Verdict, kept effects, gains and the noise ratio of one diagnosis report (JSON)."""
    effs = rep["effects"]
    first = effs[0] if effs else None
    return {
        "verdict": rep["verdict"],
        "effects": [e["name"] for e in effs],
        "gain": (1 - first["heldout_rmse_after"] / first["heldout_rmse_before"] if first else 0.0),
        "total_gain": 1 - rep["rmse_after"] / rep["rmse_before"] if effs else 0.0,
        "hold_gain": ((first.get("holds") or {}).get("gain") if first else None),
        "ratio": rep.get("noise_test", {}).get("ratio"),
        "unexplained": (rep.get("unexplained") or {}).get("statement"),
        "step1": _step1_best(rep.get("candidates") or []),
    }


def _step1_best(rows: list[dict[str, Any]]) -> dict[str, list[Any]]:
    """Per effect name, its best form at selection step 1: ``[form, gain, p-value]``."""
    best: dict[str, list[Any]] = {}
    for c in rows:
        name = c["name"].split("/")[0]
        if c["step"] == 1 and (name not in best or c["gain"] > best[name][1]):
            best[name] = [c["name"], c["gain"], c["p_value"]]
    return best


def collect(outdir: Path, work: Path, passes: list[str]) -> list[dict[str, Any]]:
    """Results of the cases already run into ``work`` (``r_<pass>.json`` per case folder)."""
    results = []
    for d in sorted(p for p in work.iterdir() if p.is_dir()):
        truth = outdir / "truth" / f"{d.name}.json"
        if not truth.exists():
            continue
        r: dict[str, Any] = {
            "case": d.name,
            "kinds": truth_kinds(truth),
            "passes": {},
        }
        for name in passes:
            f = d / f"r_{name}.json"
            if f.exists():
                r["passes"][name] = _outcome(json.loads(f.read_text()))
        results.append(r)
    return results


def right(kinds: list[str], verdict: str) -> bool:
    """Whether the verdict names one of the case's kinds (``none`` on a null)."""
    return verdict in kinds


def summarise(results: list[dict[str, Any]], name: str) -> list[str]:
    """Confusion matrix and rates of one pass, as lines."""
    rows = [r for r in results if name in r.get("passes", {}) and "verdict" in r["passes"][name]]
    lines = [f"pass {name!r}: {len(rows)} cases"]
    short = {v: v[:10] for v in VERDICTS}
    cols = [v for v in VERDICTS if any(r["passes"][name]["verdict"] == v for r in rows)]
    cols = sorted(set(cols) | set(KINDS), key=VERDICTS.index)
    lines.append(
        "truth (first kind) ".ljust(26) + " ".join(f"{short[c]:>10}" for c in cols) + "   right"
    )
    for k in KINDS:
        sub = [r for r in rows if r["kinds"][0] == k]
        if not sub:
            continue
        counts = [sum(r["passes"][name]["verdict"] == c for r in sub) for c in cols]
        ok = sum(right(r["kinds"], r["passes"][name]["verdict"]) for r in sub)
        lines.append(f"{k:<26}" + " ".join(f"{n:>10}" for n in counts) + f"   {ok}/{len(sub)}")
    per_kind: dict[str, list[bool]] = {}
    for r in rows:
        for k in r["kinds"]:
            per_kind.setdefault(k, []).append(
                k in ([r["passes"][name]["verdict"]] + r["passes"][name]["effects"])
            )
    lines.append(
        "found per kind (verdict or a kept effect; mixtures count for both kinds): "
        + ", ".join(f"{k} {sum(v)}/{len(v)}" for k, v in per_kind.items())
    )
    nulls = [r for r in rows if r["kinds"] == ["none"]]
    fa = sum(r["passes"][name]["verdict"] != "none" for r in nulls)
    lines.append(f"false alarms on nulls: {fa}/{len(nulls)}")
    eff = [r for r in rows if r["kinds"] != ["none"]]
    ok = [r for r in eff if right(r["kinds"], r["passes"][name]["verdict"])]
    wrong = [
        r
        for r in eff
        if not right(r["kinds"], r["passes"][name]["verdict"])
        and r["passes"][name]["verdict"] not in ("unexplained",)
    ]
    unexp = [r for r in eff if r["passes"][name]["verdict"] == "unexplained"]
    lines.append(
        f"effect cases: right {len(ok)}/{len(eff)}, unexplained {len(unexp)}, "
        f"wrong name or none {len(wrong)}"
    )
    if ok:
        g = sorted(r["passes"][name]["gain"] for r in ok)
        lines.append(
            f"held-out gain when right: median {100 * g[len(g) // 2]:.0f} %, min {100 * g[0]:.0f} %"
            f", >= 30 % in {sum(x >= 0.3 for x in g)}/{len(g)}"
        )
    lines.append("per case (truth, verdict, kept effects, first gain, held-out RMSE / noise):")
    for r in rows:
        p = r["passes"][name]
        hit = right(r["kinds"], p["verdict"])
        mark = "ok " if hit else "-- "
        ratio = "-" if p["ratio"] is None else f"{p['ratio']:.2f}"
        hg = p.get("hold_gain")
        held = "" if hg is None else f" (within the holds {100 * hg:.0f} %)"
        lines.append(
            f"  {mark}{r['case']}: {'+'.join(r['kinds']):<32} -> {p['verdict']:<21} "
            f"[{', '.join(p['effects'])}] gain {100 * p['gain']:.0f} %{held}, ratio {ratio}"
        )
        near = [p.get("step1", {}).get(k) for k in r["kinds"]]
        if not hit and any(near):  # how near the truth's own fits came at step 1
            lines.append(
                "       step 1, the truth's best fit: "
                + "; ".join(f"{f} {100 * g:.1f} % (p {pv:.2g})" for f, g, pv in filter(None, near))
            )
    return lines


def main() -> int:
    """Run every case of OUTDIR through the CLI and print the summary per pass."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir", type=Path, help="the blind generator's output folder")
    ap.add_argument("--passes", default="default,bare", help="comma-separated passes")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--work", type=Path, default=Path("blind_work"))
    ap.add_argument("--cases", help="comma-separated case names (default: all)")
    ap.add_argument("--json", type=Path, help="write all results here")
    ap.add_argument(
        "--cli",
        help="command that runs the preisach command line (default: python -m preisach.cli), "
        "e.g. a frozen copy of the package while the working tree changes",
    )
    ap.add_argument(
        "--summarise",
        action="store_true",
        help="run nothing: summarise the reports already in --work",
    )
    args = ap.parse_args()
    if args.cli:
        CLI[:] = args.cli.split()
    passes = [p for p in args.passes.split(",") if p]
    for p in passes:
        if p not in PASS_ARGS:
            ap.error(f"--passes: unknown pass {p!r}; choose from {sorted(PASS_ARGS)}")
    truth_dir = args.outdir / "truth"
    cases = sorted(p for p in args.outdir.iterdir() if p.is_dir() and p.name != "truth")
    if args.cases:
        want = set(args.cases.split(","))
        cases = [c for c in cases if c.name in want]
    if args.summarise:
        results = collect(args.outdir, args.work, passes)
        print(f"blind study (summary of {args.work}): {len(results)} cases, passes {passes}")
        for p in passes:
            print()
            print("\n".join(summarise(results, p)))
        return 0
    t0 = time.perf_counter()

    def one(case: Path) -> dict[str, Any]:
        kinds = truth_kinds(truth_dir / f"{case.name}.json")
        r = run_case(case, {"kinds": kinds}, args.work / case.name, passes)
        summary = {n: p.get("verdict", p.get("error")) for n, p in r["passes"].items()}
        print(f"{case.name} {kinds}: {summary} ({r.get('seconds', 0):.0f} s)", flush=True)
        return r

    with ThreadPoolExecutor(max(1, args.workers)) as ex:
        results = list(ex.map(one, cases))
    wall = time.perf_counter() - t0
    print(f"\nblind study: {len(results)} cases, passes {passes}, {wall:.0f} s wall")
    for p in passes:
        print()
        print("\n".join(summarise(results, p)))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
