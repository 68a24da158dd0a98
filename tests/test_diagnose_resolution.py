"""A slow drift is not the base's resolution, and a known initial state is not free.

The device is written from a physical description, not from the check's form: a classical
piezo (the built-in SS15 surface on a 21-level grid, so the 11-level model identified from
its sweep leaves a resolution residual) read through a displacement sensor whose offset
follows the lab's temperature - a slow swing of a few millivolts over the run - with 1 mV
white noise.  Every experiment starts from negative saturation (a known initial state).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from _inputs import offset_loops
from preisach import PreisachModel, Recording, _core
from preisach.diagnose.candidates import CreepCandidate, NonCongruenceCandidate
from preisach.diagnose.context import Chain, Context
from preisach.diagnose.core import _classical_change
from preisach.diagnose.data import noise_sigma, prepare_recordings
from preisach.diagnose.holds import HoldMotion
from preisach.diagnose.scoring import fine_system, make_folds, unresolved_start, unvisited_bound
from preisach.diagnose.selection import (
    DRIFT_CONFIRM_LEVELS,
    DRIFT_KEEP_SHARE,
    DRIFT_REFINE_RATIO,
    RESOLUTION_BEYOND_CLASSICAL,
    _creep_within_classical,
    _feedback_within_classical,
    resolution_check,
)
from preisach.identify import identify_fod
from preisach.waveforms import fod_sweep, legs

DT, NOISE = 2e-3, 1e-3


def _device(u: np.ndarray, seed: int, creep: float = 0.0, moving: float = 0.0) -> np.ndarray:
    """The piezo's output (V) with 1 mV noise; ``creep``: the logarithmic creep law's share of
    every move that follows per decade of time (from 50 ms on), superposed over the moves;
    ``moving``: a moving model's interaction (Della Torre, the relays see ``u + alpha y``),
    as the input shift (V) at the ends of the output range per volt of input range."""
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    x = np.asarray(_core.simulate(m.table, u, m.negative_saturation(), "clamp")[0])
    if moving:
        ends = _core.simulate(m.table, [100.0, -100.0], m.negative_saturation(), "clamp")[0]
        lo, half = float(ends[1]), 0.5 * float(ends[0] - ends[1])
        x = np.asarray(
            _core.simulate_moving(
                m.table, u, m.negative_saturation(), 100.0 * moving / half, 0.0, lo + half, half
            )[0]
        )
    if creep:
        decades = np.log10(1.0 + np.arange(u.size) * DT / 0.05)
        x = x + creep * np.convolve(np.diff(x, prepend=x[0]), decades)[: u.size]
    return x + np.random.default_rng(seed).normal(0.0, NOISE, u.size)


def _context(
    swing: float, start: float = -100.0, lead: float = 0.1, creep: float = 0.0, moving: float = 0.0
) -> Context:
    """Two loop experiments after the sweep; the sensor offset swings by ``swing`` (V).

    Each experiment holds ``start`` (V) for 50 ms first, then moves to -100 V (in ``lead``
    seconds); from 0 V its initial state is unknown to the diagnosis.  ``creep`` and
    ``moving``: the device's logarithmic creep and interaction (:func:`_device`), in the sweep
    too.
    """
    sweep = fod_sweep(np.linspace(-100.0, 100.0, 11), frequency=2.0, sample_time=DT).u
    ident = Recording.from_arrays(
        t=np.arange(sweep.size) * DT, u=sweep, y=_device(sweep, 0, creep, moving)
    )
    head = np.full(25, start) if start == -100.0 else legs([start, -100.0], lead, sample_time=DT).u
    u = np.concatenate([head, offset_loops(DT)])
    t = np.arange(u.size) * DT
    recs = []
    for k in range(2):  # the temperature swings with a 12 s period over the 10 s run
        y = _device(u, 1 + k, creep, moving) + _offset(swing, t, k)
        recs.append(Recording.from_arrays(t=t, u=u, y=y, experiment=f"loops{k}"))
    model = identify_fod(ident, 11).model
    return Context(model, prepare_recordings(model, recs, identification=[ident]), refit=True)


def _offset(swing: float, t: np.ndarray, k: int) -> np.ndarray:
    """The sensor offset (V) of experiment ``k`` at its times ``t``."""
    return swing * np.sin(2.0 * np.pi * (t + k * t[-1]) / 12.0)


@pytest.mark.parametrize("swing", [0.0, 3e-3])
def test_a_slow_drift_beyond_the_fine_classical_model(swing):
    """A drifting sensor is not consistent with the fine classical model; a steady one is.

    Fails when the resolution check stops seeing a slow change in time that no classical
    model follows (the drift's gain and its significance), when a known initial state gets
    the freedom of an unknown one again (the running range then follows the drift while
    the loops widen), or when it starts calling a steady device's residual more than the
    base's resolution.
    """
    ctx = _context(swing)
    assert all(r.history is None for r in ctx.recs)  # both start from saturation
    chk, curves = resolution_check(ctx, NOISE, noise_ratio=2.0)
    drift = chk["drift"]
    assert drift is not None, chk["statement"]  # the fine classical model is within the bound
    assert (curves is not None) == bool(swing)  # its drift curves, when they count
    if swing:
        assert drift["gain_noise_variances"] >= RESOLUTION_BEYOND_CLASSICAL, drift
        # the swing is about 4 noise variances, less each recording's offset; a known state
        # with the running-range freedom left only 0.11 of it to the drift (1.08 without)
        assert drift["gain_noise_variances"] >= 0.5, drift
        assert drift["p"] < 0.01, drift
        # a drift, not a grid's misfit: the finer grid keeps it
        assert drift["finer"][-1]["gain_noise_variances"] >= 0.5, drift
        assert drift["finer"][-1]["p"] < 0.01, drift
        assert not chk["consistent"], chk["statement"]
        assert "drift in time" in chk["statement"]
    else:
        assert drift["gain_noise_variances"] < RESOLUTION_BEYOND_CLASSICAL, drift
        assert chk["consistent"], chk["statement"]
        assert "identify on a finer grid" in chk["statement"]  # what to do about it


@pytest.mark.parametrize("swing", [0.0, 3e-3])
def test_an_unknown_initial_state_has_only_the_unvisited_relays_freedom(swing):
    """The same device, each experiment starting at 0 V (an unknown state) before -100 V.

    An unknown initial state differs from the chosen one only in the relays the input has
    not reached; once the input has been at -100 V there are none.  Fails when the fine
    model's initial-state nuisance is not held to that bound (the running range then
    follows the drift while it grows: with the bound lifted the drift adds 0.11 noise
    variances, with it 1.18), or when a steady device stops being consistent.
    """
    ctx = _context(swing, start=0.0)
    assert all(r.history is not None for r in ctx.recs if not r.ident)
    chk, curves = resolution_check(ctx, NOISE, noise_ratio=2.0)
    drift = chk["drift"]
    assert drift is not None, chk["statement"]
    if swing:
        assert drift["gain_noise_variances"] >= 0.5, drift
        assert drift["p"] < 0.01, drift
        assert not chk["consistent"], chk["statement"]
    else:
        assert drift["gain_noise_variances"] < RESOLUTION_BEYOND_CLASSICAL, drift
        assert chk["consistent"], chk["statement"]


def test_the_unvisited_relays_bound_is_the_major_loops_width():
    """From nothing at 0 V, two states differ at most by the major loop's width there."""
    m = PreisachModel.builtin("ss15-1hz", levels=21)
    down = _core.simulate(m.table, np.array([100.0, 0.0]), m.positive_saturation(), "clamp")[0]
    up = _core.simulate(m.table, np.array([-100.0, 0.0]), m.negative_saturation(), "clamp")[0]
    u = np.array([0.0, 50.0, -100.0, 100.0])
    b = unvisited_bound(m, u, np.arange(4))
    assert b[0] == pytest.approx(down[-1] - up[-1], rel=1e-9)
    assert b[0] > b[1] > b[2] == pytest.approx(0.0, abs=1e-12) and b[3] == b[2]


