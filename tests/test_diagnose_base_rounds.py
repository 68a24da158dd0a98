"""The refitted base a candidate must beat has converged in its unknown initial states.

Blind seed 42's case 011 (a thermal warm-up over the session, written by the independent
generator in ``scripts/blind2``) has recordings whose best initial state is the one the
previous recording left: a chain of choices that changes again after each solve of the
weights.  With one re-choice of the states the refitted base had a held-out RMSE of 7.0 mV,
each candidate's own fit (two alternations of weights and states) 5.8 mV, and so every
candidate - a 1-parameter delay that fitted no delay among them - gained 16-19 % at step 1
and the first name was wrong (``rate_dependence``).
"""

from __future__ import annotations

import pytest
from _paths import blind_case
from preisach.recording import Recording


@pytest.mark.slow
def test_the_refitted_base_is_a_fixed_point_of_its_initial_states(tmp_path):
    from preisach.diagnose.context import Chain, Context
    from preisach.diagnose.data import prepare_recordings
    from preisach.diagnose.scoring import make_folds
    from preisach.identify import identify

    case, forms = blind_case(tmp_path, 42, 11)
    assert forms == ["thermal_warmup"]
    ident = Recording.load(case / "id.csv")
    recordings = [Recording.load(p) for p in sorted(case.glob("exp*.csv"))]
    model = identify([ident], progress=False).model
    recs = prepare_recordings(model, recordings, identification=[ident])
    ctx = Context(model, recs, refit=True)
    for fold in make_folds(recs, "blocks"):
        chain = Chain(ctx.refit_base([], ctx.given, fold.train, False))
        # no recording's initial state would change for the weights the base ends with
        assert ctx.choose_states(chain) is chain
