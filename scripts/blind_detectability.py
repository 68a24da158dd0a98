#!/usr/bin/env python3
"""How much of each blind case's effect no classical Preisach model can reproduce (an oracle).

A blind case's effect size (the generator's ``ratio_experiments``: RMS of the effect over the
noise) counts all of it, but diagnosis can only see what no classical model explains: the
identification is refitted on data that carry the effect, and a re-identified classical
Preisach model absorbs whatever part of the effect is itself rate-independent and congruent
(a moving model with a small feedback is close to a classical model with another density; a
sensor offset that changes between recordings is close to what an unknown initial state
leaves).  This script measures that part with the truth, not the diagnosis:

* the generator's noiseless outputs (``generator.py --clean``: ``truth/case_NNN_clean.npz``)
  with and without the effects, for every file;
* the diagnosis's own fine classical check (:func:`preisach.diagnose.scoring.classical_check`:
  61 levels, smooth density, free unknown initial states, interleaved 10 ms stretches held
  out) fitted to the noiseless output with the effects (``ratio``) and without
  (``floor``: the grid's own error on this device), both over the case's noise level;
* ``excess = sqrt(max(ratio^2 - floor^2, 0))``: the effect's part, in noise RMS, that the best
  fine classical model cannot reproduce even without noise.  A diagnosis can name an effect
  from the classical check only when this is well above the noise; below about 1 the data do
  not show an effect that a classical model cannot explain, and ``none`` is an honest verdict.

The model file of each case (the eval's ``work/case_NNN/m.npz``) only sets the input range and
the prior of the fine grid.  Usage (with the package installed, or ``PYTHONPATH=python``)::

    python scripts/blind2/generator.py OUT --cases-per-kind 3 --seed S --cml --clean
    python scripts/blind_detectability.py OUT EVAL_DIR [--kinds non_congruence,sensor_drift]

``EVAL_DIR`` is a ``scripts/blind_study.py`` run (``results.json`` and ``work/``).  Printed:
one line per case (truth kinds and forms, effect size, floor, ratio, excess, verdict) and,
per first kind, the verdicts split at an excess of 1 noise RMS.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

if __name__ == "__main__":  # one BLAS thread, set before numpy loads (not when imported)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from preisach.diagnose.augmented import load_model  # noqa: E402
from preisach.diagnose.context import Context  # noqa: E402
from preisach.diagnose.data import prepare_recordings  # noqa: E402
from preisach.diagnose.scoring import classical_check  # noqa: E402
from preisach.recording import Recording  # noqa: E402

DT = 1e-3  # the generator's sampling interval (s)
Array = np.ndarray
#: Excess (noise RMS) from which the fine classical model's misfit shows the effect.
EXCESS_VISIBLE = 1.0
#: Loop-shape z from which a test at p < 0.001 on the CML loops can see the effect.
LOOPS_VISIBLE = 3.1


def _recordings(clean: Any, key: str) -> tuple[list[Recording], list[Recording]]:
    """The experiments and the identification sweep, with output ``FILE:{key}``."""
    names = sorted({k.split(":")[0] for k in clean.files})
    recs = {
        n: Recording(
            np.arange(clean[f"{n}:u"].size) * DT,
            clean[f"{n}:u"],
            clean[f"{n}:{key}"],
            metadata={"name": n.removesuffix(".csv"), "sample_time": DT},
        )
        for n in names
    }
    ident = [recs.pop("id.csv")]
    return [recs[n] for n in sorted(recs)], ident


def oracle(model_path: Path, clean_path: Path, sigma: float) -> dict[str, float]:
    """Fine classical ratios of the noiseless outputs with (``ratio``) and without (``floor``)."""
    model = load_model(str(model_path))
    out: dict[str, float] = {}
    with np.load(clean_path) as clean:
        for key, label in (("y", "ratio"), ("y0", "floor")):
            exps, ident = _recordings(clean, key)
            recs = prepare_recordings(model, exps, identification=ident)
            ctx = Context(model, recs, refit=True)
            out[label] = classical_check(ctx, sigma).ratio
    out["excess"] = math.sqrt(max(out["ratio"] ** 2 - out["floor"] ** 2, 0.0))
    return out


def cml_shape(clean: Any, truth: dict[str, Any], sigma: float, key: str) -> float:
    """The congruent-minor-loop file's loop-shape difference, as a z score of the noise.

    The CML file runs the same minor loop three times at different output levels (loops A,
    B and C, ``truth["design"]["cml"]["loops_s"]``).  A classical Preisach model makes them
    congruent: equal up to a constant shift.  Returned: ``sqrt(sum over the pairs of the
    squared shift-removed difference) / (sigma sqrt 2)`` of the noiseless output ``key``,
    the size, in noise standard deviations, of what a test on the loops could see (0 for a
    congruent output).
    """
    cml = truth.get("design", {}).get("cml")
    names = [n.split(":")[0] for n in clean.files if n.endswith("_cml.csv:y")]
    if not cml or not names:
        return float("nan")
    u, y = clean[f"{names[0]}:u"], clean[f"{names[0]}:{key}"]
    branches: dict[str, dict[int, tuple[Array, Array]]] = {}
    for name, (t0, t1) in cml["loops_s"].items():
        sl = slice(int(round(t0 / DT)), int(round(t1 / DT)))
        us, ys = u[sl], y[sl]
        du = np.diff(us)
        branches[name] = {}
        for sign in (1, -1):  # rising and falling branch, each as a function of the input
            m = sign * du > 0
            order = np.argsort(us[1:][m])
            branches[name][sign] = (us[1:][m][order], ys[1:][m][order])
    ss = 0.0
    for a, b in (("A", "B"), ("A", "C"), ("C", "B")):
        diffs = []
        for sign in (1, -1):
            ua, ya = branches[a][sign]
            ub, yb = branches[b][sign]
            grid = np.linspace(max(ua[0], ub[0]), min(ua[-1], ub[-1]), min(ua.size, ub.size))
            diffs.append(np.interp(grid, ub, yb) - np.interp(grid, ua, ya))
        d = np.concatenate(diffs)
        d = d - d.mean()
        ss += float(d @ d)
    return math.sqrt(ss) / (sigma * math.sqrt(2.0))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", type=Path, help="generator output (with --clean)")
    ap.add_argument("evaluation", type=Path, help="blind_study.py run: results.json, work/")
    ap.add_argument("--kinds", default="", help="comma-separated first kinds (default: all)")
    ap.add_argument("--pass", dest="pass_", default="default", help="study pass to compare")
    a = ap.parse_args()
    kinds = {k for k in a.kinds.split(",") if k}
    results = json.loads((a.evaluation / "results.json").read_text())
    rows = []
    for r in results:
        if kinds and r["kinds"][0] not in kinds:
            continue
        case = r["case"]
        truth = json.loads((a.cases / "truth" / f"{case}.json").read_text())
        clean = a.cases / "truth" / f"{case}_clean.npz"
        model = a.evaluation / "work" / case / "m.npz"
        if not clean.exists() or not model.exists():
            print(f"{case}: no clean outputs or model file; skipped", flush=True)
            continue
        sigma = float(truth["noise_rms"])
        o = oracle(model, clean, sigma)
        with np.load(clean) as cl:
            z, z0 = cml_shape(cl, truth, sigma, "y"), cml_shape(cl, truth, sigma, "y0")
        verdict = r["passes"][a.pass_]["verdict"]
        right = verdict in r["kinds"]
        # a drift or creep distorts the loops in time too; only a non-congruence is seen by them
        loops = "non_congruence" in r["kinds"] and z >= LOOPS_VISIBLE
        visible = o["excess"] >= EXCESS_VISIBLE or loops
        rows.append((r["kinds"][0], visible, right))
        print(
            f"{case} {'+'.join(r['kinds']):34s} "
            f"{','.join(f['form'] for f in truth['forms']) or '-':50s} "
            f"size {truth['ratio_experiments']:6.2f}  floor {o['floor']:5.2f}  "
            f"ratio {o['ratio']:6.2f}  excess {o['excess']:6.2f}  loops z {z:6.1f} ({z0:.1f})  "
            f"{verdict} ({'right' if right else 'wrong'})",
            flush=True,
        )
    print(
        f"\nper first kind: right / cases, split by whether the effect is visible (excess >= "
        f"{EXCESS_VISIBLE:g}, or loops z >= {LOOPS_VISIBLE:g} for a non-congruence)"
    )
    for k in sorted({k for k, _, _ in rows}):
        vis = [ok for kk, v, ok in rows if kk == k and v]
        hid = [ok for kk, v, ok in rows if kk == k and not v]
        print(f"  {k:24s} visible: {sum(vis)}/{len(vis)}   not visible: {sum(hid)}/{len(hid)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