def test_a_change_only_the_fine_classical_model_shows_is_named_by_the_holds():
    """The fine model's drift curves follow the sensor; the holds say drift or creep.

    When nothing was kept and only the fine classical model shows a change in time (blind
    seed-20 case 001, a warm-up drift, and seed-21 case 024, a creep: their gain sat below
    the base's resolution residual in the selection), the report names it from the check:
    a sensor drift when input holds show that the residual does not follow the moves into
    them, creep when it does.  Fails when the check's curves stop following the sensor's
    offset (each recording's mean aside), when the named size is off, when the holds' verdict
    is ignored, or when something is named without holds.
    """
    swing = 3e-3
    ctx = _context(swing)
    chk, curves = resolution_check(ctx, NOISE, noise_ratio=2.0)
    assert curves is not None, chk["statement"]
    for i in ctx.diag:
        r = ctx.recs[i]
        true = _offset(swing, r.t - r.t[0], i)[r.usable]
        fit = curves[i][r.usable]
        assert np.corrcoef(fit, true)[0, 1] > 0.9
        assert np.ptp(fit) == pytest.approx(np.ptp(true), rel=0.3)
    still = HoldMotion(n_pieces=6, seconds=4.0, ratio=1.0, follows_t=-0.8)
    eff = _classical_change(ctx, chk, curves, still, NOISE)
    assert eff is not None and eff.name == "sensor_drift"
    size = max(np.ptp(_offset(swing, ctx.recs[i].t - ctx.recs[i].t[0], i)) for i in ctx.diag)
    assert eff.parameters["peak_to_peak"]["value"] == pytest.approx(size, rel=0.3)
    assert eff.heldout_rmse_after < eff.heldout_rmse_before
    assert "free initial states" in eff.evidence
    creeping = HoldMotion(n_pieces=6, seconds=4.0, ratio=1.5, follows_t=8.0)
    crept = _classical_change(ctx, chk, curves, creeping, NOISE)
    assert crept is not None and crept.name == "creep" and "as creep does" in crept.evidence
    assert _classical_change(ctx, chk, curves, None, NOISE) is None
    few = HoldMotion(n_pieces=2, seconds=1.0, ratio=1.0, follows_t=-0.8)
    assert _classical_change(ctx, chk, curves, few, NOISE) is None


