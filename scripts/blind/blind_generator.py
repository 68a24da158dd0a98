#!/usr/bin/env python3
"""
blind_generator.py -- independent ("blind") test-data generator for a hysteresis
diagnosis tool.  numpy / scipy only.  Written without reference to the tool.

Usage
-----
    python blind_generator.py OUTDIR [--seed S] [--cases-per-kind N] [--self-test]
    python blind_generator.py --self-test

Module API
----------
    make_case(kind_or_kinds, form, seed, outdir, name=None) -> truth dict
        kind_or_kinds : 'none' | one kind | list of kinds (mixture)
        form          : None (random) | form name | list of form names (one per kind)
    self_test() -> dict of results (prints them)

Output layout
-------------
    OUTDIR/<case>/id.csv, OUTDIR/<case>/<experiment>.csv      (blind data)
    OUTDIR/truth/<case>.json                                  (ground truth)
    OUTDIR/truth/summary.json                                 (all cases, ratios)
Case names (case_XXX) are shuffled and carry no information about the effect.

=============================================================================
SIMULATED ACTUATOR ("truth")
=============================================================================
Timeline.  All recordings of one case are simulated on ONE continuous global
timeline at 1 kHz: an unrecorded pre-history (0 V -> random level -> 0 V), the
identification sweep, then each experiment separated by an unrecorded gap
(ramp back to 0 V, rest 1-2 s).  Hysteresis memory, creep, filter states and
sensor drift therefore carry over between recordings as in a real lab session.

BASE = classical Preisach operator (rate-independent, wiping-out + congruency
exact).  Relays gamma(alpha,beta) in {0,1}, alpha >= beta, on [-100,100] V.
The weight density mu is integrated cell-exactly on a 400x400 grid (0.5 V cells,
80 200 relay cells) into the Everett-type table
    G(a,b) = mass{ beta' < b, beta' <= alpha' <= a }
and evaluated by bilinear interpolation (=> a continuous density).  The output
is computed from the alternating dominant-extrema (memory) stack:
    ascending from min m : y = y(m) + G(u,u) - G(u,m)
    descending from max M: y = y(M) - G(M,M) + G(M,u)
with wiping-out (pop of a max/min pair when exceeded).  Because the output
depends only on the memory stack through G, wiping-out and congruency hold
exactly (verified in self_test, which also checks the stack formula against a
brute-force relay simulation).
Densities (x = u/100, r=(a-b)/2, c=(a+b)/2), chosen per case:
  'gauss_rc'   : Gaussian in (r, c):  r0 in [0.05,0.35], sr in [0.06,0.3],
                 c0 in [-0.2,0.2], sc in [0.25,0.7]
  'lorentz_ab' : factorised Lorentzian 1/(1+((a-a0)/sa)^2) 1/(1+((b-b0)/sb)^2),
                 a0 in [-0.1,0.4], b0 = -a0 + U(-0.1,0.1), sa,sb in [0.1,0.5]
  'mixture'    : lognormal(r) x Gaussian(c) + second Gaussian blob + narrow
                 ridge on the diagonal (r < ~0.02, quasi-reversible)
Plus a single-valued reversible part (density on the diagonal)
    R(u) = norm(a x + (1-a) tanh(b x)), a in [0.3,1], b in [0.5,2.5].
y_base = offset + S [ h Y_irr(u) + (1-h) R(u) ],  Y_irr, R normalised to [0,1];
span S in [2,8] V, offset such that y(-100 V) = -S/2 + U(-0.8,0.8);
h chosen so the major-loop width = W*S with W ~ U[0.05,0.20].

Measurement: white Gaussian noise 3 mV RMS, then 14-bit quantisation over +-10 V
(LSB = 1.22 mV).

Effect size: each effect has one magnitude parameter which is tuned so that the
MEDIAN over the experiment recordings of RMS(y_with_effect - y_base)/3 mV
(noise-free signals, effect alone) hits a target drawn log-uniformly in
[4, 20] (single) or [4, 15] (each effect of a mixture).  Physical ranges are
respected where possible (the magnitude is clipped to its physical bounds; the
achieved ratio is what truth.json reports, per recording, per effect and for
the combined effects).

=============================================================================
EFFECT FORMS (3 per kind)
=============================================================================
rate_dependence  (dynamic hysteresis of piezoceramics: loops widen / change
                  shape as drive frequency grows)
  'relay_viscous_switching' : Mayergoyz-type dynamic Preisach model / viscous
        domain-wall motion: each relay switches at a finite speed,
        d gamma/dt = k (u-alpha) if u>alpha, k (u-beta) if u<beta, clipped to
        [0,1] (coarse 64x64 relay grid, same density, thresholds jittered inside cells); effect =
        g * (dynamic coarse output - static coarse output),
        k in [10,60] 1/(V s) (lowered once, down to >= 1, if g = 1 is not enough), fraction of viscous hysterons g in (0,1] (tuned).
  'debye_relaxation' : dielectric (Debye) relaxation of a slow polarisation
        component: part c of the reversible strain follows a first-order lag
        of the field, effect = c S (LP_tau(x) - x), tau in [2,12] ms; loops
        widen (elliptic, rate-proportional) and amplitude drops with
        frequency.  c tuned.
  'rate_dependent_play' : rate-dependent domain-wall pinning: the effective
        input to the Preisach operator passes a play (backlash) operator whose
        half-width grows with the smoothed input speed,
        delta = dmax r/(r+r0), r = LP_20ms(|du/dt|), r0 in [100,1000] V/s;
        dmax (tuned, <= 15 V).  Static (constant) play would be absorbed by a
        classical model -- only the rate dependence is non-classical.
creep  (slow drift of the displacement in the direction of the last input
        change, ~log(t), a few % per decade, following the input history)
  'log_kernel' : superposition of logarithmic step responses (Jung/Gweon,
        Changhai-Lining): effect = gamma * sum_i dy_i log10(1 + (t-t_i)/tau0),
        dy_i increments of the base output, tau0 in [0.01,0.1] s,
        gamma (per decade, tuned, bounds [0.2%,8%]).
  'kelvin_voigt_chain' : three Kelvin-Voigt (spring-dashpot) elements in
        series, tau_i ~ 0.05-0.2 s, 0.5-2 s, 3-10 s with weights w_i:
        effect = c sum_i w_i (LP_tau_i(y_b) - y_b): the output jumps to
        (1-c) of a step and creeps to the final value.  c tuned (<= 0.3).
  'power_law_input' : Findley power-law creep driven by the INPUT history:
        effect = kappa (S/200) sum_i du_i [((t-t_i)+tau0)^n - tau0^n],
        n in [0.05,0.25], tau0 in [0.005,0.05] s; kappa tuned.
delay  (pure transport / sampling delay in the measurement chain)
  'integer_samples' : digital buffering: y_meas(t) = y(t - d), d an integer
        number of samples (1-10 ms, tuned to the target).
  'fractional' : analog/sampling skew, non-integer delay d in [1,10] ms,
        linear interpolation of the continuous output at t - d.
  'fir_group_delay' : sigma-delta ADC decimation filter: linear-phase
        Hamming-windowed sinc FIR with 2D+1 taps, cutoff fc in [120,300] Hz;
        pure group delay D samples (1-10) plus mild smoothing.
structural_resonance  (lightly damped mechanical mode ringing after fast
        input changes)
  'single_mode' : one bending mode seen by the gauge: y = y_b + g (H*y_b - y_b),
        H = wn^2/(s^2+2 zeta wn s + wn^2) (ZOH-discretised),
        f in [40,300] Hz, zeta in [0.005,0.04]; modal participation g tuned.
  'two_mode_noncollocated' : two modes, f2/f1 in [2.5,5], second residue of
        random sign (non-collocated gauge): y = y_b + g1 (H1 y_b - y_b) +
        g2 (H2 y_b - y_b), |g2|/g1 in [0.3,1]; overall scale tuned.
  'mode_before_hysteresis' : the mode acts on the effective excitation of the
        ceramic (stress feedback of the ringing structure into the piezo
        layer): u_eff = u + g (H*u - u), y = Preisach[u_eff] -- rings pass
        through the hysteresis (asymmetric, amplitude-dependent ringing).
        g tuned (<= 1).
sensor_drift  (sensor zero drifts slowly with time, independent of input;
        the bridge is tared at the start of every recording, i.e. d(T) -
        d(T_start) is added, T = global lab-session time)
  'thermal_warmup' : A (1 - exp(-(T+T0)/tau)), tau in [60,200] s, A <= 1 V,
        T0 in [0,30] s, sign random; A tuned.
  'random_walk' : Brownian zero drift sigma W(T) (lightly low-passed, 0.5 s);
        sigma tuned.
  'linear_plus_cycle' : linear drift b T plus a slow thermal cycle
        A sin(2 pi T / P + phi), P in [30,200] s, A/(b P) random; scale tuned.
non_congruence  (minor loops between the same input extremes differ with the
        output level / history)
  'output_dependent_gain' : polarisation-dependent piezo coefficient: static
        monotone output map y = y_b + kappa S (z^2 - 1/12) (quadratic) or
        y = y_b + kappa S (z^3 - 3 z/20) (cubic), z = (y_b - y_mid)/S;
        minor-loop height scales with 1 + dPhi/dy at the loop's level.
        kappa tuned, |kappa| <= 0.9 (monotone).
  'moving_preisach' : Della Torre moving model / internal interaction field:
        the relays see u_eff = u + 100 k z(t-1) (output feedback),
        k in [-0.35,0.35] (sign random, magnitude tuned).
  'product_reversible' : reversible-irreversible coupling (product model):
        the reversible slope depends on the irreversible state s in [-1,1]:
        effect = kappa S max(1-h,0.15) s(t) (R(u) - 1/2); kappa tuned (<= 1.5).
=============================================================================
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy import signal

FS = 1000.0
DT = 1.0 / FS
UMIN, UMAX = -100.0, 100.0
NOISE_RMS = 0.003
NBITS = 14
YRANGE = 10.0

KINDS = ['rate_dependence', 'creep', 'delay', 'structural_resonance',
         'sensor_drift', 'non_congruence']
FORMS = {
    'rate_dependence': ['relay_viscous_switching', 'debye_relaxation', 'rate_dependent_play'],
    'creep': ['log_kernel', 'kelvin_voigt_chain', 'power_law_input'],
    'delay': ['integer_samples', 'fractional', 'fir_group_delay'],
    'structural_resonance': ['single_mode', 'two_mode_noncollocated', 'mode_before_hysteresis'],
    'sensor_drift': ['thermal_warmup', 'random_walk', 'linear_plus_cycle'],
    'non_congruence': ['output_dependent_gain', 'moving_preisach', 'product_reversible'],
}


def _f(x):
    return float(x)


# =============================================================================
# Classical Preisach base
# =============================================================================
class Preisach:
    """Classical Preisach operator with {0,1} relays on [-100,100] V, exact cell
    integration of a density on an n x n grid, bilinear-interpolated Everett
    table G(a,b) = mass{beta < b, beta <= alpha <= a}."""

    def __init__(self, density, n=400):
        self.n = n
        e = np.linspace(UMIN, UMAX, n + 1)
        self.edges = e
        h = e[1] - e[0]
        self.h = h
        # integrate density per cell with 3x3 Gauss points
        gp = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
        gw = np.array([5 / 9, 8 / 9, 5 / 9])
        cen = 0.5 * (e[:-1] + e[1:])
        W = np.zeros((n, n))
        for i, (pa, wa) in enumerate(zip(gp, gw)):
            for j, (pb, wb) in enumerate(zip(gp, gw)):
                A = (cen + pa * h / 2)[:, None]
                B = (cen + pb * h / 2)[None, :]
                W += wa * wb * density(A / 100.0, B / 100.0)
        W *= (h * h) / 4.0
        W = np.where(np.tril(np.ones((n, n), bool)), W, 0.0)  # alpha index p >= beta index q
        np.fill_diagonal(W, 0.5 * np.diag(W) + 1e-300)
        W = np.maximum(W, 0.0)
        self.total = W.sum()
        self.W = W / self.total  # normalised mass 1
        # G[i, j] = sum_{p<i, q<j} W[p, q]
        C = np.zeros((n + 1, n + 1))
        C[1:, 1:] = np.cumsum(np.cumsum(self.W, axis=0), axis=1)
        self.G = C
        self._Gflat = C.ravel().tolist()
        self._n1 = n + 1
        self._inv_h = 1.0 / h

    # scalar bilinear interpolation, b clamped to <= a
    def g(self, a, b):
        if b > a:
            b = a
        n = self.n
        x = (a - UMIN) * self._inv_h
        y = (b - UMIN) * self._inv_h
        if x < 0.0:
            x = 0.0
        elif x > n:
            x = float(n)
        if y < 0.0:
            return 0.0
        elif y > n:
            y = float(n)
        i = int(x)
        j = int(y)
        if i >= n:
            i = n - 1
        if j >= n:
            j = n - 1
        fx = x - i
        fy = y - j
        G = self._Gflat
        k = i * self._n1 + j
        g00 = G[k]
        g01 = G[k + 1]
        g10 = G[k + self._n1]
        g11 = G[k + self._n1 + 1]
        return (g00 * (1 - fx) * (1 - fy) + g01 * (1 - fx) * fy
                + g10 * fx * (1 - fy) + g11 * fx * fy)

    def run(self, u, fb=None):
        """Simulate from negative saturation.  u: array of inputs.
        fb: optional (k, ofs, scale) -> effective input u + k*100*((y-ofs)/scale)
        computed with the previous sample's normalised total output; y given by
        callback fb_out(yirr, ueff).  Returns (Y_irr in [0,1], u_eff)."""
        g = self.g
        S = [-1e300]
        Y = [0.0]
        up = UMIN
        y = 0.0
        N = len(u)
        out = np.empty(N)
        ueff = np.empty(N)
        ulist = u.tolist() if isinstance(u, np.ndarray) else list(u)
        fbk = None
        if fb is not None:
            fbk, fbfun = fb
        for t in range(N):
            x = ulist[t]
            if fbk is not None:
                x = x + fbk * fbfun(y, up)
            if x > UMAX:
                x = UMAX
            elif x < UMIN:
                x = UMIN
            if x > up:
                if len(S) % 2 == 0:        # was descending: up is a new minimum
                    S.append(up)
                    Y.append(y)
                while len(S) >= 3 and x >= S[-2]:
                    del S[-2:]
                    del Y[-2:]
                m = S[-1]
                y = Y[-1] + g(x, x) - (g(x, m) if m > -1e299 else 0.0)
            elif x < up:
                if len(S) % 2 == 1:        # was ascending: up is a new maximum
                    S.append(up)
                    Y.append(y)
                while len(S) >= 3 and x <= S[-2]:
                    del S[-2:]
                    del Y[-2:]
                M = S[-1]
                y = Y[-1] - g(M, M) + g(M, x)
            up = x
            out[t] = y
            ueff[t] = x
        return out, ueff


def brute_force_relays(W, edges, u):
    """Reference: explicit relay simulation; relay (p,q) up-threshold
    edges[p+1], down-threshold edges[q]; starting all down."""
    n = W.shape[0]
    A = edges[1:][:, None] * np.ones((1, n))
    B = edges[:-1][None, :] * np.ones((n, 1))
    mask = W > 0
    st = np.zeros((n, n), bool)
    out = []
    for x in u:
        st = np.where(x >= A, True, np.where(x <= B, False, st))
        out.append(float((W * (st & mask)).sum()))
    return np.array(out)


def make_density(rng, kind):
    if kind == 'gauss_rc':
        r0, sr = rng.uniform(0.05, 0.35), rng.uniform(0.06, 0.3)
        c0, sc = rng.uniform(-0.2, 0.2), rng.uniform(0.25, 0.7)
        p = dict(r0=r0, sr=sr, c0=c0, sc=sc)

        def mu(a, b):
            r, c = (a - b) / 2, (a + b) / 2
            return np.exp(-(r - r0) ** 2 / (2 * sr ** 2)) * np.exp(-(c - c0) ** 2 / (2 * sc ** 2))
    elif kind == 'lorentz_ab':
        a0 = rng.uniform(-0.1, 0.4)
        b0 = -a0 + rng.uniform(-0.1, 0.1)
        sa, sb = rng.uniform(0.1, 0.5), rng.uniform(0.1, 0.5)
        p = dict(a0=a0, b0=b0, sa=sa, sb=sb)

        def mu(a, b):
            return 1 / (1 + ((a - a0) / sa) ** 2) / (1 + ((b - b0) / sb) ** 2)
    else:
        m, s = math.log(rng.uniform(0.08, 0.3)), rng.uniform(0.3, 0.8)
        c0, sc = rng.uniform(-0.2, 0.2), rng.uniform(0.3, 0.8)
        r1, c1, s1 = rng.uniform(0.2, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(0.05, 0.15)
        w1 = rng.uniform(0.1, 0.5)
        wr = rng.uniform(0.5, 3.0)
        p = dict(logr_mean=m, logr_sd=s, c0=c0, sc=sc, blob_r=r1, blob_c=c1, blob_s=s1,
                 blob_w=w1, ridge_w=wr)

        def mu(a, b):
            r, c = (a - b) / 2, (a + b) / 2
            rr = np.maximum(r, 1e-4)
            v = np.exp(-(np.log(rr) - m) ** 2 / (2 * s * s)) / rr * np.exp(-(c - c0) ** 2 / (2 * sc * sc))
            v = v + w1 * 10 * np.exp(-((r - r1) ** 2 + (c - c1) ** 2) / (2 * s1 * s1))
            v = v + wr * 5 * np.exp(-r / 0.01) * np.exp(-c ** 2 / 0.5)
            return v
    return mu, p


class Base:
    def __init__(self, rng, density_kind=None):
        dk = density_kind or rng.choice(['gauss_rc', 'lorentz_ab', 'mixture'])
        for _attempt in range(50):
            mu, dp = make_density(rng, dk)
            P = Preisach(mu)
            # major loop width of the irreversible part
            uu = np.concatenate([np.linspace(-100, 100, 401), np.linspace(100, -100, 401)])
            yy, _ = P.run(uu)
            asc, desc = yy[:401], yy[401:][::-1]
            w0 = float(np.max(desc - asc))
            W = rng.uniform(0.05, 0.20)
            if w0 >= W * 1.05:
                break
        self.P = P
        self.density_kind = str(dk)
        self.density_params = {k: _f(v) for k, v in dp.items()}
        self.w0 = w0
        self.W = W
        self.h = W / w0
        self.ra = rng.uniform(0.3, 1.0)
        self.rb = rng.uniform(0.5, 2.5)
        self.S = rng.uniform(2.0, 8.0)
        self.y_lo = -self.S / 2 + rng.uniform(-0.8, 0.8)
        r1 = self.ra + (1 - self.ra) * math.tanh(self.rb)
        self._rnorm = r1
        self.y_mid = self.y_lo + self.S / 2

    def R(self, u):
        x = np.clip(np.asarray(u, float), UMIN, UMAX) / 100.0
        v = self.ra * x + (1 - self.ra) * np.tanh(self.rb * x)
        return 0.5 * (v / self._rnorm + 1.0)

    def combine(self, yirr, ueff):
        return self.y_lo + self.S * (self.h * yirr + (1 - self.h) * self.R(ueff))

    def sim(self, u, fb_k=None):
        if fb_k is None:
            yirr, ueff = self.P.run(u)
        else:
            h, S, ra, rb, rn = self.h, self.S, self.ra, self.rb, self._rnorm

            def fbfun(yirr_prev, ueff_prev):
                x = ueff_prev / 100.0
                rv = 0.5 * ((ra * x + (1 - ra) * math.tanh(rb * x)) / rn + 1.0)
                z = h * yirr_prev + (1 - h) * rv - 0.5
                return 100.0 * z
            yirr, ueff = self.P.run(u, fb=(fb_k, fbfun))
        return self.combine(yirr, ueff), yirr, ueff

    def info(self):
        return dict(density=self.density_kind, density_params=self.density_params,
                    span_V=_f(self.S), y_at_minus100_V=_f(self.y_lo), irr_fraction_h=_f(self.h),
                    major_loop_width_fraction=_f(self.W), reversible_a=_f(self.ra),
                    reversible_b=_f(self.rb), grid='400x400 cells (0.5 V), bilinear Everett')


# =============================================================================
# Input signals
# =============================================================================
def cos_leg(u0, u1, T):
    n = max(2, int(round(T * FS)))
    s = np.arange(1, n + 1) / n
    return u0 + (u1 - u0) * 0.5 * (1 - np.cos(np.pi * s))


def legs(points, T):
    out = []
    for a, b in zip(points[:-1], points[1:]):
        out.append(cos_leg(a, b, T if np.isscalar(T) else T.pop(0)))
    return np.concatenate(out)


def sig_id():
    u = [cos_leg(0.0, -100.0, 0.5)]
    for k in range(20, 0, -1):
        ak = -100.0 + 10.0 * k
        u.append(cos_leg(-100.0, ak, 0.5))
        u.append(cos_leg(ak, -100.0, 0.5))
    u = np.concatenate(u)
    return np.concatenate([[0.0], u])          # 20.5 s + 1 sample


def sig_wipeout(rng):
    u0 = rng.choice([-1, 1]) * rng.uniform(60, 95)
    s = np.sign(u0)
    pts = [u0]
    amps = sorted(rng.uniform(5, 90, size=8), reverse=True)
    for i, a in enumerate(amps):
        pts.append(-s * a if i % 2 == 0 else s * a)
    pts += [s * rng.uniform(96, 100) * (-1), s * rng.uniform(70, 95)]
    T = rng.uniform(0.7, 1.0)
    u = np.concatenate([np.full(int(rng.uniform(0.5, 1.0) * FS), u0), legs(pts, T),
                        np.full(int(1.0 * FS), pts[-1])])
    return u, True


def sig_cml(rng):
    amp = rng.uniform(15, 35)
    offs = np.sort(rng.uniform(-55, 55, size=4))
    f = float(rng.choice([1.0, 1.5]))
    cyc = 2 if f == 1.0 else 3
    pts = [0.0]
    for o in rng.permutation(offs):
        s = rng.choice([-1, 1])
        a = o + s * rng.uniform(40, 60)
        if abs(a) > 100:
            a = o - s * rng.uniform(40, 60)
        pts.append(float(np.clip(a, -100, 100)))
        for _ in range(cyc):
            pts += [o + s * amp / 2, o - s * amp / 2]
    u = legs(pts, 0.5 / f)
    step = rng.random() < 0.5
    if step:      # start-up jump straight to the first approach level
        u = np.concatenate([np.full(300, pts[1]), u[int(round(0.5 / f * FS)):]])
    return u, bool(step)


def sig_multisine(rng):
    T = rng.uniform(8, 12)
    t = np.arange(int(T * FS)) / FS
    fr = np.array([0.5, 1.3, 3.1, 7.7, 17.0, 37.0]) * rng.uniform(0.9, 1.08, size=6)
    fr = np.clip(fr, 0.5, 40)
    amp = fr ** -0.8
    ph = rng.uniform(0, 2 * np.pi, size=6)
    u = (amp[:, None] * np.sin(2 * np.pi * fr[:, None] * t[None, :] + ph[:, None])).sum(0)
    u = u / np.max(np.abs(u)) * rng.uniform(75, 95)
    step = abs(u[0]) > 15
    if not step:    # smooth fade-in instead of a small jump
        u = u * np.clip(np.arange(len(u)) / 500.0, 0, 1)
    return u, bool(step)


def sig_steps(rng):
    T = rng.uniform(9, 14)
    u = []
    tot = 0
    while tot < T * FS:
        n = int(rng.uniform(1, 3) * FS)
        lvl = rng.uniform(-90, 90)
        while abs(lvl - (u[-1][0] if u else 0.0)) < 25:
            lvl = rng.uniform(-90, 90)
        u.append(np.full(n, lvl))
        tot += n
    return np.concatenate(u)[: int(T * FS)], True


def sig_noise(rng):
    T = rng.uniform(8, 12)
    n = int(T * FS)
    fc = rng.uniform(5, 20)
    b, a = signal.butter(4, fc / (FS / 2))
    w = signal.lfilter(b, a, rng.standard_normal(n + 2000))[2000:]
    w = w / w.std() * rng.uniform(35, 50)
    u = 100 * np.tanh(w / 100)
    step = rng.random() < 0.5
    if not step:
        u = u * np.clip(np.arange(n) / 500.0, 0, 1)
    else:
        if abs(u[0]) < 20:
            u = u + np.sign(rng.standard_normal()) * 30 * np.exp(-np.arange(n) / 3000.0)
            u = np.clip(u, -100, 100)
    return u, step


EXPERIMENTS = [('wipeout', sig_wipeout), ('cml', sig_cml), ('multisine', sig_multisine),
               ('steps', sig_steps), ('noise', sig_noise)]


def build_timeline(rng):
    segs = []
    recs = []
    # pre-history (unrecorded)
    a = rng.uniform(-100, 100)
    pre = np.concatenate([np.zeros(200), cos_leg(0, a, 0.7), cos_leg(a, 0, 0.7), np.zeros(600)])
    segs.append(pre)
    pos = len(pre)
    names = [e for e in EXPERIMENTS]
    if rng.random() < 0.35:   # 4 experiments: drop one (never 'steps' / 'wipeout')
        drop = rng.choice(['cml', 'multisine', 'noise'])
        names = [e for e in names if e[0] != drop]
    order = [names[i] for i in rng.permutation(len(names))]
    plan = [('id', lambda r: (sig_id(), False))] + order
    for nm, fn in plan:
        u, step = fn(rng)
        u = np.asarray(u, float)
        if step:      # recording shows 0 V first, then the start-up jump
            u = np.concatenate([np.zeros(int(rng.uniform(0.1, 0.3) * FS)), u])
        recs.append(dict(name=nm, start=pos, n=len(u), step_start=bool(step)))
        segs.append(u)
        pos += len(u)
        gap = np.concatenate([cos_leg(u[-1], 0.0, 0.5), np.zeros(int(rng.uniform(1.0, 2.0) * FS))])
        segs.append(gap)
        pos += len(gap)
    return np.concatenate(segs), recs


# =============================================================================
# Effects
# =============================================================================
def lp1(x, tau):
    a = math.exp(-DT / tau)
    return signal.lfilter([1 - a], [1, -a], x, zi=[a * x[0]])[0]


def mode_filter(x, f, zeta):
    wn = 2 * np.pi * f
    sysd = signal.cont2discrete(([wn ** 2], [1, 2 * zeta * wn, wn ** 2]), DT, method='zoh')
    b = np.ravel(sysd[0])
    a = np.ravel(sysd[1])
    zi = signal.lfilter_zi(b, a) * x[0]
    return signal.lfilter(b, a, x, zi=zi)[0]


class Effect:
    """stage: 'input' (modifies the Preisach input / feedback), 'add' (additive
    term computed from the simulation), 'output' (acts on y), 'sensor'.
    mag: tuned magnitude; lo/hi physical bounds; linear: effect linear in mag."""
    stage = 'output'
    linear = True

    def __init__(self, kind, form, rng, base):
        self.kind, self.form, self.base = kind, form, base
        self.p = {}
        self.mag = 1.0
        self.lo, self.hi = 1e-6, 1e6
        self.mag_name = 'scale'
        getattr(self, 'init_' + form)(rng)

    # --- rate dependence -------------------------------------------------
    def init_relay_viscous_switching(self, rng):
        self.stage = 'add'
        self.p['k_per_Vs'] = rng.uniform(10, 60)
        self.p['jitter_seed'] = int(rng.integers(2 ** 31))
        self.mag_name, self.lo, self.hi = 'viscous_fraction_g', 0.0, 1.0
        self._cache = None

    def add_relay_viscous_switching(self, ctx):
        if self._cache is None:
            n = 64
            P = self.base.P
            idx = np.round(np.linspace(0, P.n, n + 1)).astype(int)
            e = P.edges[idx]
            # coarse weights = fine mass aggregated; thresholds jittered inside cells
            Wc = np.add.reduceat(np.add.reduceat(P.W, idx[:-1], axis=0), idx[:-1], axis=1)
            jr = np.random.default_rng(self.p['jitter_seed'])
            hc = e[1] - e[0]
            A = np.repeat(e[:-1][:, None], n, 1) + hc * jr.random((n, n))
            B = np.repeat(e[:-1][None, :], n, 0) + hc * jr.random((n, n))
            m = (Wc > 0) & (A >= B)
            Wc = np.where(m, Wc, 0.0)
            A, B, w = A[m], B[m], Wc[m] / Wc[m].sum()
            k = self.p['k_per_Vs'] * DT
            K = np.array([[k], [1e9]])          # row 0: viscous relays, row 1: ideal relays
            g2 = np.zeros((2, len(w)))
            u = ctx['ueff']
            yy = np.empty((len(u), 2))
            mx, mn, clip = np.maximum, np.minimum, np.clip
            for t, x in enumerate(u.tolist()):
                d = mx(x - A, 0.0)
                d += mn(x - B, 0.0)
                g2 += K * d
                clip(g2, 0.0, 1.0, out=g2)
                yy[t] = g2 @ w
            yd, ys = yy[:, 0], yy[:, 1]
            self._cache = self.base.S * self.base.h * (yd - ys)
        return self.mag * self._cache

    def init_debye_relaxation(self, rng):
        self.stage = 'add'
        self.p['tau_s'] = rng.uniform(0.002, 0.012)
        self.mag_name, self.lo, self.hi = 'relaxing_fraction_c', 0.0, 0.5

    def add_debye_relaxation(self, ctx):
        x = ctx['ueff'] / 100.0
        return self.mag * self.base.S * 0.5 * (lp1(x, self.p['tau_s']) - x)

    def init_rate_dependent_play(self, rng):
        self.stage, self.linear = 'input', False
        self.p['r0_V_per_s'] = rng.uniform(100, 1000)
        self.p['rate_filter_tau_s'] = 0.02
        self.mag_name, self.lo, self.hi, self.mag = 'dmax_V', 0.05, 15.0, 3.0

    def input_rate_dependent_play(self, u):
        r = lp1(np.abs(np.diff(u, prepend=u[0])) * FS, 0.02)
        dl = (self.mag * r / (r + self.p['r0_V_per_s'])).tolist()
        out = np.empty(len(u))
        v = float(u[0])
        for t, x in enumerate(u.tolist()):
            d = dl[t]
            if v < x - d:
                v = x - d
            elif v > x + d:
                v = x + d
            out[t] = v
        return out

    # --- creep -----------------------------------------------------------
    def init_log_kernel(self, rng):
        self.p['tau0_s'] = rng.uniform(0.01, 0.1)
        self.mag_name, self.lo, self.hi, self.mag = 'gamma_per_decade', 0.002, 0.08, 0.02

    def out_log_kernel(self, y, ctx):
        dy = np.diff(ctx['ybase'], prepend=ctx['ybase'][0])
        k = np.log10(1 + np.arange(len(y)) * DT / self.p['tau0_s'])
        return y + self.mag * signal.fftconvolve(dy, k)[:len(y)]

    def init_kelvin_voigt_chain(self, rng):
        self.p['taus_s'] = [rng.uniform(0.05, 0.2), rng.uniform(0.5, 2.0), rng.uniform(3, 10)]
        w = rng.dirichlet([2, 2, 2])
        self.p['weights'] = [float(v) for v in w]
        self.mag_name, self.lo, self.hi, self.mag = 'creep_fraction_c', 0.001, 0.3, 0.05

    def out_kelvin_voigt_chain(self, y, ctx):
        yb = ctx['ybase']
        e = sum(w * (lp1(yb, tau) - yb) for w, tau in zip(self.p['weights'], self.p['taus_s']))
        return y + self.mag * e

    def init_power_law_input(self, rng):
        self.p['n'] = rng.uniform(0.05, 0.25)
        self.p['tau0_s'] = rng.uniform(0.005, 0.05)
        self.mag_name, self.lo, self.hi, self.mag = 'kappa', 1e-4, 1.0, 0.05

    def out_power_law_input(self, y, ctx):
        u = ctx['u']
        du = np.diff(u, prepend=u[0])
        tt = np.arange(len(y)) * DT
        k = (tt + self.p['tau0_s']) ** self.p['n'] - self.p['tau0_s'] ** self.p['n']
        return y + self.mag * self.base.S / 200.0 * signal.fftconvolve(du, k)[:len(y)]

    # --- delay -----------------------------------------------------------
    def init_integer_samples(self, rng):
        self.stage, self.linear = 'sensor', False
        self.mag_name, self.lo, self.hi, self.mag = 'delay_samples', 1, 10, 3
        self.discrete = True

    def sensor_integer_samples(self, y, ctx):
        d = int(round(self.mag))
        return np.concatenate([np.full(d, y[0]), y[:-d]]) if d > 0 else y

    def init_fractional(self, rng):
        self.stage, self.linear = 'sensor', False
        self.mag_name, self.lo, self.hi, self.mag = 'delay_ms', 1.0, 10.0, 3.3

    def sensor_fractional(self, y, ctx):
        t = np.arange(len(y), dtype=float)
        return np.interp(t - self.mag, t, y)

    def init_fir_group_delay(self, rng):
        self.stage, self.linear = 'sensor', False
        self.p['cutoff_Hz'] = rng.uniform(120, 300)
        self.mag_name, self.lo, self.hi, self.mag = 'group_delay_samples', 1, 10, 3
        self.discrete = True

    def sensor_fir_group_delay(self, y, ctx):
        D = int(round(self.mag))
        h = signal.firwin(2 * D + 1, self.p['cutoff_Hz'], fs=FS, window='hamming')
        yp = np.concatenate([np.full(2 * D, y[0]), y])
        return np.convolve(yp, h, mode='valid')

    # --- structural resonance ---------------------------------------------
    def init_single_mode(self, rng):
        self.p['f_Hz'] = rng.uniform(40, 300)
        self.p['zeta'] = math.exp(rng.uniform(math.log(0.005), math.log(0.04)))
        self.mag_name, self.lo, self.hi, self.mag = 'modal_participation_g', 1e-3, 3.0, 0.1

    def out_single_mode(self, y, ctx):
        yb = ctx['ybase']
        return y + self.mag * (mode_filter(yb, self.p['f_Hz'], self.p['zeta']) - yb)

    def init_two_mode_noncollocated(self, rng):
        f1 = rng.uniform(40, 110)
        self.p['f_Hz'] = [f1, f1 * rng.uniform(2.5, 4.2)]
        self.p['zeta'] = [math.exp(rng.uniform(math.log(0.005), math.log(0.04))) for _ in range(2)]
        self.p['g2_over_g1'] = float(rng.choice([-1, 1]) * rng.uniform(0.3, 1.0))
        self.mag_name, self.lo, self.hi, self.mag = 'g1', 1e-3, 3.0, 0.1

    def out_two_mode_noncollocated(self, y, ctx):
        yb = ctx['ybase']
        e = (mode_filter(yb, self.p['f_Hz'][0], self.p['zeta'][0]) - yb) \
            + self.p['g2_over_g1'] * (mode_filter(yb, self.p['f_Hz'][1], self.p['zeta'][1]) - yb)
        return y + self.mag * e

    def init_mode_before_hysteresis(self, rng):
        self.stage, self.linear = 'input', False
        self.p['f_Hz'] = rng.uniform(40, 300)
        self.p['zeta'] = math.exp(rng.uniform(math.log(0.005), math.log(0.04)))
        self.mag_name, self.lo, self.hi, self.mag = 'modal_participation_g', 1e-3, 1.0, 0.1

    def input_mode_before_hysteresis(self, u):
        return u + self.mag * (mode_filter(u, self.p['f_Hz'], self.p['zeta']) - u)

    # --- sensor drift ----------------------------------------------------
    def init_thermal_warmup(self, rng):
        self.stage = 'sensor'
        self.p['tau_s'] = rng.uniform(60, 200)
        self.p['T0_s'] = rng.uniform(0, 30)
        self.p['sign'] = float(rng.choice([-1, 1]))
        self.mag_name, self.lo, self.hi, self.mag = 'amplitude_V', 1e-3, 1.0, 0.05

    def sensor_thermal_warmup(self, y, ctx):
        T = np.arange(len(y)) * DT
        d = self.p['sign'] * self.mag * (1 - np.exp(-(T + self.p['T0_s']) / self.p['tau_s']))
        return y + tare(d, ctx)

    def init_random_walk(self, rng):
        self.stage = 'sensor'
        self._w = None
        self._seed = int(rng.integers(2 ** 31))
        self.mag_name, self.mag = 'sigma_V_per_sqrt_s', 0.01

    def sensor_random_walk(self, y, ctx):
        if self._w is None:
            r = np.random.default_rng(self._seed)
            self._w = lp1(np.cumsum(r.standard_normal(len(y))) * math.sqrt(DT), 0.5)
        return y + tare(self.mag * self._w, ctx)

    def init_linear_plus_cycle(self, rng):
        self.stage = 'sensor'
        self.p['period_s'] = rng.uniform(30, 200)
        self.p['phase'] = rng.uniform(0, 2 * np.pi)
        self.p['slope_rel'] = float(rng.choice([-1, 1]) * rng.uniform(0.2, 2.0))
        self.mag_name, self.mag = 'cycle_amplitude_V', 0.05

    def sensor_linear_plus_cycle(self, y, ctx):
        T = np.arange(len(y)) * DT
        P = self.p['period_s']
        d = self.mag * (np.sin(2 * np.pi * T / P + self.p['phase']) + self.p['slope_rel'] * T / P)
        return y + tare(d, ctx)

    # --- non congruence --------------------------------------------------
    def init_output_dependent_gain(self, rng):
        self.p['shape'] = str(rng.choice(['quadratic', 'cubic']))
        self.p['sign'] = float(rng.choice([-1, 1]))
        self.mag_name, self.lo, self.hi, self.mag = 'kappa', 1e-3, 0.9, 0.2

    def out_output_dependent_gain(self, y, ctx):
        b = self.base
        z = (y - b.y_mid) / b.S
        if self.p['shape'] == 'quadratic':
            e = z ** 2 - 1.0 / 12
        else:
            e = z ** 3 - 3 * z / 20
        return y + self.p['sign'] * self.mag * b.S * e

    def init_moving_preisach(self, rng):
        self.stage, self.linear = 'input', False
        self.p['sign'] = float(rng.choice([-1, 1]))
        self.mag_name, self.lo, self.hi, self.mag = 'abs_k', 1e-3, 0.35, 0.05

    def init_product_reversible(self, rng):
        self.stage = 'add'
        self.p['sign'] = float(rng.choice([-1, 1]))
        self.mag_name, self.lo, self.hi, self.mag = 'kappa', 1e-3, 1.5, 0.3

    def add_product_reversible(self, ctx):
        b = self.base
        s = 2 * ctx['yirr'] - 1
        return self.p['sign'] * self.mag * b.S * max(1 - b.h, 0.15) * s * (b.R(ctx['ueff']) - 0.5)

    def truth(self):
        d = dict(kind=self.kind, form=self.form, magnitude_name=self.mag_name,
                 magnitude=_f(self.mag), params=self.p)
        return json.loads(json.dumps(d, default=float))


def tare(d, ctx):
    """zero the drift at the start of every recording (bridge tared)"""
    out = np.zeros_like(d)
    starts = [r['start'] for r in ctx['recs']] + [len(d)]
    out[:starts[0]] = d[:starts[0]] - d[0]
    for i, r in enumerate(ctx['recs']):
        a, b = r['start'], starts[i + 1]
        out[a:b] = d[a:b] - d[a]
    return out


def simulate(base, u, recs, effects):
    """noise-free measured output for a list of effects (pipeline order:
    input -> Preisach -> additive -> output -> sensor)."""
    ctx = dict(u=u, recs=recs)
    ui = u
    fbk = None
    for e in effects:
        if e.stage == 'input':
            if e.form == 'moving_preisach':
                fbk = e.p['sign'] * e.mag
            else:
                ui = getattr(e, 'input_' + e.form)(ui)
    if fbk is None and ui is u and getattr(base, '_cache_u', None) is u:
        y, yirr, ueff = base._cache_res
    else:
        y, yirr, ueff = base.sim(ui, fb_k=fbk)
        if fbk is None and ui is u:
            base._cache_u, base._cache_res = u, (y, yirr, ueff)
    ctx.update(yirr=yirr, ueff=ueff, ybase=y)
    for e in effects:
        if e.stage == 'add':
            y = y + getattr(e, 'add_' + e.form)(ctx)
    ctx['ybase'] = y.copy() if any(e.stage == 'add' for e in effects) else y
    for e in effects:
        if e.stage == 'output':
            y = getattr(e, 'out_' + e.form)(y, ctx)
    for e in effects:
        if e.stage == 'sensor':
            y = getattr(e, 'sensor_' + e.form)(y, ctx)
    return y


def rec_ratios(delta, recs):
    return {r['name']: _f(np.sqrt(np.mean(delta[r['start']:r['start'] + r['n']] ** 2)) / NOISE_RMS)
            for r in recs}


def median_exp_ratio(rat):
    return float(np.median([v for k, v in rat.items() if k != 'id']))


def tune(base, u, recs, e, y0, target):
    """set e.mag so that the median experiment ratio ~ target (within bounds)."""
    def ratio(m):
        e.mag = m
        d = simulate(base, u, recs, [e]) - y0
        return median_exp_ratio(rec_ratios(d, recs))
    if e.linear and e.stage != 'input':
        m0 = e.mag
        r0 = ratio(m0)
        m = m0 * target / max(r0, 1e-12)
        e.mag = float(np.clip(m, e.lo, e.hi))
        if m > e.hi and e.form == 'relay_viscous_switching':
            # slower hysterons (smaller k) -> larger dynamic lag; ratio ~ k^-1/2
            rmax = r0 * e.hi / m0
            e.p['k_per_Vs'] = float(max(1.0, e.p['k_per_Vs'] * (rmax / target) ** 2))
            e._cache = None
            e.mag = m0
            r0 = ratio(m0)
            e.mag = float(np.clip(m0 * target / max(r0, 1e-12), e.lo, e.hi))
        return
    if getattr(e, 'discrete', False):
        best = None
        for m in range(int(e.lo), int(e.hi) + 1):
            r = ratio(m)
            sc = abs(math.log(max(r, 1e-9) / target))
            if best is None or sc < best[0]:
                best = (sc, m)
            if r > target * 1.5:
                break
        e.mag = best[1]
        return
    # log-log secant / bisection on [lo, hi]
    lo, hi = math.log(e.lo), math.log(e.hi)
    m = math.log(np.clip(e.mag, e.lo, e.hi))
    r = ratio(math.exp(m))
    pts = [(m, math.log(max(r, 1e-9)))]
    lt = math.log(target)
    for _it in range(7):
        if abs(pts[-1][1] - lt) < 0.08:
            break
        if len(pts) == 1:
            slope = 1.0
        else:
            (m1, r1), (m2, r2) = pts[-2], pts[-1]
            slope = (r2 - r1) / (m2 - m1) if m2 != m1 else 1.0
            if not (0.2 < slope < 5):
                slope = 1.0
        mn = float(np.clip(pts[-1][0] + (lt - pts[-1][1]) / slope, lo, hi))
        if mn == pts[-1][0]:
            break
        r = ratio(math.exp(mn))
        pts.append((mn, math.log(max(r, 1e-9))))
    best = min(pts, key=lambda p: abs(p[1] - lt))
    e.mag = math.exp(best[0])


# =============================================================================
# Case generation
# =============================================================================
def quantise(y):
    lsb = 2 * YRANGE / 2 ** NBITS
    q = np.clip(np.round((y + YRANGE) / lsb), 0, 2 ** NBITS - 1)
    return q * lsb - YRANGE


def write_csv(path, name, u, y):
    lines = ['# sample_time: 0.001', '# input_units: V', '# output_units: V',
             '# experiment: ' + name, 't,u,y']
    ul, yl = u.tolist(), y.tolist()
    lines += ['%r,%r,%r' % (k / 1000, ul[k], yl[k]) for k in range(len(ul))]
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')


def make_case(kind_or_kinds, form=None, seed=0, outdir='.', name=None):
    kinds = [kind_or_kinds] if isinstance(kind_or_kinds, str) else list(kind_or_kinds)
    kinds = [k for k in kinds if k != 'none']
    forms = [form] if isinstance(form, str) or form is None else list(form)
    if len(forms) < len(kinds):
        forms = forms + [None] * (len(kinds) - len(forms))
    rng = np.random.default_rng(seed)
    name = name or 'case_s%d' % seed
    base = Base(rng)
    u, recs = build_timeline(rng)
    y0 = simulate(base, u, recs, [])
    effects = []
    for k, f in zip(kinds, forms):
        f = f or str(rng.choice(FORMS[k]))
        e = Effect(k, f, rng, base)
        target = math.exp(rng.uniform(math.log(4), math.log(20 if len(kinds) == 1 else 15)))
        tune(base, u, recs, e, y0, target)
        d = simulate(base, u, recs, [e]) - y0
        e.target = target
        e.ratios = rec_ratios(d, recs)
        effects.append(e)
    y = simulate(base, u, recs, effects)
    comb = rec_ratios(y - y0, recs)
    nr = np.random.default_rng(seed + 7919)
    ym = quantise(y + NOISE_RMS * nr.standard_normal(len(y)))
    cdir = os.path.join(outdir, name)
    os.makedirs(cdir, exist_ok=True)
    os.makedirs(os.path.join(outdir, 'truth'), exist_ok=True)
    files = []
    for r in recs:
        a, b = r['start'], r['start'] + r['n']
        fn = r['name'] + '.csv'
        write_csv(os.path.join(cdir, fn), r['name'], u[a:b], ym[a:b])
        files.append(dict(file=fn, experiment=r['name'], duration_s=r['n'] / FS,
                          starts_with_step=r['step_start'],
                          global_start_s=r['start'] / FS))
    truth = dict(case=name, seed=int(seed), kinds=kinds if kinds else ['none'],
                 forms=[e.form for e in effects],
                 effects=[dict(e.truth(), target_median_ratio=_f(e.target),
                               effect_to_noise_rms_ratio=e.ratios,
                               median_experiment_ratio=median_exp_ratio(e.ratios))
                          for e in effects],
                 combined_effect_to_noise_rms_ratio=comb,
                 combined_median_experiment_ratio=median_exp_ratio(comb),
                 noise_rms_V=NOISE_RMS, quantisation='14 bit over +-10 V',
                 base=base.info(), recordings=files)
    with open(os.path.join(outdir, 'truth', name + '.json'), 'w') as f:
        json.dump(truth, f, indent=1, default=float)
    return truth


# =============================================================================
# Self test
# =============================================================================
def self_test(verbose=True):
    res = {}
    rng = np.random.default_rng(123)
    for dk in ['gauss_rc', 'lorentz_ab', 'mixture']:
        b = Base(rng, dk)
        P = b.P
        # wiping-out: inner loop (50 / -20) is erased once the input exceeds 50;
        # afterwards the output must equal that of the history without it
        tail = np.concatenate([cos_leg(65, -10, 1), cos_leg(-10, 30, 1), cos_leg(30, 60, 1)])
        hA = np.concatenate([cos_leg(-100, 80, 1), cos_leg(80, -60, 1), cos_leg(-60, 50, 1),
                             cos_leg(50, -20, 1), cos_leg(-20, 65, 1), tail])
        hB = np.concatenate([cos_leg(-100, 80, 1), cos_leg(80, -60, 1), cos_leg(-60, 65, 1), tail])
        yA, _ = P.run(hA)
        yB, _ = P.run(hB)
        wipe_err = float(np.max(np.abs(yA[-len(tail) - 1:] - yB[-len(tail) - 1:])))
        # congruency: minor loop 10 <-> 40 V reached (descending) after two different
        # histories: loops must be identical up to a vertical shift
        loop = np.concatenate([cos_leg(10, 40, 0.5), cos_leg(40, 10, 0.5)] * 2)
        h1 = np.concatenate([cos_leg(-100, 100, 1), cos_leg(100, 10, 1), loop])
        h2 = np.concatenate([cos_leg(-100, 70, 1), cos_leg(70, -30, 1), cos_leg(-30, 60, 1),
                             cos_leg(60, 10, 1), loop])
        y1, _ = P.run(h1)
        y2, _ = P.run(h2)
        L = len(loop)
        l1 = y1[-L:] - y1[-L - 1]
        l2 = y2[-L:] - y2[-L - 1]
        cong_err = float(np.max(np.abs(l1 - l2)))
        loop_h = float(np.max(l1) - np.min(l1))
        lvl_diff = float(abs(y1[-L - 1] - y2[-L - 1]))
        # brute force relays on a coarse version with grid-aligned inputs
        Pc = Preisach(make_density(np.random.default_rng(5), dk)[0], n=40)
        ug = np.round(np.concatenate([[-100], rng.uniform(-100, 100, 150)]) / 5) * 5
        ug = np.concatenate([cos_leg(a, c, 0.02) for a, c in zip(ug[:-1], ug[1:])])
        ug = np.round(ug / 5) * 5
        ys, _ = Pc.run(ug)
        yb = brute_force_relays(Pc.W, Pc.edges, ug)
        bf_err = float(np.max(np.abs(ys - yb)))
        res[dk] = dict(wiping_out_max_err=float(wipe_err), congruency_max_err=cong_err,
                       minor_loop_height=loop_h, level_difference_between_loops=lvl_diff, brute_force_relay_max_err=bf_err,
                       major_loop_width_fraction=float(b.W), span_V=float(b.S))
    ok = all(v['wiping_out_max_err'] < 1e-9 and v['congruency_max_err'] < 1e-9
             and v['brute_force_relay_max_err'] < 1e-9 for v in res.values())
    res['PASS'] = bool(ok)
    if verbose:
        for k, v in res.items():
            print('self_test', k, v)
    return res


# =============================================================================
def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument('outdir', nargs='?')
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--cases-per-kind', type=int, default=3)
    ap.add_argument('--self-test', action='store_true')
    a = ap.parse_args(argv)
    if a.self_test or not a.outdir:
        self_test()
        if not a.outdir:
            return
    t0 = time.time()
    rng = np.random.default_rng(a.seed)
    N = a.cases_per_kind
    specs = []
    for k in KINDS:
        off = int(rng.integers(3))
        for i in range(N):
            specs.append(([k], [FORMS[k][(i + off) % 3]]))
    nextra = max(1, math.ceil(4 * N / 3))
    specs += [(['none'], []) for _ in range(nextra)]
    for _ in range(nextra):
        k2 = list(rng.choice(KINDS, size=2, replace=False))
        specs.append(([str(k) for k in k2], [None, None]))
    order = rng.permutation(len(specs))
    os.makedirs(a.outdir, exist_ok=True)
    summary = []
    for ci, si in enumerate(order):
        kinds, forms = specs[si]
        name = 'case_%03d' % (ci + 1)
        seed = int(a.seed * 100000 + ci + 1)
        tc = time.time()
        tr = make_case(kinds, forms if forms else None, seed, a.outdir, name)
        per = {e['kind'] + '/' + e['form']: e['median_experiment_ratio'] for e in tr['effects']}
        print('%s %-45s comb_median=%6.2f  %s  (%.1fs)' % (
            name, '+'.join(tr['kinds']) + ' ' + ','.join(tr['forms']),
            tr['combined_median_experiment_ratio'],
            ' '.join('%s=%.2f' % (k, v) for k, v in tr['combined_effect_to_noise_rms_ratio'].items()),
            time.time() - tc))
        summary.append(dict(case=name, kinds=tr['kinds'], forms=tr['forms'],
                            per_effect_median_ratio=per,
                            combined=tr['combined_effect_to_noise_rms_ratio']))
    with open(os.path.join(a.outdir, 'truth', 'summary.json'), 'w') as f:
        json.dump(summary, f, indent=1)
    print('generated %d cases in %.1f s' % (len(specs), time.time() - t0))


if __name__ == '__main__':
    main()
