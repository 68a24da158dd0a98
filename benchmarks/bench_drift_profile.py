"""Speed of the profiled fits with a drift: sparse regressors against C++ normal equations.

Once diagnosis keeps a sensor drift, every later candidate is fitted with each recording's
drift curve (a P-spline in time) profiled out jointly with the Preisach weights.  Those
weights were solved from sparse regressor matrices (``Context.solve_theta``: ``R^T R`` and
``R^T A`` by scipy.sparse, A the drift basis) at every evaluation; they now come from the C++
normal equations with the rows' cross products with the basis
(``preisach._core.normal_equations_basis``, :meth:`Problem.theta`), and the moving-model
candidate's start-value scan of 805 linear feedbacks runs in one C++ call with the drift
(:meth:`Problem.linear_feedback_scan`) instead of point by point.  On blind seed 47's case 013
(a 1/f drift, six 9-14 s recordings) one diagnosis took 420 s before, 278 s with the scan
alone moved to C++ and 184 s with both (separate runs on an idle machine, the same verdict).

Timed here in one run, on a drift case of the package's own generator (six recordings of at
least 10 s at 1 kHz), on the model's grid and on the 41-level grid diagnosis refits on:

* one evaluation of the profiled weights: the sparse path against :meth:`Problem.theta`;
* the scan: :meth:`Problem.sse_many` (point by point, each with the C++ weights) against one
  :meth:`Problem.linear_feedback_scan` call, with the largest relative difference.

    python benchmarks/bench_drift_profile.py
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from _bench import available_cores, best_of, parser
from preisach import PreisachModel
from preisach.diagnose.candidates import NonCongruenceCandidate
from preisach.diagnose.context import Chain, Context, FittedEffect
from preisach.diagnose.data import prepare_recordings
from preisach.diagnose.problem import Problem
from preisach.diagnose.scoring import make_folds
from preisach.studies.diagnosis_cases import make_case


def one_grid(model: PreisachModel, recs: list[Any], levels: np.ndarray | None) -> None:
    """Time the weights and the scan with a drift on one grid (``None``: the model's)."""
    ctx = Context(model, recs, refit=True, levels=levels)
    ctx.choose_drift_roughness()
    fold = make_folds(recs, "blocks")[0]
    cand = NonCongruenceCandidate()
    cand.prepare(ctx)
    base = ctx.refit_base([], ctx.given, fold.train, True)
    prob = Problem(ctx, cand, Chain(base), fold.train, True, profile=True)
    x = cand.linear(0.1 * cand.limit, 0.5 * (ctx.y_lo + ctx.y_hi))
    k = sum(ctx.drift_basis(i).shape[1] for i in range(len(recs)))

    def sparse() -> np.ndarray:
        eff = [FittedEffect(cand, x)]
        rs, targets, _ = ctx.linearised_targets(eff, base, fold.train, prob.feedback_from)
        return np.asarray(ctx.solve_theta(rs, targets, fold.train, True, False))

    t_old, th_old = best_of(sparse, 3)
    t_new, th_new = best_of(lambda: prob.theta(x), 3)
    diff = float(np.max(np.abs(th_new - th_old)) / np.max(np.abs(th_old)))
    print(
        f"{ctx.levels.size} levels ({ctx.n_theta} weights, {k} drift columns): weights with "
        f"the drift, sparse {1e3 * t_old:.0f} ms, C++ {1e3 * t_new:.0f} ms "
        f"({t_old / t_new:.1f} x faster; largest relative difference {diff:.1g})"
    )
    fine = np.linspace(-cand.limit, cand.limit, 161)
    zeros = [ctx.y_lo + f * (ctx.y_hi - ctx.y_lo) for f in (0.1, 0.3, 0.5, 0.7, 0.9)]
    gains = np.tile(fine, len(zeros))
    zs = np.repeat(zeros, fine.size)
    t0 = time.perf_counter()
    fast = prob.linear_feedback_scan(gains, zs)
    t_fast = time.perf_counter() - t0
    assert fast is not None
    t0 = time.perf_counter()
    slow = np.array(
        prob.sse_many([prob.clip(cand.linear(a, z)) for a, z in zip(gains, zs)], coarse=True)
    )
    t_slow = time.perf_counter() - t0
    same = all(
        int(np.argmin(fast[j : j + fine.size])) == int(np.argmin(slow[j : j + fine.size]))
        for j in range(0, gains.size, fine.size)
    )
    print(
        f"  scan of {gains.size} feedbacks with the drift: point by point {t_slow:.1f} s, "
        f"one C++ call {t_fast:.1f} s ({t_slow / t_fast:.1f} x faster); largest relative "
        f"difference {float(np.max(np.abs(fast - slow) / slow)):.1g}, best gain per zero "
        f"level {'the same' if same else 'DIFFERENT'}"
    )


def main() -> None:
    parser(__doc__).parse_args()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"cores obtained: {available_cores()}; load average {load[0]:.1f} / {load[1]:.1f}")
    case = make_case("sensor_drift", seed=3, scale=1.5, min_duration=10.0, effect_size=4.0)
    model = case.identify()
    recs = prepare_recordings(model, case.recordings, identification=[case.identification])
    n = sum(len(r.u) for r in case.recordings)
    print(f"recordings: {len(case.recordings)}, {n} samples at 1 kHz")
    for levels in (None, np.linspace(model.u_min, model.u_max, 41)):
        one_grid(model, recs, levels)


if __name__ == "__main__":
    main()