def test_a_start_up_step_from_an_unknown_state_is_not_scored_by_the_fine_check():
    """A move through unvisited relays within one stretch: only its own samples show it.

    Fails when a fast first step from rest (0 to -4.4 V in 10 ms, blind seed-20 null case
    025, mispredicted by the fine model by up to 0.3 V from an unknown state and read as
    more than the base's resolution) is scored, or when a slow first move, later moves
    inside the range visited, or a stretch after the step are taken out.
    """
    dt, stretch = 1e-3, 0.01
    rest = np.zeros(270)
    ramp = np.linspace(0.0, -4.4, 11)[1:]
    noise = -4.4 + 12.0 * np.sin(np.linspace(0.0, 3.0 * np.pi, 3000)) ** 3
    u = np.concatenate([rest, ramp, np.full(100, -4.4), noise])
    marked = unresolved_start(u, dt, stretch, 16)
    assert marked[270:280].all()  # the step's stretches (270-279, 280-289 hold its end)
    assert not marked[:260].any() and not marked[300:400].any()  # rest; the hold after it
    assert marked.sum() <= 40  # a few stretches of the noise reaching new extremes at most
    slow = np.concatenate([rest, np.linspace(0.0, -4.4, 2000)])
    assert not unresolved_start(slow, dt, stretch, 16).any()
    # the same step two samples earlier: the stretch before it holds only its first 0.88 V,
    # less than a knot interval (1.5 V), and interpolates toward a knot only the move
    # reaches - marked too (blind seed-24 case 015: 9 x the noise there, 26 x with a drift)
    early = np.concatenate([rest[:-2], ramp, np.full(102, -4.4), noise])
    marked = unresolved_start(early, dt, stretch, 16)
    assert marked[260:280].all() and not marked[:260].any() and not marked[280:400].any()
    # the fine check leaves them out of both folds: a 4 ms step from 0 V to -100 V, unknown
    # state (the 0.1 s step of the other tests grows the range by less than a knot per stretch)
    for lead, out in ((0.004, True), (0.1, False)):
        ctx = _context(0.0, start=0.0, lead=lead)
        fs = fine_system(ctx)
        for i in ctx.diag:
            r = ctx.recs[i]
            step = np.flatnonzero(np.abs(np.diff(r.u)) > 0)[0] + 1  # the move's first sample
            assert (fs.folds[i][step] == -1) == out, (lead, step)
            assert (fs.folds[i][r.usable] >= 0).mean() > 0.95


