"""Rate dependence as an Everett family in diagnosis (issue 13 item 3, issue 15).

The truth is the built-in rate-dependent SS15 model (the three Table 3.1 surfaces blended by the
filtered input rate); the model diagnosed is the classical 1 Hz surface.  The family must be
named, lower the held-out error by at least 30 % and measure the loop widening the truth has;
and a creeping device (a logarithmic creep law, not the candidates' Prony form) must stay creep.
"""

from __future__ import annotations

import numpy as np
import pytest
from _inputs import session
from preisach import PreisachModel, Recording
from preisach.diagnose import AugmentedModel, diagnose, load_model
from preisach.diagnose.rate_family import (
    RateEverettBlock,
    RateFamilyCandidate,
    hold_motion_of,
)
from preisach.rate_model import RateDependentPreisachModel

DT = 1e-3
NOISE = 0.01  # V (the SS15 outputs span about 7 V)
CANDIDATES = ["rate_dependence/everett_family", "creep"]


def _triangle(f: float, seconds: float, amp: float = 100.0) -> np.ndarray:
    t = np.arange(int(seconds / DT)) * DT
    return amp * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * f * t))


def _inputs(hold: float) -> tuple[np.ndarray, list[tuple[str, np.ndarray]]]:
    t = np.arange(int(6 / DT)) * DT
    env = 100 * np.clip(1 - t / 6, 0.1, 1)  # a 1 Hz FOD-like sweep
    ident = np.concatenate(
        [np.linspace(0, -100, 200), env * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t))]
    )
    exps = [(f"triangle {f:g} Hz", _triangle(f, T)) for f, T in ((0.5, 4), (2, 4), (3, 3), (4, 4))]
    n = int(hold / DT)
    exps.append(("steps", np.concatenate([np.full(n, v) for v in (0, 50, -30, 80, -80, 20)])))
    return ident, exps


def _recordings(simulate, hold: float, seed: int) -> tuple[Recording, list[Recording]]:
    ident, exps = _inputs(hold)
    recs = session([("sweep", ident), *exps], simulate, NOISE, seed, DT)
    return recs[0], recs[1:]


def _log_creep(p: np.ndarray, gamma: float, t0: float = 0.05) -> np.ndarray:
    """``p`` plus logarithmic creep: ``gamma`` of every move per decade of time after it."""
    h = gamma * np.log10(1 + np.arange(p.size) * DT / t0)
    return p + np.convolve(np.diff(p, prepend=p[0]), h)[: p.size]


def _mean_width(model: PreisachModel) -> float:
    up = np.linspace(model.u_min, model.u_max, 201)
    y = model.simulate(np.concatenate([up, up[::-1][1:]]), model.negative_saturation()).output
    return float(np.mean(y[200:][::-1] - y[:201]))


@pytest.fixture(scope="module")
def rate_report():
    truth = RateDependentPreisachModel.builtin("ss15-rate", levels=41)
    ident, exps = _recordings(lambda u: truth.simulate(u, sample_time=DT).output, 1.3, 1)
    model = PreisachModel.builtin("ss15-1hz", 41)
    rep = diagnose(model, exps, identification=[ident], candidates=CANDIDATES, progress=False)
    return truth, rep, exps


def test_rate_family_names_rate_dependence_of_the_ss15_rate_model(rate_report):
    truth, rep, _ = rate_report
    assert rep.verdict == "rate_dependence"
    eff = rep.effects[0]
    gain = 1 - eff.heldout_rmse_after / eff.heldout_rmse_before
    assert gain >= 0.30, eff.evidence
    assert "everett family" in eff.evidence
    # what it found, in words and numbers: the widening of the major loop between the rates
    # the data cover, against the truth's over the same rates
    p = eff.parameters
    knots = [p[k]["value"] for k in sorted(p) if k.startswith("knot_")]
    found = p[f"width_change_{len(knots) - 1}"]["value"]
    true = _mean_width(truth.at_rate(knots[-1])) - _mean_width(truth.at_rate(knots[0]))
    assert true > 0.1  # the 4 Hz surface's loop is wider than the 1 Hz one
    assert abs(found - true) < 0.3 * true, (found, true)
    assert "the major loop widens by" in eff.statement and "per V/s of input rate" in eff.statement
    assert 0 < p["tau"]["value"] <= RateFamilyCandidate.TAU_MAX


