"""The diagnosis context: recordings, the base model (given or refitted), chains of effects.

:class:`Context` holds what every candidate needs during a diagnosis: the prepared
recordings, the Everett table of the base model or the least-squares refit of its weights
(``preisach._core.regressor_rows`` / ``normal_equations``), the sensor-drift P-spline, the
evaluation of a chain (input blocks -> Preisach operator with feedback -> output blocks), and
the fitting of a candidate on training samples (:class:`~preisach.diagnose.problem.Problem`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy import linalg, optimize

from .. import _core
from .._resources import check_allocation
from ..model import PreisachModel
from . import drift as drift_mod
from .candidates import Candidate
from .data import History, Rec, state_options
from .effects import OutputFeedback

if TYPE_CHECKING:
    from .problem import Problem

__all__ = ["Base", "Chain", "Context", "FittedEffect", "Fold", "Stage", "signal_lag"]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: Most least-squares solves of a refitted base's weights, each after the unknown initial
#: states were re-chosen for the last (:meth:`Context.refit_base`); it stops earlier when no
#: state changes.
BASE_ROUNDS = 4


@dataclass
class FittedEffect:
    """A candidate with fitted parameters."""

    cand: Candidate
    x: Array
    cov: Array | None = None


@dataclass
class Base:
    """The Preisach part of a chain: the given model (``theta is None``) or refitted weights.

    ``states`` maps a recording whose initial state is unknown to the input history chosen
    for this base (absent: the recording's own, the given model's choice); see
    :meth:`Context.choose_states`.
    """

    theta: Array | None = None
    table: Any = None
    cache: dict[int, Array] = field(default_factory=dict, repr=False)
    states: dict[int, History] = field(default_factory=dict)


@dataclass
class Chain:
    """Base model plus fitted effects (drift is handled separately, by projection)."""

    base: Base
    effects: list[FittedEffect] = field(default_factory=list)

    def plus(self, eff: FittedEffect, base: Base | None = None) -> Chain:
        """Return this chain with ``eff`` appended (and ``base`` when given)."""
        return Chain(base if base is not None else self.base, [*self.effects, eff])


@dataclass
class Stage:
    """What the Preisach operator saw for one recording: its input (V) and its table."""

    i: int
    u: Array
    table: Any


@dataclass
class Fold:
    """Training and held-out samples of one cross-validation fold."""

    train: list[Mask]
    test: list[Mask]


def prior_everett(model: PreisachModel, levels: Array) -> Array:
    """Return the given model's Everett table on ``levels`` (V): the refit's prior weights.

    On the model's own grid (or a coarser one), and on any grid for a cubic model, its table
    interpolated as it simulates.  On a finer grid than a bilinear model's the table's nodes
    are interpolated by a bicubic spline of its antisymmetric extension
    ``E(a, b) = -E(b, a)`` (smooth across the diagonal, where the reversible part makes ``E``
    linear in ``a - b``): a bilinear table is a poor prior
    for the finer grid's nodes of a smooth density.  On the 26 densities of a blind seed
    (Gaussian, lognormal, ridge and two-component densities; 6.5-8.5 V) the bilinear
    interpolant of a 22-level grid missed the Everett function by 13-36 mV RMS, the bicubic
    one of the same nodes by 0.2-5 mV (noise 1-3 mV), so the finer grid's weights that the
    diagnosis recordings barely constrain start where the density is.
    """
    lv = np.asarray(levels, float)
    own = np.asarray(model.levels, float)
    a, b = np.meshgrid(lv, lv, indexing="ij")
    if lv.size <= own.size or own.size < 4 or model.interpolation == "cubic":
        return np.asarray(model.everett(a, np.minimum(a, b)), float)
    from scipy.interpolate import RectBivariateSpline

    A, B = np.meshgrid(own, own, indexing="ij")
    e = np.asarray(model.everett_values, float)
    ext = np.where(A >= B, e, -e.T)
    x = np.clip(lv, own[0], own[-1])
    out = RectBivariateSpline(own, own, ext, kx=3, ky=3).ev(*np.meshgrid(x, x, indexing="ij"))
    return np.where(a > b, out, 0.0)


def signal_lag(x: Array, pole: float) -> Array:
    """First-order lag of ``x`` (pole ``exp(-dt/tau)``) started at its steady state ``x[0]``."""
    from scipy import signal

    y, _ = signal.lfilter([1 - pole], [1.0, -pole], x, zi=[pole * float(x[0])])
    return np.asarray(y)


class Context:
    """Recordings, the base model and helpers shared by the candidates during a diagnosis."""

    def __init__(
        self,
        model: PreisachModel,
        recs: list[Rec],
        *,
        max_fit_samples: int = 30_000,
        max_delay: float | None = None,
        drift_smoothing: float = drift_mod.DRIFT_SMOOTHING,
        refit: bool = False,
        refit_levels: int = 21,
        alternations: int = 2,
        levels: Array | None = None,
        ridge: float = 1e-7,
        output_unit: str = "V",
    ) -> None:
        self.model = model
        self.recs = recs
        #: the recordings' output unit: the candidates' statements state amounts in it
        self.output_unit = str(output_unit)
        self.diag = [i for i, r in enumerate(recs) if not r.ident]
        self.dt_min = min(r.dt for r in recs)
        self.u_span = model.u_max - model.u_min
        self.y_lo, self.y_hi = model.y_min, model.y_max
        self.y_span = abs(self.y_hi - self.y_lo)
        self.y_centre = 0.5 * (self.y_lo + self.y_hi)
        self.y_half_span = max(0.5 * self.y_span, 1e-12)
        #: the noise's RMS (output unit), set by :func:`~.core.diagnose` once estimated; 0
        #: while unknown (the candidates' checks against the noise are then skipped)
        self.noise_sigma = 0.0
        self.longest_duration = max(float(recs[i].t[-1] - recs[i].t[0]) for i in self.diag)
        self.max_delay = float(max_delay) if max_delay is not None else max(0.05, 10 * self.dt_min)
        #: knot spacing (s) of each recording's drift curve until it is chosen by held-out
        #: time (:meth:`choose_drift_roughness`, see :mod:`.drift`)
        self.drift_knot_spacing = float(np.clip(self.longest_duration / 6.0, 1.5, 10.0))
        self.drift_spacing: dict[int, float] = {}
        for i, r in enumerate(recs):  # the dense drift bases (drift_basis): estimate first
            T = max(float(r.t[-1] - r.t[0]), 1e-9)
            cols = math.ceil(T / drift_mod.spacing_options(T)[-1]) + 3  # the finest tried
            check_allocation(
                8.0 * r.t.size * cols,
                f"the drift basis of recording {i} ({r.t.size} samples x {cols} knots)",
                "diagnose a shorter stretch (split the recording) or decimate it",
            )
        self.drift_smoothing = float(drift_smoothing)
        self.max_fit_samples = max_fit_samples
        self.alternations = int(alternations)
        self.given = Base()
        rates = []
        for i in self.diag:
            r = recs[i]
            v = np.abs(np.gradient(r.u, r.dt))
            rates.append(v[v > 1e-3 * self.u_span])
        allr = np.concatenate(rates) if rates else np.zeros(0)
        self.reference_rate = float(np.median(allr)) if allr.size else 1.0
        self._basis: dict[int, Array] = {}
        self._states_seen: dict[int, Any] = {}
        self._anh: dict[Any, Any] = {}
        self._left: dict[tuple[int, int, bytes], Any] = {}  # session_left, by feedback
        self._options: dict[tuple[int, str], tuple[list[History], dict[int, Any]]] = {}
        self._problem: Problem | None = None
        self._last_problem: Any = None
        self.n_evals = 0
        #: the fine classical model's normal equations per setting (scoring.fine_system)
        self.fine_systems: dict[tuple[int, float, int], Any] = {}
        self.refit = bool(refit)
        #: the refit's interpolation between its nodes: the given model's
        self.interpolation = model.interpolation
        if self.refit:
            lv = model.levels
            if levels is not None:  # a grid chosen by the diagnosis (see choose_grid)
                lv = np.asarray(levels, float)
            elif lv.size > 41:
                lv = np.linspace(model.u_min, model.u_max, int(refit_levels))
            self.levels = lv
            #: ridge of the refit toward the given model's weights, relative to the mean
            #: diagonal of the normal matrix
            self.ridge = float(ridge)
            n = lv.size
            self.n_theta = n * (n - 1) // 2 + 1
            e = prior_everett(model, lv)
            self._ii, self._jj = np.tril_indices(n, -1)
            self.theta0 = np.concatenate([e[self._ii, self._jj], [model.y_min]])
            self._R: dict[tuple[int, int], sp.csr_matrix] = {}
            self._normal_cache: dict[tuple[int, int, bytes, bool], tuple[Any, Any]] = {}

    # -- base model -------------------------------------------------------------------------
    def table(self, base: Base) -> Any:
        """Return the Everett table of ``base`` (the given model's, or built from ``theta``)."""
        if base.theta is None:
            return self.model.table
        if base.table is None:
            n = self.levels.size
            v = np.zeros((n, n))
            v[self._ii, self._jj] = base.theta[:-1]
            base.table = _core.EverettTable(
                self.levels, v, float(base.theta[-1]), self.interpolation
            )
        return base.table

    def history(self, i: int, base: Base) -> History | None:
        """Input history before recording ``i`` under ``base`` (None: a known initial state)."""
        return base.states.get(i, self.recs[i].history)

    def state(
        self, i: int, base: Base, x: Array | None = None, fb: FittedEffect | None = None
    ) -> Any:
        """Return the initial state of recording ``i`` under ``base`` for the relay input ``x`` (V).

        A known initial state is the recording's ``state0``; an unknown one is the base's
        chosen history (:meth:`choose_states`) for the input the relays see (default the
        recording's input).  ``fb``: the feedback effect that shifts the relays' input, also
        before this recording (:meth:`session_left`).
        """
        r = self.recs[i]
        h = self.history(i, base)
        if h is None:
            return r.state0
        if x is None:
            if h is r.history:
                return r.state0
            x = r.u
        if fb is not None and h.kind == "session":
            return h.state(x, self.session_left(i, fb))
        return h.state(x)

    def session_left(self, i: int, fb: FittedEffect) -> Any:
        """Return the state the recording before ``i`` left when ``fb`` fed back on its relays.

        The session history (:func:`~preisach.diagnose.data.session_history`) runs the
        previous recording's input from its initial state; with a feedback effect its relays
        saw that input shifted by the feedback of its output, which at the end of a run at
        rest is a standing offset.  Left out, the next recording starts with its relays moved
        by that offset from where the previous one left them: on blind seed 49's moving-model
        case the relays' input moved by 41 mV, the predicted output sat 37 mV off at rest, and
        the two recordings concerned were predicted at 3.4 x the base's held-out error.  The
        previous recording's relays
        are taken to see its input shifted by the feedback of its measured output, as for an
        unknown initial state (:meth:`_relays_estimate`); its input blocks are left out (at
        rest at its end they pass the input).
        """
        key = (i, id(fb.cand), np.asarray(fb.x, float).tobytes())
        hit = self._left.get(key)
        if hit is None:
            p = self.recs[i - 1]  # the session's previous recording (prepare_recordings)
            hit = p.state0.apply(self._fed_back(i - 1, p.u, fb, p.y).tolist())
            if len(self._left) > 256:
                self._left.clear()
            self._left[key] = hit
        return hit

    def _history_key(self, i: int, base: Base) -> int:
        """Return a cache key for the history of recording ``i``: its identity (kept alive)."""
        h = self.history(i, base)
        self._states_seen.setdefault(id(h), h)
        return id(h)

    def preisach(
        self, i: int, base: Base, u: Array | None = None, fb: FittedEffect | None = None
    ) -> Array:
        """Return the Preisach output (V) of recording ``i`` for its input (or ``u``).

        ``fb``: the feedback effect by which ``u`` is shifted (for the initial state only).
        """
        r = self.recs[i]
        if u is None:
            if i not in base.cache:
                base.cache[i] = _core.simulate(self.table(base), r.u, self.state(i, base), "clamp")[
                    0
                ]
            return base.cache[i]
        return _core.simulate(self.table(base), u, self.state(i, base, u, fb), "clamp")[0]

    def regressor(self, i: int, u: Array | None = None, base: Base | None = None) -> sp.csr_matrix:
        """Sparse map from the refit weights ``theta`` to the Preisach output of recording ``i``.

        The relays start from the initial state of recording ``i`` under ``base`` (default:
        the recording's ``state0``).
        """
        r = self.recs[i]
        b = base if base is not None else self.given
        key = (i, self._history_key(i, b))
        if u is None and key in self._R:
            return self._R[key]
        x = r.u if u is None else u
        indptr, idx, data, _ = _core.regressor_rows(
            self.levels, x, self.state(i, b, u), "clamp", self.interpolation
        )
        R = sp.csr_matrix((data, idx.astype(np.int64), indptr), shape=(r.n, self.n_theta))
        if u is None:
            self._R[key] = R
        return R

    def _normal(
        self, i: int, R: sp.csr_matrix, m: Mask, drift: bool, cacheable: bool
    ) -> tuple[Array, Any]:
        """``R^T R`` over the rows ``m`` (minus the drift projection), and the projection."""
        # cacheable regressors are the cached ones of ``regressor`` (one per initial state),
        # kept alive in ``_R``, so their identity names them
        key = (i, id(R), np.packbits(m).tobytes(), drift)
        if cacheable and key in self._normal_cache:
            return self._normal_cache[key]
        Rm = R[m]
        Ni = (Rm.T @ Rm).toarray()
        proj = None
        if drift:
            A = self.drift_basis(i)[m]
            G, _ = self._drift_system(A)
            Ginv = np.linalg.inv(G)
            RA = np.asarray(Rm.T @ A)
            Ni = Ni - RA @ Ginv @ RA.T
            proj = (A, Ginv)
        if cacheable:
            self._normal_cache[key] = (Ni, proj)
        return Ni, proj

    def normal_factor(
        self, Rs: dict[int, sp.csr_matrix], train: list[Mask], drift: bool, cacheable: bool
    ) -> tuple[Any, dict[int, Any]]:
        """Cholesky factor of the ridged normal matrix (training rows) and drift projections."""
        p = self.n_theta
        N = np.zeros((p, p))
        projs = {}
        for i, R in Rs.items():
            Ni, proj = self._normal(i, R, train[i], drift, cacheable)
            N += Ni
            projs[i] = proj
        lam = self.ridge * max(float(np.trace(N)) / p, 1e-300)
        N[np.diag_indices(p)] += lam
        return (linalg.cho_factor(N), lam), projs

    def solve_theta(
        self,
        Rs: dict[int, sp.csr_matrix],
        targets: dict[int, Array],
        train: list[Mask],
        drift: bool,
        cacheable: bool,
        factor: Any = None,
    ) -> Array:
        """Least-squares Preisach weights for ``targets`` (V) on the ``train`` rows.

        A small ridge toward the given model keeps weights that no training sample constrains.
        ``factor`` (from :meth:`normal_factor`) may be given to reuse a factorisation; with the
        factor of other regressors the solution is approximate (used inside optimisations).
        """
        if factor is None:
            factor = self.normal_factor(Rs, train, drift, cacheable)
        (cho, lam), projs = factor
        rhs = lam * self.theta0
        for i, R in Rs.items():
            m = train[i]
            t = np.where(m, targets[i], 0.0)
            proj = projs.get(i)
            if proj is not None:
                A, Ginv = proj
                tm = t[m]
                t[m] = tm - A @ (Ginv @ (A.T @ tm))
            rhs = rhs + R.T @ t
        return np.asarray(linalg.cho_solve(cho, rhs), dtype=float)

    def linearised_targets(
        self,
        effects: Sequence[FittedEffect],
        base: Base,
        train: list[Mask],
        feedback_from: dict[int, Array] | None = None,
    ) -> tuple[dict[int, sp.csr_matrix], dict[int, Array], bool]:
        """Regressors and targets ``y - (Out(P) - P)`` about ``base`` (training recordings).

        ``feedback_from`` gives the signals a feedback effect is driven by (see :meth:`stage`).
        """
        moved = any(e.cand.side in ("input", "feedback") for e in effects)
        outs = [e for e in effects if e.cand.side == "output"]
        Rs, targets = {}, {}
        for i, r in enumerate(self.recs):
            if not train[i].any():
                continue
            P, ue, st = self.stage(
                i, base, effects, None if feedback_from is None else feedback_from[i]
            )
            Rs[i] = self.regressor(i, ue if moved else None, base)
            targets[i] = r.y - (self.output_side(i, P, outs, st) - P) if outs else r.y
        return Rs, targets, not moved

    def refit_base(
        self,
        effects: Sequence[FittedEffect],
        base: Base,
        train: list[Mask],
        drift: bool,
        choose: bool = True,
    ) -> Base:
        """Least-squares Preisach weights for ``effects`` on the ``train`` samples.

        The output blocks are linearised about ``base``: the target is ``y - (Out(P) - P)``
        with ``P`` the Preisach output of ``base``.  With ``choose`` the unknown initial
        states are then re-chosen for the refitted chain (:meth:`choose_states`) and, while
        one changes, the weights are solved again for the new states - up to
        :data:`BASE_ROUNDS` solves, so that the base a candidate must beat has had at least
        as many rounds of weights and states as a candidate's fit (:meth:`fit_profiled`).
        With at most two solves, on blind seed 42's thermal warm-up every candidate gained
        16-19 % at step 1 (a 1-parameter delay that fitted no delay among them): the gain of
        the further rounds, credited to the candidate.
        """
        Rs, targets, cacheable = self.linearised_targets(effects, base, train)
        new = Base(self.solve_theta(Rs, targets, train, drift, cacheable), states=base.states)
        if not choose:
            return new
        for _ in range(BASE_ROUNDS - 1):
            chosen = self.choose_states(Chain(new, list(effects)), drift).base
            if chosen is new:
                break
            Rs, targets, cacheable = self.linearised_targets(effects, chosen, train)
            new = Base(self.solve_theta(Rs, targets, train, drift, cacheable), states=chosen.states)
        return new

    # -- unknown initial states: a nuisance parameter profiled for every chain -----------------
    def choose_states(self, chain: Chain, drift: bool = False) -> Chain:
        """Re-choose every unknown initial state for ``chain`` by least squares.

        An unknown initial state is a nuisance parameter of the model it is simulated with.
        The history chosen once with the given model (in
        :func:`~preisach.diagnose.data.prepare_recordings`) suits that model's errors, and
        can be far off for a candidate's refitted weights: on a recording that repeats one
        loop the weights are determined only along that loop, and a history with turning
        points elsewhere reads weights no sample constrains (on the yan9a recordings the
        held-out error of an input lag went from 231 to 564 mV that way, all of it before the
        first extreme).  So every fitted chain gets, per recording, the history of the same
        kind (:class:`~preisach.diagnose.data.History`: within the recording's own range, or
        from a saturation, or anhysteretic) that fits it best over the usable samples (with a
        drift projected off when ``drift``).  Like the first choice, this uses each
        recording's measured output: one discrete choice per recording.  The state the
        previous recording left (:func:`~preisach.diagnose.data.session_history`) counts as
        of the kind within the range (neither has a free offset).  The kind stays: it
        sets the relays the input never reaches, i.e. an output offset per recording, which
        chosen with held-out samples would take a sensor drift's place.

        Returns ``chain`` itself when no history changes, else a chain with a new
        :class:`Base` (same weights) holding the chosen histories.
        """
        todo = [i for i, r in enumerate(self.recs) if r.history is not None]
        if not todo:
            return chain
        base = chain.base
        changed = {}
        for i in todo:
            h = self._best_history(i, chain, drift)
            if h is not self.history(i, base):
                changed[i] = h
        if not changed:
            return chain
        cache = {j: v for j, v in base.cache.items() if j not in changed}
        return Chain(Base(base.theta, base.table, cache, {**base.states, **changed}), chain.effects)

    def _best_history(self, i: int, chain: Chain, drift: bool) -> History:
        """Return the input history before recording ``i`` that fits ``chain`` best.

        The relays see the same input for every history (after the input blocks; with a
        feedback effect, the input shifted by the feedback of the measured output, see
        :meth:`_relays_estimate`), so the states are simulated together
        and only until that input has visited its extremes: from then on they differ only in
        relays the input never reaches again, so the outputs differ by a constant.
        """
        r = self.recs[i]
        base = chain.base
        effects = chain.effects
        table = self.table(base)
        ins = [e for e in effects if e.cand.side == "input"]
        fb = [e for e in effects if e.cand.side == "feedback"]
        outs = [e for e in effects if e.cand.side == "output"]
        u = self.preisach_input(i, ins) if ins else r.u
        # with a feedback effect, as in stage(): the input shifted by the feedback of the
        # measured output
        ue = self._relays_estimate(i, base, u, fb[-1]) if fb else u
        st = Stage(i, u, table)
        cur = self.history(i, base)
        assert cur is not None
        lo, hi = float(ue.min()), float(ue.max())
        # the state the previous recording left has no free parameter: it competes with the
        # histories within the recording's own range (one kind of uncharged history), and
        # with those of a charged kind too (it replaces their free offset by none)
        first = r.history
        assert first is not None
        within = first.kind in ("range", "session")
        hists, states = self._history_options(
            i, ue, cur, "range" if within else first.kind, fb[-1] if fb else None
        )
        P_ref = _core.simulate(table, ue, states[0], "clamp")[0]
        kw = 1 + max(int(np.argmax(ue >= hi)), int(np.argmax(ue <= lo)))
        pre = np.ascontiguousarray(np.broadcast_to(ue[:kw], (len(states), kw)))
        P_pre = _core.simulate_batch(table, pre, states, "clamp")[0]
        shift = P_pre[:, -1] - P_ref[kw - 1]
        m = r.usable
        # the output blocks linearised about the current state's output (as in refit_base):
        # the Preisach-level target; exact for a chain without output blocks
        target = r.y - (self.output_side(i, P_ref, outs, st) - P_ref) if outs else r.y
        # residual e - d with d = P_state - P_ref: the prefix exactly, a constant after it
        head = m[:kw]
        d = P_pre[:, head]  # only the usable columns (the same values as squaring them all)
        np.subtract(target[:kw][head], d, out=d)
        np.square(d, out=d)
        sse = d.sum(axis=1)
        tail = m.copy()
        tail[:kw] = False
        et = (target - P_ref)[tail]
        sse = sse + float(et @ et) - 2.0 * shift * float(et.sum()) + shift**2 * et.size
        if outs or drift:  # the few best again, exactly (output blocks, drift projected off)
            A = Ginv = None
            if drift:
                A = self.drift_basis(i)[m]
                Ginv = np.linalg.inv(self._drift_system(A)[0])
            top = {0, *np.argsort(sse)[:5].tolist()}
            exact = np.full(len(states), np.inf)
            for k in top:
                P = P_ref + shift[k]
                P[:kw] = P_pre[k]
                y = self.output_side(i, P, outs, st) if outs else P
                res = (r.y - y)[m]
                if A is not None and Ginv is not None:
                    res = res - A @ (Ginv @ (A.T @ res))
                exact[k] = float(res @ res)
            sse = exact
        k_best = int(np.argmin(sse))
        # keep the current history unless another fits clearly better (no churn on ties)
        if sse[k_best] >= sse[0] - 1e-9 * max(float(sse[0]), 1e-300):
            return cur
        return hists[k_best]

    def _history_options(
        self, i: int, ue: Array, cur: History, kind: str, fb: FittedEffect | None = None
    ) -> tuple[list[History], list[Any]]:
        """Return the histories ``_best_history`` chooses from (``cur`` first), and their states.

        For the recording's own input (no input or feedback effect: most chains) the options
        and their states are made once and kept: the same objects every time, so a history
        chosen again keeps its regressor cached (:meth:`regressor` keys on its identity).
        ``fb``: the feedback effect that shifts ``ue`` (:meth:`session_left`).
        """
        r = self.recs[i]
        left = self.session_left(i, fb) if fb is not None and r.session is not None else None
        hit = self._options.get((i, kind)) if ue is r.u else None
        if hit is None:
            opts = state_options(self.model, ue, kind)
            if r.session is not None:
                opts.append(r.session)
            hit = (opts, {id(h): h.state(ue, left) for h in opts})
            if ue is r.u:
                self._options[(i, kind)] = hit
        opts, st = hit
        # as many entries as built afresh: an option equal to ``cur`` stays (it did as a new
        # object), the session's state only once
        hists = [cur, *(h for h in opts if not (h is r.session and h is cur))]
        states = [st[id(h)] if id(h) in st else h.state(ue, left) for h in hists]
        return hists, states

    # -- drift: a smooth function of time per recording ------------------------------------
    def drift_basis(self, i: int) -> Array:
        """Cubic B-spline basis in time of recording ``i`` (knots every :meth:`spacing_of`)."""
        if i not in self._basis:
            r = self.recs[i]
            self._basis[i] = drift_mod.bspline_basis(r.t, self.spacing_of(i))
        return self._basis[i]

    def spacing_of(self, i: int) -> float:
        """Knot spacing (s) of recording ``i``'s drift: chosen, else the default."""
        return self.drift_spacing.get(i, self.drift_knot_spacing)

    def choose_drift_roughness(self) -> dict[int, float]:
        """Choose every diagnosis recording's drift knot spacing by held-out time blocks.

        On the residual of the base (refitted on all usable samples with the finest drift
        projected off when the weights are refitted, else the given model) the drift curve
        fitted on each recording's blocks of one parity predicts the other parity, for knot
        spacings from one interval per recording down to :data:`.drift.MIN_SPACING` and
        penalty weights :data:`.drift.SMOOTHINGS` (one weight for all recordings, which sets
        :attr:`drift_smoothing`; :func:`.drift.choose_roughness`).
        Called once before a drift is fitted; returns the spacings (s) per recording.
        """
        if self.drift_spacing:
            return self.drift_spacing
        train = [r.usable for r in self.recs]
        chain = Chain(self.given)
        if self.refit:  # weights refitted with the finest drift projected off, so that
            # they do not absorb the drift the spacing is chosen for
            self.drift_spacing = {
                i: drift_mod.spacing_options(float(r.t[-1] - r.t[0]))[-1]
                for i, r in enumerate(self.recs)
            }
            self._basis.clear()
            chain = Chain(self.refit_base([], self.given, train, True))
        recs = [self.recs[i] for i in self.diag]
        lam, spacings, _ = drift_mod.choose_roughness(
            [
                (r.t, r.y - self.predict_one(i, chain), r.usable, r.fold)
                for i, r in zip(self.diag, recs)
            ]
        )
        self.drift_smoothing = lam
        chosen = dict(zip(self.diag, spacings))
        self.drift_spacing = chosen
        self._basis.clear()
        if self.refit:  # normal matrices with the old drift projections are stale
            self._normal_cache = {k: v for k, v in self._normal_cache.items() if not k[3]}
        return chosen

    def _drift_system(self, A: Array) -> tuple[Array, float]:
        """Penalised normal matrix of a P-spline (first differences of the coefficients)."""
        return drift_mod.penalised_system(A, self.drift_smoothing)

    def drift_fit(self, i: int, res: Array, mask: Mask) -> Array:
        """P-spline coefficients of the drift of recording ``i`` fitted to ``res[mask]``."""
        B = self.drift_basis(i)
        A = B[mask]
        if A.shape[0] == 0:
            return np.zeros(B.shape[1])
        G, _ = self._drift_system(A)
        return np.asarray(np.linalg.solve(G, A.T @ res[mask]), dtype=float)

    def drift_dof(self) -> float:
        """Effective number of drift parameters (trace of the smoother, diagnosis recordings)."""
        return float(
            sum(self._drift_system(self.drift_basis(i)[self.recs[i].usable])[1] for i in self.diag)
        )

    def drift_step_share(self, chain: Chain) -> float:
        """Share of the fitted drift curves' variance that follows the model output's moves.

        Per diagnosis recording the drift P-spline is fitted to the chain's residual on the
        usable samples; the curve is regressed (least squares, per-recording means removed)
        on slow responses to the chain's output ``P``: ``lag_tau(P) - P`` for first-order lags
        with time constants log-spaced from 0.05 s to a fifth of the recording (responses that
        settle within it; slower ones could build any trend).  A sensor drift has nothing to
        do with those; creep is made of them.
        """
        num = den = 0.0
        for i in self.diag:
            r = self.recs[i]
            m = r.usable
            p = self.predict_one(i, chain)
            d = (self.drift_basis(i) @ self.drift_fit(i, r.y - p, m))[m]
            d = d - d.mean()
            T = max(float(r.t[-1] - r.t[0]), 1e-9)
            taus = np.geomspace(max(0.05, 5 * r.dt), max(T / 5, 0.1), 6)
            cols = []
            for tau in taus:
                pole = math.exp(-r.dt / tau)
                g = signal_lag(p, pole) - p
                g = g[m]
                cols.append(g - g.mean())
            G = np.stack(cols, axis=1)
            coef, *_ = np.linalg.lstsq(G, d, rcond=None)
            fit = G @ coef
            num += float(d @ d - (d - fit) @ (d - fit))
            den += float(d @ d)
        return num / den if den > 0 else 0.0

    def drift_heldout(self, i: int, res: Array, test: Mask) -> Array:
        """Drift predicted on the ``test`` samples, fitted on the other-parity usable samples.

        The drift is a per-recording nuisance (a sensor's offset wanders differently in every
        run), so it cannot be carried over from other recordings.  Its curve at a held-out
        sample of block parity ``p`` is fitted on the same recording's samples of the other
        parity: no sample is predicted by a drift fitted on it.  Under ``cv="blocks"`` those
        samples are training samples.  Under ``cv="recordings"`` they belong to the held-out
        recording itself - the one exception to "held-out recordings are never used for
        fitting": the chain (base weights and effects) comes from the other recordings, only
        this recording's drift curve comes from its other blocks.
        """
        r = self.recs[i]
        out = np.zeros(r.n)
        B = self.drift_basis(i)
        for p in (0, 1):
            ev = test & (r.fold == p)
            if not ev.any():
                continue
            c = self.drift_fit(i, res, r.usable & (r.fold != p))
            out[ev] = B[ev] @ c
        return out

    # -- chain evaluation -----------------------------------------------------------------
    def preisach_input(self, i: int, effects: Sequence[FittedEffect]) -> Array:
        """Return the input (V) of recording ``i`` after the input-side ``effects``, clamped.

        The blocks start in the state that steady motion at the recording's initial rate
        leaves them in (:meth:`lead_in`), not at rest: a recording that starts mid-sweep
        has its relays behind the input already (an input lag of 30 ms on a 1 Hz, 3.6 V
        sine put the first relay input 0.3 V too high when started at rest, 3.8 V of output
        error at the first sample of the yan9a recordings).
        """
        r = self.recs[i]
        ins = [e for e in effects if e.cand.side == "input"]
        if not ins:
            return np.clip(r.u, self.model.u_min, self.model.u_max)
        pre = self.lead_in(i)
        x = np.concatenate([pre, r.u])
        for e in ins:
            b = e.cand.block(e.x, r.dt)
            b.reset(float(x[0]))
            x = b.run(x)
        return np.asarray(np.clip(x[pre.size :], self.model.u_min, self.model.u_max), dtype=float)

    def lead_in(self, i: int) -> Array:
        """Input (V) assumed before recording ``i``: steady motion at its initial rate.

        ``5 max_delay`` long (the input blocks' time constants are at most ``max_delay``), at
        the median rate of the first four sample steps (a recording that starts with a step
        and then holds gets rate 0: at rest).
        """
        r = self.recs[i]
        n = int(min(max(r.n - 1, 1), math.ceil(5.0 * self.max_delay / r.dt)))
        d = np.diff(r.u[: min(r.n, 5)])
        step = float(np.median(d)) if d.size else 0.0
        return float(r.u[0]) - step * np.arange(n, 0, -1, dtype=float)

    def stage(
        self,
        i: int,
        base: Base,
        effects: Sequence[FittedEffect],
        feedback_from: Array | None = None,
    ) -> tuple[Array, Array, Stage]:
        """Run the Preisach operator of ``base`` with the input and feedback ``effects``.

        With a feedback effect the loop is closed through the simulated output, unless
        ``feedback_from`` (V, one value per sample) is given: the relays then see the input
        shifted by the feedback of that signal's previous sample (series-parallel form, used to
        fit the feedback with the measured output, see :class:`~preisach.diagnose.problem.Problem`).

        Returns the Preisach output (V), the input the relays saw (V, for the regressor) and
        the :class:`Stage` for output blocks that need the input.
        """
        r = self.recs[i]
        ins = [e for e in effects if e.cand.side == "input"]
        fb = [e for e in effects if e.cand.side == "feedback"]
        table = self.table(base)
        u = self.preisach_input(i, ins) if ins else r.u
        if fb:
            if feedback_from is None:
                blk = cast(OutputFeedback, fb[-1].cand.block(fb[-1].x, r.dt))
                # an unknown initial state is built on the relays' own input range, which the
                # feedback moves and the closed loop gives only once simulated from that state:
                # it is taken from the input shifted by the feedback of the measured output
                # (the series-parallel form the feedback is fitted in; iterating the closed
                # loop instead locked it into other periodic solutions on the yan9a data)
                x = self._relays_estimate(i, base, u, fb[-1])
                y, ue, _ = blk.simulate(table, u, self.state(i, base, x, fb[-1]))
            else:
                ue = self._fed_back(i, u, fb[-1], feedback_from)
                y = self.preisach(i, base, ue, fb[-1])
            return y, ue, Stage(i, u, table)
        y = self.preisach(i, base, u if ins else None)
        return y, u, Stage(i, u, table)

    def _relays_estimate(self, i: int, base: Base, u: Array, fb: FittedEffect) -> Array:
        """Return the input (V) a feedback loop's relays see, to build an unknown initial state.

        The input shifted by the feedback of the measured output (the series-parallel form
        the feedback is fitted in); ``u`` when the initial state is known.
        """
        if self.history(i, base) is None:
            return u
        return self._fed_back(i, u, fb, self.recs[i].y)

    def _fed_back(
        self, i: int, u: Array, fb: FittedEffect, feedback_from: Array, prev: Array | None = None
    ) -> Array:
        """Return the relays' input (V): ``u`` plus the feedback of the previous sample.

        ``prev``: :meth:`previous` of ``feedback_from`` when the caller keeps it.
        """
        blk = fb.cand.block(fb.x, self.recs[i].dt)
        if prev is None:
            prev = self.previous(feedback_from)
        return np.clip(u + blk.run(prev), self.model.u_min, self.model.u_max)

    @staticmethod
    def previous(signal: Array) -> Array:
        """``signal`` one sample late (its first sample repeated): what a feedback acts on."""
        return np.concatenate([signal[:1], signal[:-1]])

    def relay_input(
        self, i: int, effects: Sequence[FittedEffect], feedback_from: Array | None
    ) -> Array | None:
        """Return the input (V) the relays see, when it follows without simulating them.

        That is without a feedback effect, or with one driven by ``feedback_from``; None when
        the feedback loop must be closed through the simulated output (use :meth:`stage`).
        """
        ins = [e for e in effects if e.cand.side == "input"]
        fb = [e for e in effects if e.cand.side == "feedback"]
        u = self.preisach_input(i, ins) if ins else self.recs[i].u
        if not fb:
            return u
        if feedback_from is None:
            return None
        return self._fed_back(i, u, fb[-1], feedback_from)

    def anhysteretic(self, stage: Stage) -> Array:
        """Anhysteretic curve ``A(u)`` of the stage's table at its input (V), cached."""
        key = (id(stage.table), stage.i, stage.u.ctypes.data, stage.u.size)
        hit = self._anh.get(key)
        if hit is None or hit[0] is not stage.table or hit[2] is not stage.u:
            grid = np.linspace(self.model.u_min, self.model.u_max, 401)
            loc = np.asarray(_core.neutral_locus(stage.table, grid))
            hit = (stage.table, np.interp(stage.u, grid, loc), stage.u)
            if len(self._anh) > 64:
                self._anh.clear()
            self._anh[key] = hit
        return hit[1]

    def predict_one(self, i: int, chain: Chain) -> Array:
        """Prediction (V) of recording ``i`` by ``chain`` (no drift)."""
        y, _, st = self.stage(i, chain.base, chain.effects)
        return self.output_side(i, y, [e for e in chain.effects if e.cand.side == "output"], st)

    def output_side(self, i: int, y: Array, effects: Sequence[FittedEffect], stage: Stage) -> Array:
        """Apply the output-side ``effects`` in chain order to the Preisach output ``y`` (V)."""
        r = self.recs[i]
        for e in sorted(effects, key=lambda e: e.cand.order):
            y = e.cand.apply(e.x, y, r.dt, stage, self)
        return y

    def predict(self, chain: Chain) -> list[Array]:
        """Predictions of every recording (no drift)."""
        return [self.predict_one(i, chain) for i in range(len(self.recs))]

    # -- fitting --------------------------------------------------------------------------
    def grid_search(self, cand: Candidate, starts: list[Array], top: int = 1) -> list[Array]:
        """Return the ``top`` start vectors with the smallest training SSE (used by candidates)."""
        prob = self._problem
        if prob is None or not starts:
            return starts[:top]
        sse = prob.sse_many([prob.clip(s) for s in starts], coarse=True)
        order = np.argsort(sse)
        return [prob.clip(starts[k]) for k in order[:top]]

    def _fit_params(
        self,
        cand: Candidate,
        fixed: Chain,
        train: list[Mask],
        drift: bool,
        starts: list[Array] | None,
        profile: bool = False,
        reference: FittedEffect | None = None,
    ) -> FittedEffect:
        from .problem import Problem

        prob = Problem(self, cand, fixed, train, drift, profile=profile, reference=reference)
        self._last_problem = prob
        if starts is None:
            self._problem = prob
            try:
                starts = cand.starts(self)
            finally:
                self._problem = None
        best: Any = None
        # starts that give the same model (the same training residuals to 1e-9 of their
        # largest, e.g. a feedback scan's zero gain found at every zero level: its zero level
        # then does nothing) are optimised once, from the first of them: on the six-recording
        # benchmark the feedback candidate spent 2/3 of its optimiser time on three such starts
        seen: list[Array] = []
        last: dict[bytes, Array] = {}

        def fun(x: Array) -> Array:
            key = np.asarray(x, float).tobytes()
            if key in last:  # the start, evaluated once for the comparison
                return last.pop(key).copy()
            return prob.residuals(x)

        for s in starts:
            x0 = prob.clip(s)
            r0 = prob.residuals(x0)
            tol = 1e-9 * float(np.max(np.abs(r0))) if r0.size else 0.0
            if any(q.shape == r0.shape and float(np.max(np.abs(q - r0))) <= tol for q in seen):
                continue
            seen.append(r0)
            last.clear()
            last[np.asarray(x0, float).tobytes()] = r0
            budget = 20 if cand.side != "output" else 30  # input-side evaluations re-run the relays
            res = optimize.least_squares(
                fun,
                x0,
                bounds=(prob.lo, prob.hi),
                x_scale=prob.scale,
                diff_step=1e-3,
                method="trf",
                ftol=1e-6,
                xtol=1e-6,
                max_nfev=budget * max(1, x0.size),
            )
            if best is None or res.cost < best.cost:
                best = res
        return FittedEffect(cand, np.asarray(best.x, float))

    def fit(
        self,
        cand: Candidate,
        fixed: Chain,
        train: list[Mask],
        drift: bool = False,
        starts: Sequence[Array] | None = None,
    ) -> Chain:
        """Fit ``cand`` on the ``train`` samples after the ``fixed`` chain; returns the new chain.

        With ``drift`` every recording's residual is also freed of a smooth drift (fitted
        jointly by projection).  With a refitted base, the Preisach weights are profiled out:
        every evaluation re-solves them by least squares for the candidate's parameters, with
        the blocks linearised about a reference base that is updated ``alternations`` times.
        ``starts``: parameter vectors to start the optimiser from instead of the candidate's
        own (the selection folds' fits, for a final fit that must find the mode they found); a
        family solved by its own least squares has none and ignores them.
        """
        if hasattr(cand, "fit_chain"):  # a family solved by its own least squares
            return cast(Chain, cand.fit_chain(self, fixed, train, drift))
        return self.fit_profiled(cand, fixed, train, drift, starts)

    def fit_profiled(
        self,
        cand: Candidate,
        fixed: Chain,
        train: list[Mask],
        drift: bool = False,
        starts: Sequence[Array] | None = None,
    ) -> Chain:
        """Fit ``cand`` by the optimiser as :meth:`fit` does (also for a ``fit_chain``)."""
        starts = None if starts is None else list(starts)  # the first fit's; then its optimum
        if not self.refits(fixed):
            chain = fixed.plus(self._fit_params(cand, fixed, train, drift, starts, profile=False))
            chosen = self.choose_states(chain, drift)
            if chosen is chain:
                return chain
            # the initial states changed: fit again from there with the new states
            again = self._fit_params(
                cand, Chain(chosen.base, fixed.effects), train, drift, [chain.effects[-1].x]
            )
            return self.choose_states(Chain(chosen.base, fixed.effects).plus(again), drift)
        ref = fixed.base
        eff: FittedEffect | None = None
        prob = None
        for _ in range(max(1, self.alternations)):
            eff = self._fit_params(
                cand, Chain(ref, fixed.effects), train, drift, starts, profile=True, reference=eff
            )
            prob = self._last_problem
            ref = Base(prob.theta(eff.x), states=ref.states)
            # the unknown initial states are re-chosen for the candidate's chain (a nuisance
            # parameter of every model, see choose_states); the next alternation fits with them
            ref = self.choose_states(Chain(ref, [*fixed.effects, eff]), drift).base
            starts = [eff.x]
        assert eff is not None and prob is not None
        if ref.states != prob.fixed.base.states:  # weights for the states chosen last
            from .problem import Problem

            last = Problem(
                self, cand, Chain(ref, fixed.effects), train, drift, profile=True, reference=eff
            )
            ref = Base(last.theta(eff.x), states=ref.states)
        return fixed.plus(eff, ref)

    def refits(self, fixed: Chain) -> bool:
        """Whether a candidate after ``fixed`` is fitted with the Preisach weights refitted.

        Not after a feedback effect: the weights were fitted with it in series-parallel form
        (the relays driven by the measured output), which a further refit with the loop
        closed through the simulated output cannot reproduce - on the yan9a recordings such
        refits moved the weights by up to 70 % and the closed-loop predictions diverged.
        """
        return self.refit and not any(e.cand.side == "feedback" for e in fixed.effects)

    def covariance(self, chain: Chain, train: list[Mask], drift: bool = False) -> Array | None:
        """Block-clustered sandwich covariance of the last effect's parameters at the optimum."""
        eff = chain.effects[-1]
        fit_context = getattr(eff.cand, "fit_context", None)
        if fit_context is not None and fit_context(self) is not self:  # fitted on another grid
            return cast("Context", fit_context(self)).covariance(chain, train, drift)
        from .problem import Problem

        # with a refitted base the weights are profiled out, so their trade-off with the
        # effect's parameters is in the Jacobian
        prob = Problem(
            self,
            eff.cand,
            Chain(chain.base, chain.effects[:-1]),
            train,
            drift,
            profile=self.refits(Chain(chain.base, chain.effects[:-1])),
            reference=eff,
        )
        x = eff.x
        r0 = prob.residuals(x)
        J = np.empty((r0.size, x.size))
        for k in range(x.size):
            h = 1e-4 * max(abs(x[k]), prob.scale[k])
            lo, hi = max(x[k] - h, prob.lo[k]), min(x[k] + h, prob.hi[k])
            xp, xm = x.copy(), x.copy()
            xp[k], xm[k] = hi, lo
            J[:, k] = (prob.residuals(xp) - prob.residuals(xm)) / max(hi - lo, 1e-300)
        bread = np.linalg.pinv(J.T @ J)
        n = prob.blocks.size  # data rows; a candidate's penalty rows follow them
        g = J[:n] * r0[:n, None]
        _, inv = np.unique(prob.blocks, return_inverse=True)
        S = np.zeros((int(inv.max()) + 1 if inv.size else 0, x.size))
        np.add.at(S, inv, g)
        return bread @ (S.T @ S) @ bread


_POOL: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    """Threads for the per-recording work of a fit (one per core, made once)."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=os.cpu_count() or 1, thread_name_prefix="diagnose")
    return _POOL