def test_added_columns_extend_the_one_fine_system_exactly():
    """The fine system is assembled once per context; an effect's columns border it.

    Fails when the bordered normal equations differ from those of the dense design (the
    Everett rows, each recording's state basis, its own columns and the shared ones), or
    when a second call assembles the system again.
    """
    ctx = _context(0.0, start=0.0)
    base = fine_system(ctx, levels=11)
    assert fine_system(ctx, levels=11) is base
    rng = np.random.default_rng(5)
    own = [rng.normal(size=(r.n, 1 + i)) for i, r in enumerate(ctx.recs)]
    shared = [rng.normal(size=(r.n, 2)) for r in ctx.recs]
    fs = base.extended(own=own, shared=shared)
    P = fs.A.shape[1]
    assert P == base.A.shape[1] + sum(1 + i for i in range(len(ctx.recs))) + 2
    for k in range(3):
        want, rhs = np.zeros((P, P)), np.zeros(P)
        for i, r in enumerate(ctx.recs):
            X = np.zeros((r.n, P))
            X[:, : fs.p] = fs.regs[i].toarray()
            X[:, fs.cols[i]] = fs.feats[i]
            m = fs.folds[i] == k
            want += X[m].T @ X[m]
            rhs += X[m].T @ r.y[m]
        np.testing.assert_allclose(fs.A[k], want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
        np.testing.assert_allclose(fs.rhs[k], rhs, rtol=1e-9, atol=1e-9 * np.abs(rhs).max())
    for i in range(len(ctx.recs)):  # each recording's own columns, then the shared ones
        new = fs.feats[i][:, base.feats[i].shape[1] :]
        np.testing.assert_array_equal(new[:, : 1 + i], own[i])
        np.testing.assert_array_equal(new[:, 1 + i :], shared[i])
        assert fs.own_cols[i].size == 1 + i


@pytest.mark.parametrize("swing, creep", [(3e-3, 0.0), (0.0, 0.0), (0.0, 3e-3)])
def test_creep_is_named_only_beyond_the_fine_classical_model(swing, creep):
    """A creep bank that adds nothing to the fine classical model is not creep.

    With no input holds to show it, creep must add to the fine classical model with free
    initial states, as every linear form must (blind seeds 36/004 and 37/001, a random walk
    and a 1/f sensor wander, were named creep by the bank's 20 s mode).  Fails when a
    sensor that swings with the lab's temperature or a steady classical device lets the bank
    pass, or when a logarithmic creep (0.3 % of every move per decade) stops passing.
    """
    ctx = _context(swing, creep=creep)
    cand = CreepCandidate()
    cand.prepare(ctx)
    why = _creep_within_classical(ctx, cand, None, NOISE, 0.01, seed=0)
    if creep:
        assert why is None
    else:
        assert why is not None and "too few input holds" in why, why
        assert "classical Preisach model with free initial states explains" in why, why


@pytest.mark.parametrize("moving", [0.0, 0.03])
def test_a_feedback_is_named_only_beyond_the_fine_classical_model(moving):
    """A fitted output feedback whose contribution a classical model makes is not named.

    Fails when the feedback fitted to a classical device (an 11-level model of a 21-level
    density: its residual is resolution) passes, as blind seed 39's null 023 did with a 25 %
    held-out gain, or when a moving-model device (the relays see the input shifted by 3 % of
    the input range at the ends of the output range) stops passing.
    """
    ctx = _context(0.0, moving=moving)
    fold = make_folds(ctx.recs, "blocks")[0]
    cand = NonCongruenceCandidate()
    cand.prepare(ctx)
    chain = ctx.fit(
        cand, Chain(ctx.refit_base([], ctx.given, fold.train, False)), fold.train, False
    )
    why = _feedback_within_classical(ctx, cand, chain, NOISE, 0.01, seed=0)
    if moving:
        assert why is None
    else:
        assert why is not None and "classical Preisach model" in why, why


def _generated_case(tmp_path, seed: int, index: int) -> tuple[Context, list[str]]:
    """Case ``index`` of the blind generator's seed ``seed`` (:func:`_paths.blind_case`) as
    the diagnosis sees it when nothing was kept: the model identified from its sweep,
    refitted on the experiments, the drift's knots chosen on held-out time (as the
    selection's drift candidate does), and the forms of its effects."""
    from _paths import blind_case
    from preisach.identify import identify

    case, forms = blind_case(tmp_path, seed, index)
    ident = Recording.load(case / "id.csv")
    recordings = [Recording.load(p) for p in sorted(case.glob("exp*.csv"))]
    model = identify([ident], progress=False).model
    ctx = Context(model, prepare_recordings(model, recordings, identification=[ident]), refit=True)
    ctx.choose_drift_roughness()
    return ctx, forms


def _noise(ctx: Context) -> float:
    """The noise (V) as the diagnosis estimates it (third differences; smooth outputs)."""
    return math.sqrt(np.mean([noise_sigma(r.y) ** 2 for r in ctx.recs if not r.ident]))


@pytest.mark.slow
def test_a_drift_must_also_pass_on_the_finer_grid(tmp_path):
    """A classical device with narrow loops is not named a drift by the resolution check.

    Blind seed 46's case 013 has no effect: a Preisach density close to the diagonal (loops
    about 0.75 V wide on a +-10 V input), slow triangles and a wiping-out sequence among its
    experiments.  The 61-level fine model cannot follow the narrow loops, and what it leaves
    changes slowly with the triangles' amplitudes: a drift curve in time took up 0.046 noise
    variances of it (p 0.00025) and the null was named ``sensor_drift``.  On 81 levels that
    misfit is gone, and so is the drift.  Fails when a drift found on the fine grid is named
    without a finer one (``DRIFT_CONFIRM_LEVELS``) confirming it.
    """
    ctx, forms = _generated_case(tmp_path, 46, 13)
    assert forms == []  # a null
    chk, curves = resolution_check(ctx, _noise(ctx), noise_ratio=2.0)
    drift = chk["drift"]
    # the fine grid's misfit passes the bar as a drift ...
    assert drift["gain_noise_variances"] >= RESOLUTION_BEYOND_CLASSICAL, drift
    assert drift["p"] < 0.01, drift
    # ... the first finer grid leaves nothing for it
    (finer,) = drift["finer"]
    assert finer["levels"] == DRIFT_CONFIRM_LEVELS[0]
    assert finer["gain_noise_variances"] < 0.1 * drift["gain_noise_variances"], finer
    assert chk["found"] is None and chk["consistent"], chk["statement"]
    assert curves is None
    assert "not a change in time" in chk["statement"]


@pytest.mark.slow
def test_a_drift_is_confirmed_on_the_grid_that_resolves_no_more(tmp_path):
    """A drift that passes on 81 levels while they still resolve more is tried on 101.

    Blind seed 47's case 017: a rate effect of 1.05 x the noise (far below what it was meant
    to be) on a density with a narrow peak.  Its drift beyond the fine model added 0.026
    noise variances on 61 levels and 0.013 on 81 (both p < 0.01), and it was named
    ``sensor_drift``; the 81-level model lowered the held-out ratio from 1.73 to 1.40 x the
    noise, more than ``DRIFT_REFINE_RATIO`` allows, and on 101 levels the drift adds
    nothing.  Fails when the refinement stops at the first finer grid.
    """
    ctx, forms = _generated_case(tmp_path, 47, 17)
    assert forms == ["debye_relaxation"]
    chk, curves = resolution_check(ctx, _noise(ctx), noise_ratio=2.0)
    drift = chk["drift"]
    assert [f["levels"] for f in drift["finer"]] == list(DRIFT_CONFIRM_LEVELS), drift
    first, last = drift["finer"]
    assert first["gain_noise_variances"] >= RESOLUTION_BEYOND_CLASSICAL, drift
    assert first["ratio"] <= DRIFT_REFINE_RATIO * chk["ratio"], drift
    assert last["gain_noise_variances"] < RESOLUTION_BEYOND_CLASSICAL, drift
    assert chk["found"] is None and chk["consistent"], chk["statement"]


@pytest.mark.slow
def test_a_drift_that_keeps_its_gain_on_finer_grids_is_found(tmp_path):
    """A random-walk drift smaller on finer grids, but not gone, is found beyond the model.

    Blind seed 59's case 010: a sensor drift (a random walk, 3.1 x the noise).  Beyond the
    fine classical model it adds 0.014 noise variances (p 0.0005) on 61 levels and 0.009 on
    81 and 101 (p <= 0.0015): under the absolute bar (0.01) it was refused as a grid's misfit
    and the verdict was ``none``.  A misfit shrinks as the grid refines (the nulls kept
    0-9 %); this drift keeps about two thirds.  Fails when the finer grids' bar is absolute.
    """
    ctx, forms = _generated_case(tmp_path, 59, 10)
    assert forms == ["random_walk"]
    chk, curves = resolution_check(ctx, _noise(ctx), noise_ratio=2.0)
    drift = chk["drift"]
    assert drift["gain_noise_variances"] >= RESOLUTION_BEYOND_CLASSICAL, drift
    last = drift["finer"][-1]
    assert last["gain_noise_variances"] < RESOLUTION_BEYOND_CLASSICAL, drift
    assert last["gain_noise_variances"] >= DRIFT_KEEP_SHARE * drift["gain_noise_variances"], drift
    assert last["p"] < 0.01, drift
    assert chk["found"] == "drift" and not chk["consistent"], chk["statement"]
    assert curves is not None


@pytest.mark.parametrize(
    ("fine", "finer", "levels"),
    [(2.3, 1.8, [61, 81]), (2.3, 2.2, [61, 81]), (3.5, 1.8, [61])],
)
def test_a_fine_grid_just_above_the_bound_is_checked_on_a_finer_one(
    monkeypatch, fine, finer, levels
):
    """The fine (61-level) and finer (81-level) models' ratios set to ``fine`` and ``finer``
    x the noise (bound 2 x).  Just above the bound the finer grid is tried, and when its
    model is within the bound it decides: the residual is resolution (a density narrower
    than the fine grid), the tests beyond it run on that grid and the report says which
    grid left what.  Far above, no finer grid is tried.  Blind seed-53 null 007 (a diagonal
    ridge): 2.36 x on 61 levels, 1.79 x on 81.  A finer grid is not always better - on this
    steady device 81 levels leave 2.5 x where 61 leave 1.1 x - so it only ever decides for
    resolution.  Fails when the finer grid is not tried, is tried beyond its span, or its
    ratio is not the one that decides.
    """
    from dataclasses import replace

    from preisach.diagnose import selection
    from preisach.diagnose.scoring import CHECK_LEVELS, classical_check

    assert (CHECK_LEVELS, selection.RESOLUTION_CONFIRM_LEVELS) == (61, 81)
    seen = []

    def check(ctx, sigma, **kw):  # the grids' ratios set as the case says
        res = classical_check(ctx, sigma, **kw)
        seen.append(res.levels)
        return replace(res, ratio=fine if res.levels == CHECK_LEVELS else finer)

    monkeypatch.setattr(selection, "classical_check", check)
    ctx = _context(0.0)
    chk, _ = resolution_check(ctx, NOISE, noise_ratio=2.0)
    assert seen == levels, seen
    within = finer <= 2.0 and len(levels) == 2
    assert chk["consistent"] is within, chk["statement"]
    if within:
        assert chk["levels"] == 81 and chk["ratio"] == finer, chk
        assert chk["coarser"] == {"levels": 61, "ratio": fine}, chk
        assert "where 61 levels left 2.3 x" in chk["statement"], chk["statement"]
    else:
        assert chk["levels"] == 61 and chk["coarser"] is None, chk
    assert not any(k[0] == 81 for k in ctx.fine_systems)  # released