def test_rate_family_augmented_model_simulates_and_round_trips(rate_report, tmp_path):
    _, rep, exps = rate_report
    aug = rep.model
    assert any(isinstance(b, RateEverettBlock) for b in aug.blocks)
    r = exps[1]  # 2 Hz triangle: the augmented model is closer to it than its base alone
    s0 = aug.negative_saturation()
    y_aug = aug.simulate(r.u, s0, sample_time=DT).output
    y_base = aug.base.simulate(r.u, s0, sample_time=DT).output
    late = slice(r.u.size // 2, None)  # after the start from saturation is wiped out
    assert np.sqrt(np.mean((r.y - y_aug)[late] ** 2)) < np.sqrt(np.mean((r.y - y_base)[late] ** 2))
    aug.save(tmp_path / "aug.npz")
    back = load_model(tmp_path / "aug.npz")
    assert isinstance(back, AugmentedModel) and back == aug
    np.testing.assert_array_equal(back.simulate(r.u, s0, sample_time=DT).output, y_aug)


def test_creep_stays_creep_next_to_the_rate_family():
    base = PreisachModel.builtin("ss15-1hz", 41)

    def simulate(u: np.ndarray) -> np.ndarray:  # 3 % of every move per decade of time
        return _log_creep(base.simulate(u, base.anhysteretic_state(), sample_time=DT).output, 0.03)

    ident, exps = _recordings(simulate, 2.0, 2)
    rep = diagnose(base, exps, identification=[ident], candidates=CANDIDATES, progress=False)
    assert rep.verdict == "creep", [e.evidence for e in rep.effects]


def test_hold_motion_tells_creep_from_an_after_effect_that_ends():
    """Late motion in holds: creep goes on for seconds; a 50 ms lag has ended after 0.5 s."""
    rng = np.random.default_rng(3)
    u = np.concatenate([np.full(1500, v) for v in (0.0, 1.0, -0.5, 0.8, -1.0, 0.2)])
    lag = np.convolve(np.diff(u, prepend=u[0]), 1 - np.exp(-np.arange(u.size) * DT / 0.05))
    noise = 1e-3 * rng.normal(size=u.size)
    creep = hold_motion_of([(u, _log_creep(u, 0.01) + noise, DT)], 2.0)
    ends = hold_motion_of([(u, lag[: u.size] + noise, DT)], 2.0)
    assert creep.n_holds == ends.n_holds == 5
    assert creep.creeps and creep.ratio > 0.002
    assert not ends.creeps and abs(ends.t_stat) < 3


def test_holds_refute_a_creep_only_when_they_move_on_less_than_its_fit():
    """A late motion the holds cannot resolve refutes no creep; one far below the fit's does.

    Twelve 2 s holds of a device with a small logarithmic creep (0.03 % of every move per
    decade of time, 10 mV noise): from 0.5 s into the holds the output moves on by less
    than the noise resolves (t < 2).  A Prony creep that moves on about as much is not
    refuted (seed-18 blind case 006, a logarithmic creep at t = 1.2, was rejected for "the
    output holds still"); one that moves on 50 times more is.
    """
    from preisach.diagnose.context import Context
    from preisach.diagnose.data import prepare_recordings
    from preisach.diagnose.rate_family import CREEP_MIN_T, creep_implausible, hold_motion

    base = PreisachModel.builtin("ss15-1hz", 21)
    gamma = 3e-4
    levels = np.random.default_rng(5).uniform(-80, 80, 12)
    u = np.concatenate([np.full(int(2 / DT), v) for v in levels])

    def simulate(x: np.ndarray) -> np.ndarray:
        return _log_creep(base.simulate(x, base.negative_saturation()).output, gamma)

    recs = session([("steps", u)], simulate, NOISE, 5, DT)
    ctx = Context(base, prepare_recordings(base, recs, initial_states=["negative_saturation"]))
    hm = hold_motion(ctx)
    assert hm.n_holds >= 10 and 0 < hm.t_stat < CREEP_MIN_T  # real, but not resolved
    taus = [0.02, 0.2, 2.0, 20.0]
    # a 2 s lag of weight c moves on by c (exp(-1/4) - exp(-1)) ~ 0.41 c from 0.5 s to 2 s;
    # the log creep by gamma (log10(41) - log10(11)) ~ 0.57 gamma
    assert creep_implausible(ctx, taus, [0.0, 0.0, 1.4 * gamma, 0.0]) is None
    why = creep_implausible(ctx, taus, [0.0, 0.0, 70 * gamma, 0.0])
    assert why is not None and "holds still" in why and "fitted creep" in why


def _ramp(a: float, b: float, rate: float) -> np.ndarray:
    return np.linspace(a, b, max(2, int(abs(b - a) / rate / DT)))


def test_rate_family_base_is_held_by_the_contexts_ridge():
    """On a fine grid the family's refitted base keeps the classical refit's ridge (issue 13).

    When the model's grid is too coarse, diagnosis refits the base on a finer grid whose
    weights the sweep barely constrains, pulled toward the given model by a firmer ridge
    (:data:`~preisach.diagnose.selection.FIRM_RIDGE`).  The family refits the base together
    with its increments and must hold it the same way: with the former fixed 1e-7 its base
    followed the noise along the weakly determined directions, which held-out samples reach
    (here 423 mV held out against 98 mV for the classical refit, 66 mV with the fix; seed-9
    blind case 021: 165 mV against 7.8 mV).  A rate-dependent device (the SS15 rate model)
    identified from a
    9-curve FOD sweep at 200 V/s, diagnosed on filtered noise, a multi-sine and steps with a
    slow random-walk drift, 3 mV noise and 1 mV quantisation; one held-out fold.
    """
    from preisach.diagnose.context import Chain, Context
    from preisach.diagnose.data import prepare_recordings
    from preisach.diagnose.scoring import make_folds
    from preisach.diagnose.selection import FINE_LEVELS, FIRM_RIDGE
    from preisach.identify import identify
    from scipy import signal

    rng = np.random.default_rng(3)
    seg, cur = [_ramp(0, -100, 200)], -100.0
    for a in np.linspace(-100, 100, 10)[1:]:
        seg += [_ramp(cur, a, 200), _ramp(a, -100, 200)]
    ident = np.concatenate(seg)
    b, a = signal.butter(2, 18.3 * 2 * DT)
    x = signal.lfilter(b, a, rng.normal(size=6906))
    t = np.arange(9898) * DT
    ms = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 6)) for f in (1.92, 3.33, 1.44, 1.19))
    exps = [
        100 * np.clip(x / x.std() / 2.9, -1, 1),
        95 * ms / np.abs(ms).max(),
        *(
            np.concatenate([np.full(h, v) for v in rng.uniform(-100, 100, n // h)])
            for n, h in ((8292, 611), (9127, 472))
        ),
    ]
    truth = RateDependentPreisachModel.builtin("ss15-rate", levels=61)
    u_all = np.concatenate([ident, *exps])
    y_all = truth.simulate(u_all, sample_time=DT).output + 0.003 * rng.normal(size=u_all.size)
    y_all += 0.02 * np.cumsum(rng.normal(size=u_all.size)) / np.sqrt(u_all.size)
    y_all = np.round(y_all / 1e-3) * 1e-3
    recs, k = [], 0
    for u in [ident, *exps]:
        recs.append(Recording.from_arrays(u=u, y=y_all[k : k + u.size], sample_time=DT))
        k += u.size
    model = identify([recs[0]], progress=False).model
    prep = prepare_recordings(model, recs[1:], identification=[recs[0]])
    levels = np.linspace(model.u_min, model.u_max, FINE_LEVELS)
    ctx = Context(model, prep, refit=True, levels=levels, ridge=FIRM_RIDGE)
    fold = make_folds(prep, "blocks")[0]

    def heldout(chain: Chain) -> float:
        e = [(r.y - p)[m] for r, p, m in zip(prep, ctx.predict(chain), fold.test)]
        return float(np.sqrt(np.mean(np.concatenate(e) ** 2)))

    base = Chain(ctx.refit_base([], ctx.given, fold.train, False))
    cand = RateFamilyCandidate()
    cand.prepare(ctx)
    family = cand.fit_chain(ctx, base, fold.train, False)
    assert heldout(family) < 0.8 * heldout(base), (heldout(family), heldout(base))


def test_a_rate_form_that_does_not_grow_with_the_rate_is_not_rate_dependence():
    """A loop width or threshold dilation fitted with a rate exponent near 0 is the same at
    every rate: a rate-independent change of the loops (seed-11 blind null 008 was named
    rate dependence by a loop width scaling as rate^0.0003)."""
    from typing import Any

    from preisach.diagnose.candidates import RateCandidate, RateWidthCandidate

    ctx: Any = None  # the check reads only the fitted parameters
    for cand in (RateWidthCandidate(), RateCandidate()):
        assert "rate-independent" in (cand.implausible(np.array([0.01, 0.0003]), ctx) or "")
        assert cand.implausible(np.array([0.01, 0.44]), ctx) is None


@pytest.mark.parametrize("rate", [True, False])
def test_the_family_is_held_against_the_fine_classical_model(rate):
    """What the family's rate columns add to the fine classical model is its evidence.

    On the SS15 rate model the family's increments (with their smoothness across rate) add
    many noise variances to a 61-level classical model with free initial states; on a
    rate-independent device (the 1 Hz surface itself, with the same inputs) they add less
    than the bar.  Fails when the columns or their penalty stop describing the family's
    rate-varying part, or the check gives a classical device a rate effect.
    """
    from preisach.diagnose.context import Chain, Context
    from preisach.diagnose.data import prepare_recordings
    from preisach.diagnose.scoring import beyond_classical
    from preisach.diagnose.selection import FORM_BEYOND_CLASSICAL

    model = PreisachModel.builtin("ss15-1hz", 41)
    if rate:
        truth = RateDependentPreisachModel.builtin("ss15-rate", levels=41)
        ident, exps = _recordings(lambda u: truth.simulate(u, sample_time=DT).output, 1.3, 1)
    else:
        ident, exps = _recordings(
            lambda u: model.simulate(u, model.anhysteretic_state()).output, 1.3, 1
        )
    ctx = Context(model, prepare_recordings(model, exps, identification=[ident]), refit=True)
    cand = RateFamilyCandidate()
    cand.prepare(ctx)
    chain = cand.fit_chain(ctx, Chain(ctx.given), [r.usable.copy() for r in ctx.recs], False)
    eff = chain.effects[-1]
    form = eff.cand.classical_columns(ctx, eff.x)
    assert form is not None and form[1] is not None
    chk = beyond_classical(ctx, NOISE, form[0], penalty=form[1])
    assert chk.passes(FORM_BEYOND_CLASSICAL) == rate, chk
    if rate:
        assert chk.gain > 10 * FORM_BEYOND_CLASSICAL, chk


def test_a_rate_filter_at_its_longest_time_constant_is_not_rate_dependence():
    """The family's ``tau`` at the longest tried follows the input's history, not its rate.

    (Seen blind cases 19/024, 21/017 and 22/019 - a drift with a delay, a drift with creep,
    a delay - were named rate dependence by the family with ``tau`` = 0.25 s.)
    """
    from typing import Any

    cand = RateFamilyCandidate()
    cand.taus = list(cand.TAUS)
    ctx: Any = None  # the check reads only the fitted parameter
    assert "longest tried" in (cand.implausible(np.array([max(cand.TAUS)]), ctx) or "")
    assert cand.implausible(np.array([0.015]), ctx) is None


def test_late_share_is_the_bank_movement_after_one_second():
    from preisach.diagnose.rate_family import late_share

    assert late_share([0.25], [1.0]) == pytest.approx(np.exp(-4.0))
    # weights average the lags' late shares; a negative weight counts as none
    assert late_share([0.02, 2.0], [1.0, 1.0]) == pytest.approx(0.5 * np.exp(-0.5), rel=1e-9)
    assert late_share([0.02, 2.0], [1.0, -1.0]) == pytest.approx(np.exp(-50.0))
    assert late_share([0.2], [0.0]) == 0.0


@pytest.mark.slow
def test_a_creep_of_tenths_of_a_second_is_named_creep(tmp_path):
    """Blind seed 74's case 017 (scripts/blind2, written from physical descriptions only): a
    Kelvin-Voigt creep with time constants of 0.25 and 0.28 s, 6.5 x the noise.  The creep
    fit gains 64 % but less than a tenth of it moves later than 1 s after a move, so the
    late-share rule refused it ("a lag or rate dependence"), and a rate dependence that
    gained 15 % was named.  Nothing that acts faster explains half as much: it is a creep of
    tenths of a second.  Fails with ``CREEP_FAST_RIVAL = 0`` (verdict ``rate_dependence``)."""
    from _paths import blind_diagnosed

    forms, rep = blind_diagnosed(tmp_path, 74, 17, ["creep", "rate_dependence", "delay"])
    assert forms == ["kelvin_voigt_chain"]
    assert rep.verdict == "creep", rep.summary()
    eff = rep.effects[0]
    assert "qualified although fast" in eff.evidence, eff.evidence
    assert eff.heldout_rmse_after < 0.5 * eff.heldout_rmse_before, eff.evidence
    # the bank's weight sits at the 0.2 s lag, none at 2 s or 20 s
    w = {k: v["value"] for k, v in eff.parameters.items() if k.startswith("c_")}
    assert max(w, key=w.get) == "c_0.2s", w
    assert w["c_2s"] + w["c_20s"] < 0.1 * w["c_0.2s"], w
