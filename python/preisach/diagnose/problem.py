"""The training problem of one candidate after a fixed chain, evaluated fast.

Every evaluation of a candidate's parameters predicts the training samples of every
recording; with a refitted base the Preisach weights are profiled out (re-solved by least
squares for the parameters, from the C++ normal equations), and with a drift the residual is
projected off each recording's drift P-spline.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from typing import Any, Callable, cast

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy import linalg

from .. import _core
from .candidates import Candidate
from .context import Base, Chain, Context, FittedEffect, Stage, _pool

__all__ = ["Problem"]

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
#: one recording of :meth:`Problem.scan_linear`: index, rows, residual, drift basis and system
ScanPart = tuple[int, NDArray[np.intp], Array, "tuple[Array, Array] | None"]


class Problem:
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
        self.stride = max(1, int(math.ceil(n_train / ctx.max_fit_samples)))
        self.idx = [np.flatnonzero(m)[:: self.stride] for m in train]
        self.coarse = [ix[::4] for ix in self.idx]
        self.blocks = np.concatenate([ctx.recs[i].block[ix] for i, ix in enumerate(self.idx)])
        self.proj: list[tuple[Array, Any] | None] = []
        # the inverse penalised drift systems: at the residual rows (proj) and, for the weights
        # an input-side or feedback candidate profiles (:meth:`_theta`), at the training rows
        # (the same ones when no training sample is skipped)
        self.fit_ginv: dict[int, Array] = {}
        for i, ix in enumerate(self.idx):
            if drift and ix.size:
                A = ctx.drift_basis(i)[ix]
                G, _ = ctx._drift_system(A)
                ginv = np.asarray(np.linalg.inv(G), dtype=float)
                self.proj.append((A, ginv))
                if cand.side != "output":
                    if self.stride > 1:
                        G, _ = ctx._drift_system(ctx.drift_basis(i)[train[i]])
                        ginv = np.asarray(np.linalg.inv(G), dtype=float)
                    self.fit_ginv[i] = ginv
            else:
                self.proj.append(None)
        effs = fixed.effects
        outs = [e for e in effs if e.cand.side == "output"]
        self.ins = [e for e in effs if e.cand.side != "output" and e.cand.side != cand.side]
        self.up: dict[int, Array] = {}
        self._scan_parts: list[ScanPart] | None = None
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
        # a feedback candidate leaves the input blocks' output alone: the Preisach input (and
        # the stage of output blocks that read it) is the same for every parameter vector
        self.u_in: dict[int, Array] = {}
        self._folds: dict[tuple[int, bool], NDArray[np.int32]] = {}
        self._prev: dict[int, Array] = {}  # the feedback signals one sample late
        if cand.side == "feedback" and not any(e.cand.side == "feedback" for e in effs):
            self.u_in = {i: ctx.preisach_input(i, self.ins) for i, m in enumerate(train) if m.any()}
        if profile:
            # regressors at the reference base; fixed for output-side candidates
            self.ref_stage = {}
            self.R: dict[int, sp.csr_matrix] = {}
            moved = bool(self.ins)
            for i, m in enumerate(train):
                if m.any():
                    P, ue, st = ctx.stage(i, fixed.base, self.ins)
                    self.ref_stage[i] = (P, st)
                    self.R[i] = ctx.regressor(i, ue if moved else None, fixed.base)
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
        start-value scan); with a drift they are always fitted on every training sample.
        """
        return self._theta(x, coarse, False)[0]

    def _theta(self, x: Array, coarse: bool, serial: bool) -> tuple[Array, dict[int, Array] | None]:
        """:meth:`theta`, with the relay inputs it used (None for an output-side candidate).

        ``serial``: the recordings one after the other in this thread (when the evaluations
        themselves run in parallel, :meth:`sse_many`), else one per core.
        """
        ctx = self.ctx
        if self.cand.side == "output":
            Rs = self.R
            targets = {}
            for i, (P, st) in self.ref_stage.items():
                targets[i] = ctx.recs[i].y - (self._outputs(i, x, P, st) - P)
            theta = ctx.solve_theta(
                Rs, targets, self.train, self.drift, self.cacheable, self.factor
            )
            return theta, None
        effs = [*self.fixed.effects, FittedEffect(self.cand, x)]
        fb_eff = self._feedback(effs)
        # normal equations straight from the C++ regressor, without forming it; a drift is
        # profiled out of them as ctx.solve_theta does, from the rows' cross products with its
        # basis, fitted on every training sample
        outs = [e for e in effs if e.cand.side == "output"]
        p = ctx.n_theta
        ctx.table(self.fixed.base)  # built once, before the threads share it

        def one(i: int) -> tuple[Array, Array, Array]:
            r = ctx.recs[i]
            fb = None if self.feedback_from is None else self.feedback_from[i]
            # the reference base's output is needed only to linearise output blocks
            if outs:
                ue_open = None
            elif fb is not None and i in self.u_in:  # relay_input with the input blocks run once
                if i not in self._prev:
                    self._prev[i] = ctx.previous(fb)
                ue_open = ctx._fed_back(i, self.u_in[i], effs[-1], fb, self._prev[i])
            else:
                ue_open = ctx.relay_input(i, effs, fb)
            if ue_open is None:
                P, ue, st = ctx.stage(i, self.fixed.base, effs, fb)
                target = r.y - (ctx.output_side(i, P, outs, st) - P) if outs else r.y
            else:
                ue, target = ue_open, r.y
            s0 = ctx.state(i, self.fixed.base, ue, fb_eff)
            if not self.drift:
                gram, b, *_ = _core.normal_equations(
                    ctx.levels, ue, target, s0, self._fold(i, coarse), 1, "clamp", ctx.interpolation
                )
                return gram[0], b[0], ue
            A, m = ctx.drift_basis(i), self.train[i]
            g, b, cross, _ = _core.normal_equations_basis(
                ctx.levels, ue, target, s0, self._fold(i, False), A, ctx.interpolation
            )
            cg = cross @ self.fit_ginv[i]
            return g - cg @ cross.T, b - cg @ (A[m].T @ target[m]), ue

        # the recordings are independent and the C++ loops release the GIL: one per core,
        # summed in recording order so the result does not depend on the threads
        todo = [i for i, m in enumerate(self.train) if m.any()]
        N = np.zeros((p, p))
        rhs = np.zeros(p)
        last_u = {}
        for i, (gram, b, ue) in zip(todo, (map if serial else _pool().map)(one, todo)):
            N += gram
            rhs += b
            last_u[i] = ue
        lam = ctx.ridge * max(float(np.trace(N)) / p, 1e-300)
        N[np.diag_indices(p)] += lam
        rhs += lam * ctx.theta0
        # Cholesky without the condition estimate of linalg.solve (the ridge keeps N definite)
        theta = np.asarray(
            linalg.cho_solve(linalg.cho_factor(N, check_finite=False), rhs, check_finite=False),
            dtype=float,
        )
        return theta, last_u

    @staticmethod
    def _feedback(effs: list[FittedEffect]) -> FittedEffect | None:
        """Return the feedback effect the relays' input carries (the last one), or None."""
        fb = [e for e in effs if e.cand.side == "feedback"]
        return fb[-1] if fb else None

    def _fold(self, i: int, coarse: bool) -> NDArray[np.int32]:
        """Fold labels of recording ``i`` for the normal equations (0: a row; -1: state only)."""
        key = (i, coarse)
        fold = self._folds.get(key)
        if fold is None:
            if coarse:
                fold = np.full(self.ctx.recs[i].n, -1, np.int32)
                fold[self.coarse[i]] = 0
            else:
                fold = np.where(self.train[i], 0, -1).astype(np.int32)
            self._folds[key] = fold
        return fold

    def _profiled_predict(
        self, x: Array, coarse: bool = False, serial: bool = False
    ) -> dict[int, Array]:
        theta, last_u = self._theta(x, coarse, serial)
        if self.cand.side != "output" and last_u is not None:
            table = self.ctx.table(Base(theta))
            ctx, last = self.ctx, last_u

            fb_eff = self._feedback([*self.fixed.effects, FittedEffect(self.cand, x)])

            def sim(i: int) -> Array:
                s0 = ctx.state(i, self.fixed.base, last[i], fb_eff)
                return cast(Array, _core.simulate(table, last[i], s0, "clamp")[0])

            Ps = dict(zip(last, (map if serial else _pool().map)(sim, last)))
        else:
            Ps = {i: R @ theta for i, R in self.R.items()}
        out = {}
        for i, P in Ps.items():
            if self.cand.side == "output":
                st = self.ref_stage[i][1]
            else:  # the Preisach input with the candidate; the reference table for A(u)
                if i in self.u_in:
                    u_in = self.u_in[i]
                else:
                    u_in = self.ctx.preisach_input(i, [*self.ins, FittedEffect(self.cand, x)])
                st = Stage(i, u_in, self.ctx.table(self.fixed.base))
            out[i] = self._outputs(i, x, P, st)
        return out

    def scan_linear(self, make: Callable[[int, Array], Array]) -> tuple[float, float]:
        """Project the training residual on one extra signal (output-side candidates only).

        ``make(i, up)`` returns the extra signal of recording ``i`` from the signal entering
        the candidate; returns ``(coefficient, SSE reduction)`` of the least-squares fit
        ``residual ~ c * signal`` on the training samples the fit uses, ignoring downstream
        blocks.  (Not on the coarse rows, every fourth of them: at 1 kHz those alias a 337 Hz
        ring onto 163 Hz, and a mode scan found the wrong one.)
        """
        c, red = self.scan_columns([make])
        return float(c[0]), red

    def scan_columns(self, makes: Sequence[Callable[[int, Array], Array]]) -> tuple[Array, float]:
        """:meth:`scan_linear` on several extra signals at once.

        Returns the coefficients of the joint least-squares fit ``residual ~ sum_k c_k
        signal_k`` and its SSE reduction (zeros and 0 when the signals are degenerate).
        """
        k = len(makes)
        gg, rg = np.zeros((k, k)), np.zeros(k)
        for i, ix, r, drift in self._scan_residuals():
            g = np.stack([mk(i, self.up[i])[ix] for mk in makes], axis=1)
            if drift is not None:
                A, G = drift
                g = g - A @ np.linalg.lstsq(G, A.T @ g, rcond=None)[0]
            rg += g.T @ r
            gg += g.T @ g
        if not np.all(np.diag(gg) > 0) or np.linalg.cond(gg) > 1e12:
            return np.zeros(k), 0.0
        c = np.asarray(np.linalg.solve(gg, rg), dtype=float)
        return c, float(c @ rg)

    def _scan_residuals(self) -> list[ScanPart]:
        """Return what :meth:`scan_linear` needs per recording (the same for every signal).

        Its fit rows, the training residual there (freed of its drift fit), and the drift
        basis at those rows with its normal matrix (None without a drift); computed once.
        """
        if self._scan_parts is None:
            self._scan_parts = []
            for i, ix in enumerate(self.idx):
                if ix.size == 0 or i not in self.up:
                    continue
                r = (
                    self.ctx.recs[i].y[ix]
                    - self.ctx.output_side(i, self.up[i], self.down, self.stages[i])[ix]
                )
                drift = None
                pr = self.proj[i]
                if pr is not None:
                    A = pr[0]
                    G = A.T @ A
                    r = r - A @ np.linalg.lstsq(G, A.T @ r, rcond=None)[0]
                    drift = (A, G)
                self._scan_parts.append((i, ix, r, drift))
        return self._scan_parts

    def linear_feedback_scan(self, gains: Array, zeros: Array) -> Array | None:
        """Coarse training SSE (V^2) of the linear feedback ``a (y - y_c)`` at every point, in C++.

        The same numbers as :meth:`sse_many` of the feedback candidate's vectors
        ``cand.linear(a, y_c)`` (the cubic feedback of
        :class:`~preisach.diagnose.candidates.NonCongruenceCandidate` with no curvature, or a
        straight :class:`~preisach.diagnose.candidates.SplineFeedbackCandidate`, whose feedback
        is constant outside its output range: the fed-back output is clipped to
        ``cand.linear_range`` first), up to rounding (the
        weights by a Cholesky factor of the summed normal equations, the prediction from the
        regressor's rows instead of a simulation of the fitted table), in one call
        (``preisach._core.feedback_gain_scan``) whose points run on every core with the GIL
        released.  Output blocks in the fixed chain that are linear filters run in C++ too
        (linearised about the reference base as :meth:`theta` does).  A drift is profiled out
        in C++ as :meth:`theta` and :meth:`residuals` do it: the weights fitted on every
        training sample with each recording's drift curve, the residuals at the subsampled
        rows freed of their own drift fit.  None when the shortcut does not apply: no profiled
        weights, another output block (or a linear filter with a drift), or a feedback effect
        already fitted; then use :meth:`sse_many`.  ``gains`` and ``zeros`` must lie
        within the candidate's bounds (see :meth:`clip`).
        """
        from .candidates import NonCongruenceCandidate, SplineFeedbackCandidate
        from .effects import OutputFeedback, SplineFeedback

        ctx = self.ctx
        cand = cast("NonCongruenceCandidate | SplineFeedbackCandidate", self.cand)
        todo = [i for i, m in enumerate(self.train) if m.any()]
        filters = self._linear_filters(todo)
        linear = (
            (NonCongruenceCandidate, OutputFeedback),
            (SplineFeedbackCandidate, SplineFeedback),
        )
        if (
            not any(isinstance(cand, c) and cand.block_type is b for c, b in linear)
            or not self.profile
            or filters is None
            or (self.drift and any(filters))
            or self.feedback_from is None
            or not todo
            or any(i not in self.u_in for i in todo)
        ):
            return None
        gains = np.asarray(gains, float)
        zeros = np.asarray(zeros, float)
        lo, hi = ctx.model.u_min, ctx.model.u_max
        us, ps, ys, folds, drift = [], [], [], [], []
        per_rec: list[list[Any]] = []  # every point's initial state, by recording
        for i in todo:
            fb = self.feedback_from[i]
            if i not in self._prev:
                self._prev[i] = ctx.previous(fb)
            u, prev = self.u_in[i], np.clip(self._prev[i], *cand.linear_range)
            us.append(u)
            ps.append(prev)
            ys.append(ctx.recs[i].y)
            # with a drift the weights are fitted on every training sample (as ctx.solve_theta)
            folds.append(self._fold(i, not self.drift))
            if self.drift:
                proj = self.proj[i]
                assert proj is not None
                drift.append((ctx.drift_basis(i), self.fit_ginv[i], proj[1]))
            h = ctx.history(i, self.fixed.base)
            if h is None:  # a known initial state
                per_rec.append([ctx.recs[i].state0] * gains.size)
                continue
            # an unknown one follows the relays' input (its first value and range), computed
            # as ``Context._fed_back`` does, a few hundred points at a time; the state the
            # previous recording left, with its relays fed back too (``Context.session_left``)
            sts: list[Any] = []
            left: list[Any] = [None] * gains.size
            if h.kind == "session":
                left = self._scan_left(i, gains, zeros, cand.linear_range)
            for k0, x in self._linear_rows(u, prev, gains, zeros):
                sts += [
                    h.state_of(float(f), float(mn), float(mx), lf)
                    for f, mn, mx, lf in zip(
                        x[:, 0], x.min(axis=1), x.max(axis=1), left[k0 : k0 + len(x)]
                    )
                ]
            per_rec.append(sts)
        states = [per_rec[j][k] for k in range(gains.size) for j in range(len(todo))]
        sse = np.asarray(
            _core.feedback_gain_scan(
                ctx.levels,
                us,
                ps,
                ys,
                folds,
                states,
                gains,
                zeros,
                lo,
                hi,
                ctx.ridge,
                ctx.theta0,
                filters=filters,
                reference=ctx.table(self.fixed.base) if any(filters) else None,
                interpolation=ctx.interpolation,
                drift=drift,
                res_stride=self.stride if self.drift else 1,
                score_every=4 if self.drift else 1,
            ),
            dtype=np.float64,
        )
        ctx.n_evals += int(gains.size)
        n_rows = int(sum(ix.size for ix in self.coarse))
        for k in range(gains.size):  # a candidate's regularisation, as in :meth:`residuals`
            pen = cand.penalty(cand.linear(float(gains[k]), float(zeros[k])), n_rows)
            sse[k] += float(pen @ pen) if pen.size else 0.0
        return sse

    def _scan_left(
        self, i: int, gains: Array, zeros: Array, span: tuple[float, float]
    ) -> list[Any]:
        """Return the state recording ``i - 1`` left under each linear feedback ``a (y - y_c)``.

        As :meth:`Context.session_left` builds it (the previous recording's input shifted by
        the feedback of its measured output, ``span`` the output range the feedback is linear
        over), for every scanned point at once: its relays run in C++ on both cores, a few
        hundred points at a time.
        """
        ctx = self.ctx
        p = ctx.recs[i - 1]
        pp = np.clip(ctx.previous(p.y), *span)
        table = ctx.table(self.fixed.base)  # any table: only the relays' final states are kept
        out: list[Any] = []
        for _, x in self._linear_rows(p.u, pp, gains, zeros):
            out += _core.simulate_batch(table, x, [p.state0] * len(x), "clamp")[1]
        return out

    def _linear_rows(
        self, u: Array, prev: Array, gains: Array, zeros: Array
    ) -> Iterator[tuple[int, Array]]:
        """Yield ``(k0, rows)``: the relays' input ``u + a (prev - y_c)`` per point, clamped.

        As ``Context._fed_back`` computes it, a few hundred points at a time (rows ``k0`` on).
        """
        lo, hi = self.ctx.model.u_min, self.ctx.model.u_max
        step = max(1, int(4e6 // max(u.size, 1)))
        for k0 in range(0, gains.size, step):
            a, z = gains[k0 : k0 + step, None], zeros[k0 : k0 + step, None]
            yield k0, np.clip(u[None, :] + (prev[None, :] - z) * a, lo, hi)

    def _linear_filters(self, todo: list[int]) -> list[list[tuple[Array, Array, float]]] | None:
        """Return the fixed output blocks of each recording as linear filters ``(b, a, mix)``.

        None unless every one is a linear filter run by the candidates' own :meth:`apply`
        (from rest at its first input: :class:`~preisach.diagnose.effects._LinearFilter`);
        ``a`` normalised to ``a[0] = 1`` as :func:`scipy.signal.lfilter` does.
        """
        from .candidates import Candidate as _Candidate
        from .effects import _LinearFilter

        outs = sorted(self.outs, key=lambda e: e.cand.order)
        if any(type(e.cand).apply is not _Candidate.apply for e in outs):
            return None
        per_rec = []
        for i in todo:
            chain = []
            for e in outs:
                blk = e.cand.block(e.x, self.ctx.recs[i].dt)
                if not isinstance(blk, _LinearFilter):
                    return None
                b, a = np.asarray(blk._b, float), np.asarray(blk._a, float)
                chain.append((b / a[0], a / a[0], float(blk._mix)))
            per_rec.append(chain)
        return per_rec

    def clip(self, x: Array) -> Array:
        """Clip ``x`` just inside the parameter bounds."""
        span = self.hi - self.lo
        eps = np.where(np.isfinite(span), 1e-9 * span, 0.0)
        return np.asarray(np.clip(np.asarray(x, float), self.lo + eps, self.hi - eps), dtype=float)

    def predict(self, i: int, x: Array) -> Array:
        """Prediction (V) of recording ``i`` with the candidate at ``x`` (weights fixed)."""
        ctx, r = self.ctx, self.ctx.recs[i]
        if self.cand.side == "output":
            st = self.stages[i]
            y = self.cand.apply(x, self.up[i], r.dt, st, ctx)
        else:
            y, _, st = ctx.stage(i, self.fixed.base, [*self.ins, FittedEffect(self.cand, x)])
        return ctx.output_side(i, y, self.down, st)

    def residuals(self, x: Array, coarse: bool = False, serial: bool = False) -> Array:
        """Training residuals (V) at ``x``, drift projected off; ``coarse``: every fourth.

        ``serial``: the recordings one after the other in this thread (see :meth:`sse_many`).
        """
        self.ctx.n_evals += 1
        parts = []
        todo = [i for i, ix in enumerate(self.idx) if ix.size]
        if self.profile:
            preds = self._profiled_predict(x, coarse, serial)
        else:  # independent recordings, C++ simulations that release the GIL: one per core
            run = map if serial else _pool().map
            preds = dict(zip(todo, run(lambda i: self.predict(i, x), todo)))
        for i in todo:
            ix = self.idx[i]
            res = self.ctx.recs[i].y[ix] - preds[i][ix]
            pr = self.proj[i]
            if pr is not None:
                A, Ginv = pr
                res = res - A @ (Ginv @ (A.T @ res))
            parts.append(res[::4] if coarse else res)
        pen = self.cand.penalty(x, sum(p.size for p in parts))
        if pen.size:  # a candidate's regularisation (e.g. a spline's curvature)
            parts.append(pen)
        return np.concatenate(parts) if parts else np.zeros(0)

    def sse(self, x: Array, coarse: bool = False, serial: bool = False) -> float:
        """Training sum of squared residuals (V^2) at ``x``."""
        r = self.residuals(x, coarse, serial)
        return float(r @ r)

    def sse_many(self, xs: Sequence[Array], coarse: bool = False) -> list[float]:
        """:meth:`sse` of every vector in ``xs`` (a start-value scan), the same numbers.

        The evaluations run one per core, each with its recordings one after the other: one
        evaluation's Python (output blocks, residuals) then overlaps another's C++ loops,
        which release the GIL, where the recordings of a single evaluation spread over the
        cores leave a core idle while the first thread runs Python.
        """
        xs = list(xs)
        if len(xs) < 2 or (os.cpu_count() or 1) < 2:
            return [self.sse(x, coarse) for x in xs]
        self.ctx.table(self.fixed.base)  # built once, before the threads share it
        return list(_pool().map(lambda x: self.sse(x, coarse, serial=True), xs))
