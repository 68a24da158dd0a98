"""The diagnosis engine: prepare recordings, fit candidates, score them on held-out data.

Procedure (see :func:`preisach.diagnose.diagnose` for the user-facing description):

1. Every recording is simulated from its initial state (negative or positive saturation when
   it starts there, else the anhysteretic state with a burn-in that masks the samples until
   the input has visited both its extremes).  Identification recordings (the data the model
   was identified from) are training data only, never scored.
2. The measurement noise is estimated from the data: the robust standard deviation of the
   third differences of the residual (white noise and quantisation pass them, smooth model
   errors do not).
3. Cross-validation folds: alternating time blocks of every recording (``cv="blocks"``, the
   default: every experiment type is in both the training and the held-out data, so an
   effect whose evidence sits in one experiment - ringing after steps - can be learnt), or
   groups of whole recordings held out (``cv="recordings"``: stricter, an effect must carry
   over to experiments it was not fitted on).
4. The base model is either the given one, or - when identification recordings are given -
   refitted on every fold's training data together with the candidate: its Everett table
   on a grid of levels is linear in the output (``preisach._core.regressor_rows``), so it is
   re-solved by least squares for the candidate's current blocks (the sweep carries the
   effect, so the identified model has absorbed part of it; refitting undoes that).
   The weights are profiled out of every evaluation of the candidate's parameters (blocks
   linearised about a reference base that is updated twice).  Once a feedback effect is
   kept, later candidates keep the weights it was fitted with (:meth:`Context.refits`).
5. Greedy forward selection.  In each step every remaining candidate is fitted on each
   fold's training samples (with the effects kept so far) and predicts the held-out ones;
   the pooled held-out residual scores it.  A candidate may be kept only if it lowers the
   held-out RMSE by at least ``min_gain``, explains at least ``noise_factor`` times the noise
   variance and wins a one-sided sign-flip test over held-out blocks at level ``alpha``.
   Of those, the one with the lowest held-out error is kept - unless one with fewer
   parameters is not significantly worse on the held-out blocks (sign-flip test at
   ``tie_alpha``), which is then preferred (parsimony among explanations the data cannot tell
   apart; the held-out scoring itself already charges for over-fitting, so no information
   criterion is added: the number of parameters matters only through this preference).
   Selection stops
   when nothing qualifies; candidates that lowered the held-out error by less than
   ``retry_gain`` (2 %) in a step are not tried again in the next.
6. The kept effects are refitted on all usable samples; parameter uncertainties come from the
   Jacobian at the optimum with a block-clustered (sandwich) covariance, which allows for
   the residual's autocorrelation.
"""

from __future__ import annotations

import math
import os
import time as _time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, cast

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy import interpolate, linalg, optimize

from .. import _core
from ..model import PreisachModel, State
from ..recording import Recording
from .blocks import OutputFeedback
from .candidates import Candidate, DriftCandidate

__all__ = [
    "Base",
    "Chain",
    "Context",
    "FittedEffect",
    "Fold",
    "Score",
    "StepResult",
    "heldout_score",
    "make_folds",
    "noise_sigma",
    "prepare_recordings",
    "run_selection",
]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


# ----------------------------------------------------------------------------------------
# recordings
# ----------------------------------------------------------------------------------------
@dataclass
class Rec:
    """A recording prepared for diagnosis."""

    name: str
    t: Array
    u: Array
    y: Array
    dt: float
    state0: State
    usable: Mask
    block: NDArray[np.int64]
    fold: NDArray[np.int64]
    start: str
    ident: bool = False

    @property
    def n(self) -> int:
        return int(self.u.size)


def _rec_name(rec: Recording, i: int) -> str:
    for key in ("name", "experiment"):
        v = rec.metadata.get(key)
        if isinstance(v, str) and v:
            return v
    return f"recording {i}"


