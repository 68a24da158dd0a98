"""What a static output curve adds to the fine classical model, per blind case folder.

Usage: ``python scripts/congruency_study.py OUT MODELS CASE...``: ``MODELS/CASE/m.npz`` from
``preisach identify OUT/CASE/id.csv``, the experiments ``OUT/CASE/exp*.csv``.  Prints the
fine classical check's held-out ratio and the gain and p of
:func:`preisach.diagnose.congruency.output_curve_check` (the numbers quoted in its module
docstring and in docs/diagnosis.md).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from preisach import PreisachModel
from preisach.diagnose.congruency import output_curve_check
from preisach.diagnose.context import Context
from preisach.diagnose.core import _baseline, _load
from preisach.diagnose.data import prepare_recordings


def main() -> None:
    """Run the check on every case named on the command line."""
    out, models = Path(sys.argv[1]), Path(sys.argv[2])
    for case in sys.argv[3:]:
        t0 = time.perf_counter()
        model = PreisachModel.load(models / case / "m.npz")
        exps = [str(p) for p in sorted((out / case).glob("exp*.csv"))]
        recs = prepare_recordings(model, _load(exps), identification=list(model.identification))
        ctx = Context(model, recs, refit=True)
        sigma = _baseline(ctx, None).sigma
        c = output_curve_check(ctx, sigma)
        print(
            f"{case}: noise {1e3 * sigma:.3g} mV, fine classical {c.ratio_classical:.3f} x, "
            f"with the output curve {c.ratio_with:.3f} x, gain {c.gain:.3f} noise variances, "
            f"p {c.p:.2g} ({c.seconds:.1f} s check, {time.perf_counter() - t0:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