def _burn_in(u: Array, tol: float) -> int:
    """Return the number of samples to skip when the initial state is unknown.

    Once the input has visited its maximum and its minimum the Preisach state no longer
    depends on the unknown start; a block acting before the relays (a lag, a play) may still
    carry the start a little further, so the burn-in runs to the next visit of the first
    extreme (max -> min -> max, or min -> max -> min), or, if there is none, 5 % of the
    recording beyond the second extreme.
    """
    at_hi, at_lo = u >= u.max() - tol, u <= u.min() + tol
    i_hi, i_lo = int(np.argmax(at_hi)), int(np.argmax(at_lo))
    second = max(i_hi, i_lo)
    again = np.flatnonzero((at_hi if i_hi < i_lo else at_lo)[second:])
    if again.size:
        return second + int(again[0])
    return min(u.size, second + max(1, u.size // 20))


def prepare_recordings(
    model: PreisachModel,
    recordings: Sequence[Recording],
    *,
    initial_states: Sequence[State | str | None] | None = None,
    block_length: float | None = None,
    identification: Sequence[Recording] = (),
) -> list[Rec]:
    """Prepare the recordings: initial states, burn-in masks, time blocks and fold parities.

    Identification recordings come last in the returned list, flagged ``ident``.
    """
    if not recordings:
        raise ValueError("recordings: need at least one recording to diagnose")
    if initial_states is not None and len(initial_states) != len(recordings):
        raise ValueError(
            f"initial_states: expected {len(recordings)} entries (one per recording), "
            f"got {len(initial_states)}"
        )
    span = model.u_max - model.u_min
    tol = 0.01 * span
    durations = [float(r.t[-1] - r.t[0]) if len(r.t) > 1 else 0.0 for r in recordings]
    if block_length is None:
        block_length = float(np.clip(max(durations) / 10.0, 0.25, 2.0))
    if not block_length > 0:
        raise ValueError(f"block_length: must be positive, got {block_length}")
    out: list[Rec] = []
    next_block = 0
    all_recs = [(r, False) for r in recordings] + [(r, True) for r in identification]
    for i, (r, ident) in enumerate(all_recs):
        name = _rec_name(r, i)
        if ident:
            name = f"identification: {name}"
        if len(r.t) < 20:
            raise ValueError(
                f"recording {name!r}: too short ({len(r.t)} samples; need at least 20)"
            )
        dt = float(np.median(np.diff(r.t)))
        u = np.clip(r.u, model.u_min, model.u_max)
        spec = None if (initial_states is None or ident) else initial_states[i]
        if spec is None:
            meta = r.metadata.get("initial_state")
            spec = meta if isinstance(meta, str) else None
        if spec is None:
            if u[0] <= model.u_min + tol:
                spec = "negative_saturation"
            elif u[0] >= model.u_max - tol:
                spec = "positive_saturation"
            else:
                spec = "unknown"
        usable = np.ones(u.size, bool)
        if isinstance(spec, State):
            s0, start = spec, "given"
        elif spec == "negative_saturation":
            s0, start = model.negative_saturation(), spec
        elif spec == "positive_saturation":
            s0, start = model.positive_saturation(), spec
        elif spec in ("anhysteretic", "unknown"):
            s0, start = model.anhysteretic_state(), spec
            if spec == "unknown":
                usable[: _burn_in(u, tol)] = False
        else:
            raise ValueError(
                f"initial state of {name!r}: expected a State or one of "
                f"'negative_saturation', 'positive_saturation', 'anhysteretic', 'unknown'; "
                f"got {spec!r}"
            )
        if usable.sum() < 20:
            raise ValueError(
                f"recording {name!r}: fewer than 20 usable samples after the burn-in "
                "(the input must visit its maximum and minimum to fix the unknown initial state)"
            )
        blk = np.floor((r.t - r.t[0]) / block_length).astype(np.int64) + next_block
        next_block = int(blk[-1]) + 1
        out.append(
            Rec(
                name,
                np.asarray(r.t, float),
                u,
                np.asarray(r.y, float),
                dt,
                s0,
                usable,
                blk,
                (blk % 2).astype(np.int64),
                start,
                ident,
            )
        )
    return out


def noise_sigma(residual: Array) -> float:
    """Robust noise standard deviation (V) from third differences of a residual."""
    d = np.diff(residual, 3)
    if d.size < 10:
        return float("nan")
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / math.sqrt(20.0))


# ----------------------------------------------------------------------------------------
# fitted effects, base models, chains
# ----------------------------------------------------------------------------------------
@dataclass
class FittedEffect:
    """A candidate with fitted parameters."""

    cand: Candidate
    x: Array
    cov: Array | None = None


@dataclass
class Base:
    """The Preisach part of a chain: the given model (``theta is None``) or refitted weights."""

    theta: Array | None = None
    table: Any = None
    cache: dict[int, Array] = field(default_factory=dict, repr=False)


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


class Context:
    """Recordings, the base model and helpers shared by the candidates during a diagnosis."""

    def __init__(
        self,
        model: PreisachModel,
        recs: list[Rec],
        *,
        max_fit_samples: int = 30_000,
        max_delay: float | None = None,
        drift_smoothing: float = 0.1,
        refit: bool = False,
        refit_levels: int = 21,
        alternations: int = 2,
    ) -> None:
        self.model = model
        self.recs = recs
        self.diag = [i for i, r in enumerate(recs) if not r.ident]
        self.dt_min = min(r.dt for r in recs)
        self.u_span = model.u_max - model.u_min
        self.y_lo, self.y_hi = model.y_min, model.y_max
        self.y_span = abs(self.y_hi - self.y_lo)
        self.y_centre = 0.5 * (self.y_lo + self.y_hi)
        self.y_half_span = max(0.5 * self.y_span, 1e-12)
        self.longest_duration = max(float(recs[i].t[-1] - recs[i].t[0]) for i in self.diag)
        self.max_delay = float(max_delay) if max_delay is not None else max(0.05, 10 * self.dt_min)
        self.drift_knot_spacing = float(np.clip(self.longest_duration / 6.0, 1.5, 10.0))
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
        self._anh: dict[Any, Any] = {}
        self._problem: _Problem | None = None
        self._last_problem: Any = None
        self.n_evals = 0
        self.refit = bool(refit)
        if self.refit:
            lv = model.levels
            if lv.size > 41:
                lv = np.linspace(model.u_min, model.u_max, int(refit_levels))
            self.levels = lv
            n = lv.size
            self.n_theta = n * (n - 1) // 2 + 1
            a, b = np.meshgrid(lv, lv, indexing="ij")
            e = model.everett(a, np.minimum(a, b))
            self._ii, self._jj = np.tril_indices(n, -1)
            self.theta0 = np.concatenate([e[self._ii, self._jj], [model.y_min]])
            self._R: dict[int, sp.csr_matrix] = {}
            self._normal_cache: dict[tuple[int, bytes, bool], tuple[Any, Any]] = {}

    # -- base model -------------------------------------------------------------------------
    def table(self, base: Base) -> Any:
        """Return the Everett table of ``base`` (the given model's, or built from ``theta``)."""
        if base.theta is None:
            return self.model.table
        if base.table is None:
            n = self.levels.size
            v = np.zeros((n, n))
            v[self._ii, self._jj] = base.theta[:-1]
            base.table = _core.EverettTable(self.levels, v, float(base.theta[-1]))
        return base.table

    def preisach(self, i: int, base: Base, u: Array | None = None) -> Array:
        """Return the Preisach output (V) of recording ``i`` for its input (or ``u``)."""
        r = self.recs[i]
        if u is None:
            if i not in base.cache:
                base.cache[i] = _core.simulate(self.table(base), r.u, r.state0, "clamp")[0]
            return base.cache[i]
        return _core.simulate(self.table(base), u, r.state0, "clamp")[0]

    def regressor(self, i: int, u: Array | None = None) -> sp.csr_matrix:
        """Sparse map from the refit weights ``theta`` to the Preisach output of recording ``i``."""
        r = self.recs[i]
        if u is None and i in self._R:
            return self._R[i]
        indptr, idx, data, _ = _core.regressor_rows(
            self.levels, r.u if u is None else u, r.state0, "clamp"
        )
        R = sp.csr_matrix((data, idx.astype(np.int64), indptr), shape=(r.n, self.n_theta))
        if u is None:
            self._R[i] = R
        return R

    def _normal(
        self, i: int, R: sp.csr_matrix, m: Mask, drift: bool, cacheable: bool
    ) -> tuple[Array, Any]:
        """``R^T R`` over the rows ``m`` (minus the drift projection), and the projection."""
        key = (i, np.packbits(m).tobytes(), drift)
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
        lam = 1e-7 * max(float(np.trace(N)) / p, 1e-300)
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
        return linalg.cho_solve(cho, rhs)

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
            Rs[i] = self.regressor(i, ue) if moved else self.regressor(i)
            targets[i] = r.y - (self.output_side(i, P, outs, st) - P) if outs else r.y
        return Rs, targets, not moved

    def refit_base(
        self, effects: Sequence[FittedEffect], base: Base, train: list[Mask], drift: bool
    ) -> Base:
        """Least-squares Preisach weights for ``effects`` on the ``train`` samples.

        The output blocks are linearised about ``base``: the target is ``y - (Out(P) - P)``
        with ``P`` the Preisach output of ``base``.
        """
        Rs, targets, cacheable = self.linearised_targets(effects, base, train)
        return Base(self.solve_theta(Rs, targets, train, drift, cacheable))

    # -- drift: a smooth function of time per recording ------------------------------------
    def drift_basis(self, i: int) -> Array:
        """Cubic B-spline basis in time of recording ``i``, knots every ``drift_knot_spacing``."""
        if i not in self._basis:
            r = self.recs[i]
            t = r.t - r.t[0]
            T = max(float(t[-1]), 1e-9)
            n_int = max(1, int(math.ceil(T / self.drift_knot_spacing)))
            inner = np.linspace(0.0, T, n_int + 1)
            k = 3
            knots = np.concatenate([[0.0] * k, inner, [T] * k])
            self._basis[i] = interpolate.BSpline.design_matrix(np.clip(t, 0, T), knots, k).toarray()
        return self._basis[i]

    def _drift_system(self, A: Array) -> tuple[Array, float]:
        """Penalised normal matrix of a P-spline (second differences of the coefficients)."""
        m = A.shape[1]
        D = np.diff(np.eye(m), 2, axis=0) if m > 2 else np.zeros((0, m))
        AtA = A.T @ A
        lam = self.drift_smoothing * max(float(np.trace(AtA)) / m, 1e-300)
        G = AtA + lam * (D.T @ D) + 1e-9 * lam * np.eye(m)
        dof = float(np.trace(np.linalg.solve(G, AtA)))
        return G, dof

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
        """Return the input (V) of recording ``i`` after the input-side ``effects``, clamped."""
        r = self.recs[i]
        x = r.u
        for e in effects:
            if e.cand.side == "input":
                b = e.cand.block(e.x, r.dt)
                b.reset(float(r.state0.input))
                x = b.run(x)
        return np.clip(x, self.model.u_min, self.model.u_max)

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
        fit the feedback with the measured output, see :class:`_Problem`).

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
                y, ue, _ = blk.simulate(table, u, r.state0)
            else:
                ue = self._fed_back(i, u, fb[-1], feedback_from)
                y = self.preisach(i, base, ue)
            return y, ue, Stage(i, u, table)
        y = self.preisach(i, base, u if ins else None)
        return y, u, Stage(i, u, table)

    def _fed_back(self, i: int, u: Array, fb: FittedEffect, feedback_from: Array) -> Array:
        """Return the relays' input (V): ``u`` plus the feedback of the previous sample."""
        blk = fb.cand.block(fb.x, self.recs[i].dt)
        prev = np.concatenate([feedback_from[:1], feedback_from[:-1]])
        return np.clip(u + blk.run(prev), self.model.u_min, self.model.u_max)

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
        sse = [prob.sse(prob.clip(s), coarse=True) for s in starts]
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
        prob = _Problem(self, cand, fixed, train, drift, profile=profile, reference=reference)
        self._last_problem = prob
        if starts is None:
            self._problem = prob
            try:
                starts = cand.starts(self)
            finally:
                self._problem = None
        best: Any = None
        for s in starts:
            x0 = prob.clip(s)
            budget = 20 if cand.side != "output" else 30  # input-side evaluations re-run the relays
            res = optimize.least_squares(
                prob.residuals,
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

    def fit(self, cand: Candidate, fixed: Chain, train: list[Mask], drift: bool = False) -> Chain:
        """Fit ``cand`` on the ``train`` samples after the ``fixed`` chain; returns the new chain.

        With ``drift`` every recording's residual is also freed of a smooth drift (fitted
        jointly by projection).  With a refitted base, the Preisach weights are profiled out:
        every evaluation re-solves them by least squares for the candidate's parameters, with
        the blocks linearised about a reference base that is updated ``alternations`` times.
        """
        if not self.refits(fixed):
            return fixed.plus(self._fit_params(cand, fixed, train, drift, None, profile=False))
        ref = fixed.base
        starts = None
        eff = None
        for _ in range(max(1, self.alternations)):
            eff = self._fit_params(
                cand, Chain(ref, fixed.effects), train, drift, starts, profile=True, reference=eff
            )
            ref = Base(self._last_problem.theta(eff.x))
            starts = [eff.x]
        assert eff is not None
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
        # with a refitted base the weights are profiled out, so their trade-off with the
        # effect's parameters is in the Jacobian
        prob = _Problem(
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
        g = J * r0[:, None]
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


class _Problem:
    """Training residuals of one candidate after a fixed chain, evaluated fast.

    ``reference`` (a fitted feedback effect, optional) closes the reference chain's loop for
    the feedback signal outside the training samples (see ``feedback_from`` below).
    """

    def __init__(
        self,
        ctx: Context,
        cand: Candidate,
        fixed: Chain,
        train: list[Mask],
        drift: bool,
        profile: bool = False,
        reference: FittedEffect | None = None,
    ) -> None:
        self.ctx, self.cand, self.fixed = ctx, cand, fixed
        self.train, self.drift, self.profile = train, drift, profile
        specs = cand.specs(ctx)
        self.lo = np.array([s.lo for s in specs], float)
        self.hi = np.array([s.hi for s in specs], float)
        self.scale = np.array([s.scale for s in specs], float)
        n_train = int(sum(int(m.sum()) for m in train))
        stride = max(1, int(math.ceil(n_train / ctx.max_fit_samples)))
        self.idx = [np.flatnonzero(m)[::stride] for m in train]
        self.coarse = [ix[::4] for ix in self.idx]
        self.blocks = np.concatenate([ctx.recs[i].block[ix] for i, ix in enumerate(self.idx)])
        self.proj: list[tuple[Array, Any] | None] = []
        for i, ix in enumerate(self.idx):
            if drift and ix.size:
                A = ctx.drift_basis(i)[ix]
                G, _ = ctx._drift_system(A)
                self.proj.append((A, np.linalg.inv(G)))
            else:
                self.proj.append(None)
        effs = fixed.effects
        outs = [e for e in effs if e.cand.side == "output"]
        self.ins = [e for e in effs if e.cand.side != "output" and e.cand.side != cand.side]
        self.up: dict[int, Array] = {}
        self.stages: dict[int, Stage] = {}
        if cand.side == "output":
            for i, ix in enumerate(self.idx):
                if ix.size:
                    y, _, st = ctx.stage(i, fixed.base, self.ins)
                    self.stages[i] = st
                    self.up[i] = ctx.output_side(
                        i, y, [e for e in outs if e.cand.order < cand.order], st
                    )
            self.down = [e for e in outs if e.cand.order > cand.order]
        else:
            self.down = outs
        self.outs = outs
        # a feedback candidate with profiled weights is fitted in series-parallel form: the
        # relays see the input shifted by the feedback of the *measured* Preisach output
        # (the recording minus the output blocks' correction at the reference base), so the
        # weights for given feedback parameters are an exact linear least-squares problem;
        # closing the loop through the simulated output instead would tie the effective input
        # to the reference weights, which have absorbed most of the feedback.  Held-out
        # predictions always close the loop.  Outside the training samples (held-out blocks,
        # burn-in) the measured output must not enter the fit - yet the relays' memory at
        # later training samples depends on the input they saw there - so the feedback is
        # driven by the reference chain's simulated Preisach output instead: the reference
        # base with the previous alternation's feedback loop closed (``reference``), or
        # without feedback in the first one.
        self.feedback_from: dict[int, Array] | None = None
        if profile:
            # regressors at the reference base; fixed for output-side candidates
            self.ref_stage = {}
            self.R: dict[int, sp.csr_matrix] = {}
            moved = bool(self.ins)
            for i, m in enumerate(train):
                if m.any():
                    P, ue, st = ctx.stage(i, fixed.base, self.ins)
                    self.ref_stage[i] = (P, st)
                    self.R[i] = ctx.regressor(i, ue) if moved else ctx.regressor(i)
            self.cacheable = not moved
            self.factor = ctx.normal_factor(self.R, train, drift, self.cacheable)
            if cand.side == "feedback":
                self.feedback_from = {}
                ref_fb = [reference] if reference is not None else []
                for i, (P, st) in self.ref_stage.items():
                    measured = ctx.recs[i].y - (ctx.output_side(i, P, outs, st) - P)
                    sim = ctx.stage(i, fixed.base, [*self.ins, *ref_fb])[0] if ref_fb else P
                    self.feedback_from[i] = np.where(train[i], measured, sim)

    def _outputs(self, i: int, x: Array, y: Array, st: Stage) -> Array:
        """All output blocks (fixed ones and, if output-side, the candidate) applied to ``y``."""
        effs = list(self.outs)
        if self.cand.side == "output":
            effs.append(FittedEffect(self.cand, x))
        return self.ctx.output_side(i, y, effs, st)

    def theta(self, x: Array, coarse: bool = False) -> Array:
        """Profiled Preisach weights for the candidate parameters ``x``.

        ``coarse``: for an input-side or feedback candidate without drift, accumulate the
        normal equations over every fourth training sample only (the quick evaluations of a
        start-value scan).
        """
        ctx = self.ctx
        if self.cand.side == "output":
            Rs = self.R
            targets = {}
            for i, (P, st) in self.ref_stage.items():
                targets[i] = ctx.recs[i].y - (self._outputs(i, x, P, st) - P)
            return ctx.solve_theta(Rs, targets, self.train, self.drift, self.cacheable, self.factor)
        effs = [*self.fixed.effects, FittedEffect(self.cand, x)]
        if self.drift:  # the drift projection needs the regressors themselves
            Rs, targets, _ = ctx.linearised_targets(
                effs, self.fixed.base, self.train, self.feedback_from
            )
            self._last_R = Rs
            self._last_u = None
            return ctx.solve_theta(Rs, targets, self.train, self.drift, False)
        # normal equations straight from the C++ regressor, without forming it
        outs = [e for e in effs if e.cand.side == "output"]
        p = ctx.n_theta
        ctx.table(self.fixed.base)  # built once, before the threads share it

        def one(i: int) -> tuple[Array, Array, Array]:
            r = ctx.recs[i]
            fb = None if self.feedback_from is None else self.feedback_from[i]
            # the reference base's output is needed only to linearise output blocks
            ue_open = None if outs else ctx.relay_input(i, effs, fb)
            if ue_open is None:
                P, ue, st = ctx.stage(i, self.fixed.base, effs, fb)
                target = r.y - (ctx.output_side(i, P, outs, st) - P) if outs else r.y
            else:
                ue, target = ue_open, r.y
            if coarse:
                fold = np.full(r.n, -1, np.int32)
                fold[self.coarse[i]] = 0
            else:
                fold = np.where(self.train[i], 0, -1).astype(np.int32)
            gram, b, *_ = _core.normal_equations(ctx.levels, ue, target, r.state0, fold, 1, "clamp")
            return gram[0], b[0], ue

        # the recordings are independent and the C++ loops release the GIL: one per core,
        # summed in recording order so the result does not depend on the threads
        todo = [i for i, m in enumerate(self.train) if m.any()]
        N = np.zeros((p, p))
        rhs = np.zeros(p)
        self._last_u = {}
        for i, (gram, b, ue) in zip(todo, _pool().map(one, todo)):
            N += gram
            rhs += b
            self._last_u[i] = ue
        lam = 1e-7 * max(float(np.trace(N)) / p, 1e-300)
        N[np.diag_indices(p)] += lam
        rhs += lam * ctx.theta0
        # Cholesky without the condition estimate of linalg.solve (the ridge keeps N definite)
        return linalg.cho_solve(linalg.cho_factor(N, check_finite=False), rhs, check_finite=False)

    def _profiled_predict(self, x: Array, coarse: bool = False) -> dict[int, Array]:
        theta = self.theta(x, coarse)
        if self.cand.side != "output" and self._last_u is not None:
            table = self.ctx.table(Base(theta))
            recs, last = self.ctx.recs, self._last_u

            def sim(i: int) -> Array:
                return cast(Array, _core.simulate(table, last[i], recs[i].state0, "clamp")[0])

            Ps = dict(zip(last, _pool().map(sim, last)))
        else:
            Rs = self.R if self.cand.side == "output" else self._last_R
            Ps = {i: R @ theta for i, R in Rs.items()}
        out = {}
        for i, P in Ps.items():
            if self.cand.side == "output":
                st = self.ref_stage[i][1]
            else:  # the Preisach input with the candidate; the reference table for A(u)
                effs = [*self.ins, FittedEffect(self.cand, x)]
                st = Stage(i, self.ctx.preisach_input(i, effs), self.ctx.table(self.fixed.base))
            out[i] = self._outputs(i, x, P, st)
        return out

    def scan_linear(self, make: Callable[[int, Array], Array]) -> tuple[float, float]:
        """Project the training residual on one extra signal (output-side candidates only).

        ``make(i, up)`` returns the extra signal of recording ``i`` from the signal entering
        the candidate; returns ``(coefficient, SSE reduction)`` of the least-squares fit
        ``residual ~ c * signal`` on the (coarse) training samples, ignoring downstream blocks.
        """
        rg = gg = 0.0
        for i, ix in enumerate(self.coarse):
            if ix.size == 0 or i not in self.up:
                continue
            g = make(i, self.up[i])[ix]
            r = (
                self.ctx.recs[i].y[ix]
                - self.ctx.output_side(i, self.up[i], self.down, self.stages[i])[ix]
            )
            pr = self.proj[i]
            if pr is not None:
                A, Ginv = pr
                sub = np.searchsorted(self.idx[i], ix)
                A = A[sub]
                G = A.T @ A
                r = r - A @ np.linalg.lstsq(G, A.T @ r, rcond=None)[0]
                g = g - A @ np.linalg.lstsq(G, A.T @ g, rcond=None)[0]
            rg += float(r @ g)
            gg += float(g @ g)
        if gg <= 0:
            return 0.0, 0.0
        return rg / gg, rg * rg / gg

    def clip(self, x: Array) -> Array:
        span = self.hi - self.lo
        eps = np.where(np.isfinite(span), 1e-9 * span, 0.0)
        return np.clip(np.asarray(x, float), self.lo + eps, self.hi - eps)

    def predict(self, i: int, x: Array) -> Array:
        ctx, r = self.ctx, self.ctx.recs[i]
        if self.cand.side == "output":
            st = self.stages[i]
            y = self.cand.apply(x, self.up[i], r.dt, st, ctx)
        else:
            y, _, st = ctx.stage(i, self.fixed.base, [*self.ins, FittedEffect(self.cand, x)])
        return ctx.output_side(i, y, self.down, st)

    def residuals(self, x: Array, coarse: bool = False) -> Array:
        self.ctx.n_evals += 1
        parts = []
        todo = [i for i, ix in enumerate(self.idx) if ix.size]
        if self.profile:
            preds = self._profiled_predict(x, coarse)
        else:  # independent recordings, C++ simulations that release the GIL: one per core
            preds = dict(zip(todo, _pool().map(lambda i: self.predict(i, x), todo)))
        for i in todo:
            ix = self.idx[i]
            res = self.ctx.recs[i].y[ix] - preds[i][ix]
            pr = self.proj[i]
            if pr is not None:
                A, Ginv = pr
                res = res - A @ (Ginv @ (A.T @ res))
            parts.append(res[::4] if coarse else res)
        return np.concatenate(parts) if parts else np.zeros(0)

    def sse(self, x: Array, coarse: bool = False) -> float:
        r = self.residuals(x, coarse)
        return float(r @ r)


# ----------------------------------------------------------------------------------------
# selection
# ----------------------------------------------------------------------------------------
@dataclass
class Score:
    """Held-out score of one chain (diagnosis recordings only)."""

    sse_blocks: Array  # SSE per held-out block
    n_blocks: Array  # samples per held-out block
    residuals: list[Array]  # held-out residual per recording (NaN where not scored)
    predictions: list[Array]  # held-out prediction per recording

    @property
    def mse(self) -> float:
        """Held-out mean-square error (V^2)."""
        return float(self.sse_blocks.sum() / max(self.n_blocks.sum(), 1))

    @property
    def rmse(self) -> float:
        """Held-out root-mean-square error (V)."""
        return math.sqrt(self.mse)


@dataclass
class StepResult:
    """One step of the forward selection."""

    baseline: Score
    scores: dict[str, Score]
    n_params: dict[str, float]
    p_values: dict[str, float]
    gains: dict[str, float]
    explained: dict[str, float]  # held-out MSE reduction / noise variance
    qualifies: dict[str, bool]
    reasons: dict[str, str]
    chosen: str | None
    chains: dict[str, list[Chain]]


def make_folds(recs: list[Rec], scheme: str, max_groups: int = 3) -> list[Fold]:
    """Make the folds: ``"recordings"`` holds out groups of recordings, ``"blocks"`` time blocks.

    Identification recordings are always training data.
    """
    diag = [i for i, r in enumerate(recs) if not r.ident]
    if scheme == "recordings":
        k = min(len(diag), max_groups)
        groups = [diag[g::k] for g in range(k)]
        return [
            Fold(
                [r.usable & (j not in g) for j, r in enumerate(recs)],
                [r.usable & (j in g) for j, r in enumerate(recs)],
            )
            for g in groups
        ]
    if scheme == "blocks":
        return [
            Fold(
                [r.usable & ((r.fold != p) | r.ident) for r in recs],
                [r.usable & (r.fold == p) & (not r.ident) for r in recs],
            )
            for p in (0, 1)
        ]
    raise ValueError(f"cv: expected 'recordings', 'blocks' or 'auto', got {scheme!r}")


def heldout_score(ctx: Context, folds: list[Fold], chains: list[Chain], drift: bool) -> Score:
    """Pool held-out residuals: each sample is predicted by the fit of the fold that held it out."""
    nb = max(int(r.block.max()) for r in ctx.recs) + 1
    sse = np.zeros(nb)
    cnt = np.zeros(nb)
    res_all, pred_all = [], []
    for i, r in enumerate(ctx.recs):
        res = np.full(r.n, np.nan)
        pred = np.full(r.n, np.nan)
        for fold, ch in zip(folds, chains):
            m = fold.test[i]
            if not m.any():
                continue
            p = ctx.predict_one(i, ch)
            if drift:
                p = p + ctx.drift_heldout(i, r.y - p, m)
            res[m] = r.y[m] - p[m]
            pred[m] = p[m]
        ok = ~np.isnan(res)
        sse += np.bincount(r.block[ok], weights=res[ok] ** 2, minlength=nb)
        cnt += np.bincount(r.block[ok], minlength=nb)
        res_all.append(res)
        pred_all.append(pred)
    keep = cnt > 0
    return Score(sse[keep], cnt[keep], res_all, pred_all)


def sign_flip_p(d: Array, n_perm: int = 4000, seed: int = 0) -> float:
    """One-sided p-value of mean(d) > 0 by random sign flips of the block differences."""
    d = np.asarray(d, float)
    if d.size == 0 or not np.any(d):
        return 1.0
    obs = d.mean()
    rng = np.random.default_rng(seed)
    signs = rng.choice([-1.0, 1.0], size=(n_perm, d.size))
    null = (signs * np.abs(d)).mean(axis=1)
    return float((1 + np.count_nonzero(null >= obs)) / (n_perm + 1))


def correlation_length(res: list[Array]) -> float:
    """Return the samples over which the residual stays correlated (integral scale, >= 1)."""
    lens = []
    for r in res:
        r = r[~np.isnan(r)]
        if r.size < 64:
            continue
        r = r - r.mean()
        n = min(r.size, 1 << 16)
        f = np.fft.rfft(r[:n], 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[:n]
        if ac[0] <= 0:
            continue
        ac = ac / ac[0]
        neg = np.flatnonzero(ac < 0.05)
        cut = int(neg[0]) if neg.size else n
        lens.append(max(1.0, 1.0 + 2.0 * float(ac[1:cut].sum())))
    return float(np.median(lens)) if lens else 1.0


@dataclass
class Selection:
    """Outcome of :func:`run_selection`."""

    steps: list[StepResult]
    kept: list[str]
    folds: list[Fold]
    given: Score
    refit_baseline: Score | None


def _choose(
    quals: list[str], scores: dict[str, Score], n_par: dict[str, float], tie_alpha: float, seed: int
) -> str:
    """Pick the qualifying candidate with the lowest held-out error, or a simpler one as good.

    A candidate with fewer parameters is preferred when the best one is not significantly
    better on the held-out blocks (one-sided sign-flip test at ``tie_alpha``): parsimony among
    explanations the data cannot tell apart.
    """
    best = min(quals, key=lambda k: scores[k].mse)
    simpler = [
        k
        for k in quals
        if n_par[k] < n_par[best]
        and sign_flip_p(scores[k].sse_blocks - scores[best].sse_blocks, seed=seed) >= tie_alpha
    ]
    if simpler:
        return min(simpler, key=lambda k: (n_par[k], scores[k].mse))
    return best


def run_selection(
    ctx: Context,
    candidates: Sequence[Candidate],
    *,
    sigma: float,
    cv: str = "auto",
    min_gain: float = 0.10,
    noise_factor: float = 1.0,
    alpha: float = 0.01,
    max_effects: int = 3,
    retry_gain: float = 0.02,
    tie_alpha: float = 0.05,
    progress: Callable[[str], None] | None = None,
) -> Selection:
    """Greedy forward selection (see the module docstring)."""
    for c in candidates:
        c.prepare(ctx)
    scheme = "blocks" if cv == "auto" else cv
    folds = make_folds(ctx.recs, scheme)
    given_chains = [Chain(ctx.given) for _ in folds]
    given = heldout_score(ctx, folds, given_chains, False)
    refit_score = None
    if ctx.refit:
        chains = [Chain(ctx.refit_base([], ctx.given, f.train, False)) for f in folds]
        refit_score = heldout_score(ctx, folds, chains, False)
        if progress:
            progress(
                "  base refitted on the training folds: held-out RMSE "
                f"{1e3 * refit_score.rmse:.4g} mV "
                f"(given model {1e3 * given.rmse:.4g} mV)"
            )
        baseline = refit_score
    else:
        chains = given_chains
        baseline = given
    kept: list[str] = []
    drift = False
    steps: list[StepResult] = []
    remaining = {c.key: c for c in candidates}
    while remaining and len(kept) < max_effects:
        scores: dict[str, Score] = {}
        new_chains: dict[str, list[Chain]] = {}
        n_par: dict[str, float] = {}
        for name, cand in remaining.items():
            t0 = _time.perf_counter()
            if isinstance(cand, DriftCandidate):
                if all(ctx.refits(ch) for ch in chains):
                    cc = [
                        Chain(ctx.refit_base(ch.effects, ch.base, f.train, True), ch.effects)
                        for ch, f in zip(chains, folds)
                    ]
                else:
                    cc = chains
                scores[name] = heldout_score(ctx, folds, cc, True)
                new_chains[name] = cc
                n_par[name] = ctx.drift_dof()
            else:
                cc = [ctx.fit(cand, ch, f.train, drift) for ch, f in zip(chains, folds)]
                scores[name] = heldout_score(ctx, folds, cc, drift)
                new_chains[name] = cc
                n_par[name] = float(cand.n_params(ctx))
            if progress:
                progress(
                    f"  {name}: held-out RMSE {1e3 * scores[name].rmse:.4g} mV "
                    f"({_time.perf_counter() - t0:.2f} s)"
                )
        pv, gains, expl, ok, why = {}, {}, {}, {}, {}
        for name, sc in scores.items():
            d = baseline.sse_blocks - sc.sse_blocks
            pv[name] = sign_flip_p(d, seed=len(steps))
            gains[name] = 1.0 - sc.rmse / baseline.rmse if baseline.rmse > 0 else 0.0
            expl[name] = (baseline.mse - sc.mse) / sigma**2 if sigma > 0 else float("inf")
            reasons = []
            if gains[name] < min_gain:
                reasons.append(
                    f"held-out RMSE lower by only {100 * gains[name]:.1f} % "
                    f"(< {100 * min_gain:.0f} %)"
                )
            if expl[name] < noise_factor:
                reasons.append(
                    f"explains {expl[name]:.2f} x the noise variance (< {noise_factor:g})"
                )
            if pv[name] >= alpha:
                reasons.append(
                    f"not significant over held-out blocks (p = {pv[name]:.3g} >= {alpha:g})"
                )
            ok[name] = not reasons
            why[name] = "; ".join(reasons) if reasons else "qualifies"
        quals = [n for n in scores if ok[n]]
        chosen = _choose(quals, scores, n_par, tie_alpha, seed=len(steps)) if quals else None
        steps.append(
            StepResult(baseline, scores, n_par, pv, gains, expl, ok, why, chosen, new_chains)
        )
        if chosen is None:
            break
        kept.append(chosen)
        if isinstance(remaining[chosen], DriftCandidate):
            drift = True
        chains = new_chains[chosen]
        baseline = scores[chosen]
        name = remaining[chosen].name
        for k in [k for k, c in remaining.items() if c.name == name]:
            del remaining[k]
        # candidates that could not lower the held-out error by even 2 % are not retried
        for k in [k for k in remaining if gains.get(k, 1.0) < retry_gain]:
            del remaining[k]
    return Selection(steps, kept, folds, given, refit_score)
