#!/usr/bin/env python3
"""Blind test-data generator for hysteresis diagnosis (piezo actuator sessions).

Written from physical descriptions only (see README.md next to this file).
Only numpy and scipy are used.

Usage:
    python3 generator.py OUTDIR --cases-per-kind N --seed S [--cml] [--clean]
    python3 generator.py --self-test

--cml  adds one more experiment file per case, expN_cml.csv (N = highest
       existing experiment number + 1): a congruent-minor-loop (CML) test
       (Mayergoyz congruency property, thesis sec. 3.2.2 / Fig. 3.13).  The same
       minor loop between two inputs `low` < `high` is traversed three times,
       each reached through a different history so that the output sits at a
       different level:
         0 -> neg (negative end) -> high -> low -> high                 loop A
           -> peak (well above high) -> low -> high -> low              loop B
           -> trough (between neg and low) -> high -> low -> high       loop C
       (levels: A lowest, C between, B highest).  All low<->high legs have the
       same duration and shape (triangle or half-cosine, 0.6-1 Hz) and every
       reversal and loop end has the same short hold (30-200 ms); the record
       is typically 9-15 s long.  low/high/peak/trough are drawn per case
       (loop span 15-50 % of the input range, at varying positions in
       [-7, 7] V, redrawn until the device's Preisach density puts loops A and
       B >= 3 % of the output range apart if possible; the trough is set so that
       loop C lies 35-65 % of the way from A to B; see design_cml).
       The file is recorded AFTER the other experiments of the case (a further
       gap, then the CML record, in the same continuous session: same device,
       effects, memory, creep/filter states and slow drifts, same 1 kHz sampling,
       noise level, quantisation and command shaping).  Its design and noise
       come from a separate random stream and the effect strengths stay
       calibrated on the original experiments only (ratio_experiments* do not
       include it), so every other file is byte-identical with and without
       --cml.  The truth JSON then also lists the file in files,
       ratio_per_file, ratio_per_file_per_effect, clipped_samples_per_file and
       design["cml"] (design, designed reversal times/values, loop segments,
       designed Preisach level offsets), and session_duration_s includes it;
       all other truth entries are unchanged.  Without --cml the output is
       unchanged.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy import signal

DT = 1e-3
FS = 1.0 / DT
LO, HI = -10.0, 10.0
QSTEP = 20.0 / 2 ** 14

KINDS = ["rate", "creep", "delay", "resonance", "drift", "noncongruence"]
FORMS = {
    "rate": ["debye_relaxation", "viscous_switching", "rate_dependent_thresholds"],
    "creep": ["log_creep", "kelvin_voigt_chain", "threshold_creep_operator"],
    "delay": ["transport_integer", "fractional_lagrange", "bessel_antialias",
              "boxcar_decimation"],
    "resonance": ["single_mode", "two_mode_noncollocated", "frame_reaction_mode"],
    "drift": ["thermal_warmup", "random_walk", "flicker_1f", "hvac_cycle"],
    "noncongruence": ["moving_model", "electrostrictive_output",
                      "state_dependent_reversible"],
}
PRE_FORMS = {"viscous_switching", "rate_dependent_thresholds", "moving_model"}


# ----------------------------------------------------------------------------
# Preisach operator (Everett-function / dominant-extrema-stack implementation)
# ----------------------------------------------------------------------------
def make_density(family, p):
    """Return mu(alpha, beta) (vectorised) for a density family."""
    def fn(A, B):
        r = 0.5 * (A - B)
        c = 0.5 * (A + B)
        if family == "gauss_gauss":
            f = np.exp(-0.5 * ((r - p["r0"]) / p["sr"]) ** 2)
            g = np.exp(-0.5 * ((c - p["c0"]) / p["sc"]) ** 2)
            return f * g
        if family == "lognormal_gauss":
            rr = np.maximum(r, 1e-6)
            f = np.exp(-0.5 * (np.log(rr / p["r0"]) / p["s"]) ** 2) / rr
            g = np.exp(-0.5 * ((c - p["c0"]) / p["sc"]) ** 2)
            return f * g
        if family == "diagonal_ridge":
            f = np.exp(-r / p["lam"]) + p["w"] * np.exp(-0.5 * ((r - p["r1"]) / p["s1"]) ** 2)
            g = 1.0 / np.cosh((c - p["c0"]) / p["sc"]) ** 2
            return f * g
        if family == "skewed_tilted":
            f = np.maximum(r, 0) ** p["k"] * np.exp(-np.maximum(r, 0) / p["theta"])
            x = (c - p["c0"] - p["tilt"] * r) / p["sc"]
            g = np.exp(-0.5 * x * x) * (1.0 + _erf(p["skew"] * x / math.sqrt(2.0)))
            return f * g
        if family == "two_component":
            out = 0.0
            for comp in p["comps"]:
                f = np.exp(-0.5 * ((r - comp["r0"]) / comp["sr"]) ** 2)
                g = np.exp(-0.5 * ((c - comp["c0"]) / comp["sc"]) ** 2)
                out = out + comp["w"] * f * g
            return out
        raise ValueError(family)
    return fn


def _erf(x):
    from scipy.special import erf
    return erf(x)


class Everett:
    """Everett function table on [LO,HI]^2, normalised so that F(HI,LO)=1.

    F(a,b) = integral of mu over the triangle b <= beta <= alpha <= a.
    Evaluated with piecewise-linear interpolation on triangles split along the
    diagonal direction, so that F(x,x) = 0 exactly and F is continuous.
    """

    def __init__(self, density, h=0.04):
        n = int(round((HI - LO) / h)) + 1
        g = LO + h * np.arange(n)
        A, B = np.meshgrid(g, g, indexing="ij")
        mu = np.asarray(density(A, B), dtype=float)
        mu = np.where(A > B + 1e-12, np.clip(mu, 0.0, None), 0.0)
        F = np.cumsum(mu, axis=0)
        F = np.cumsum(F[:, ::-1], axis=1)[:, ::-1]
        F = F / F[-1, 0]
        self.n, self.h, self.grid = n, h, g
        self.mu = mu / mu.sum()
        self.table = F
        T = F.tolist()
        nm2 = n - 2
        inv_h = 1.0 / h

        def ev(a, b):
            if a <= b:
                return 0.0
            x = (a - LO) * inv_h
            y = (b - LO) * inv_h
            i = int(x)
            j = int(y)
            if i > nm2:
                i = nm2
            elif i < 0:
                i = 0
            if j > nm2:
                j = nm2
            elif j < 0:
                j = 0
            fx = x - i
            fy = y - j
            Ti = T[i]
            Ti1 = T[i + 1]
            if fx >= fy:
                return Ti[j] + fx * (Ti1[j] - Ti[j]) + fy * (Ti1[j + 1] - Ti1[j])
            return Ti[j] + fy * (Ti[j + 1] - Ti[j]) + fx * (Ti1[j + 1] - Ti[j + 1])

        self.F = ev

    def max_slope(self):
        """Largest dY/du along any branch (major branches bound all others)."""
        up = 2.0 * np.gradient(self.table[:, 0], self.h)
        down = -2.0 * np.gradient(self.table[-1, :], self.h)
        return float(max(up.max(), down.max()))


def _advance(ext, cum, cur, v, F):
    """Move the Preisach memory from input cur to input v (in place)."""
    if v > HI:
        v = HI
    elif v < LO:
        v = LO
    if len(ext) & 1:  # rising from ext[-1] (a minimum)
        if v >= cur:
            while len(ext) >= 3 and v >= ext[-2]:
                del ext[-2:]
                del cum[-2:]
            return v
        ext.append(cur)
        cum.append(cum[-1])
        while len(ext) >= 3 and v <= ext[-2]:
            del ext[-2:]
            del cum[-2:]
        if len(ext) == 2 and v <= ext[0]:
            del ext[1:]
            del cum[1:]
        return v
    # falling from ext[-1] (a maximum)
    if v <= cur:
        while len(ext) >= 3 and v <= ext[-2]:
            del ext[-2:]
            del cum[-2:]
        if len(ext) == 2 and v <= ext[0]:
            del ext[1:]
            del cum[1:]
        return v
    ext.append(cur)
    cum.append(cum[-1] + F(ext[-2], ext[-3]) - F(ext[-2], cur))
    while len(ext) >= 3 and v >= ext[-2]:
        del ext[-2:]
        del cum[-2:]
    return v


def _output(ext, cum, cur, F):
    if len(ext) & 1:
        return -1.0 + 2.0 * (cum[-1] + F(cur, ext[-1]))
    M = ext[-1]
    return -1.0 + 2.0 * (cum[-1] + F(M, ext[-2]) - F(M, cur))


class Preisach:
    """Classical Preisach operator, output normalised to [-1, 1]."""

    def __init__(self, everett):
        self.E = everett
        self.reset()

    def reset(self):  # negative saturation
        self.ext = [LO]
        self.cum = [0.0]
        self.cur = LO

    def run(self, v):
        F = self.E.F
        ext, cum, cur = self.ext, self.cum, self.cur
        out = np.empty(len(v))
        last = _output(ext, cum, cur, F)
        for k, x in enumerate(np.asarray(v, dtype=float).tolist()):
            if x != cur:
                cur = _advance(ext, cum, cur, x, F)
                last = _output(ext, cum, cur, F)
            out[k] = last
        self.cur = cur
        return out

    def peek(self, v):
        e = self.ext[:]
        c = self.cum[:]
        cu = _advance(e, c, self.cur, v, self.E.F)
        return _output(e, c, cu, self.E.F)

    def run_moving(self, u, K):
        """Moving Preisach model: hysterons see v = u + K*Y (implicit)."""
        F = self.E.F
        out = np.empty(len(u))
        v_prev = self.cur
        y_prev = _output(self.ext, self.cum, self.cur, F)
        u_prev = v_prev - K * y_prev
        slope = 0.1
        for k, x in enumerate(np.asarray(u, dtype=float).tolist()):
            if x == u_prev:
                out[k] = y_prev
                continue
            # solve g(v) = v - x - K*P(v) = 0 by secant iterations
            va, ga = v_prev, v_prev - x - K * y_prev
            vb = v_prev - ga / max(1.0 - K * slope, 0.2)
            yb = self.peek(vb)
            gb = vb - x - K * yb
            it = 0
            while abs(gb) > 1e-10 and it < 40:
                den = gb - ga
                if den == 0.0:
                    break
                vn = vb - gb * (vb - va) / den
                va, ga = vb, gb
                vb = vn
                yb = self.peek(vb)
                gb = vb - x - K * yb
                it += 1
            self.cur = _advance(self.ext, self.cum, self.cur, vb, F)
            y = _output(self.ext, self.cum, self.cur, F)
            if vb != v_prev:
                s = (y - y_prev) / (vb - v_prev)
                if 0.0 <= s < 5.0:
                    slope = s
            v_prev, y_prev, u_prev = vb, y, x
            out[k] = y
        return out


# ----------------------------------------------------------------------------
# Input design
# ----------------------------------------------------------------------------
class Builder:
    def __init__(self, start=0.0):
        self.v = [start]

    def hold(self, T):
        n = int(round(T / DT))
        self.v.extend([self.v[-1]] * n)

    def ramp(self, to, rate):
        a = self.v[-1]
        n = max(1, int(math.ceil(abs(to - a) / rate / DT)))
        self.v.extend(np.linspace(a, to, n + 1)[1:].tolist())

    def jump(self, to):
        self.v.append(to)

    def extend(self, arr):
        self.v.extend(list(arr))

    def array(self):
        return np.asarray(self.v[1:], dtype=float)


def smooth_rise(u, L):
    """Command shaping: moving average over L samples (steps become ramps)."""
    if L <= 1:
        return u
    pad = np.concatenate([np.full(L - 1, u[0]), u])
    return np.convolve(pad, np.ones(L) / L, mode="valid")


def fit_len(u, n):
    if len(u) >= n:
        return u[:n]
    return np.concatenate([u, np.full(n - len(u), u[-1])])


def design_id(rng):
    return {"mode": str(rng.choice(["constant_slew", "constant_period"])),
            "freq": float(rng.uniform(1.0, 2.0)),
            "n_levels": 21,
            "hold_top": float(rng.uniform(0.05, 0.2))}


def build_id(d):
    levels = np.linspace(HI, LO, d["n_levels"] + 1)[1:]
    b = Builder(0.0)
    b.hold(0.3)
    slew = 40.0 * d["freq"]
    b.ramp(HI, slew)
    b.hold(d["hold_top"])
    for L in levels:
        if d["mode"] == "constant_period":
            rate = 2.0 * (HI - L) * d["freq"]
        else:
            rate = slew
        b.ramp(L, rate)
        b.ramp(HI, rate)
        b.hold(d["hold_top"])
    b.ramp(0.0, slew)
    b.hold(0.3)
    return b.array()


EXP_TYPES = ["wiping", "multisine", "steps", "noise", "triangles"]


def design_exp(rng, etype):
    d = {"type": etype, "dur": float(rng.uniform(8.0, 14.0)),
         "pre": float(rng.uniform(0.2, 0.5)), "seed": int(rng.integers(2 ** 31))}
    return d


def build_exp(d):
    rng = np.random.default_rng(d["seed"])
    n = int(round(d["dur"] / DT))
    b = Builder(0.0)
    b.hold(d["pre"])
    t = d["type"]
    if t == "wiping":
        sign = rng.choice([-1.0, 1.0])
        first = sign * rng.uniform(8.5, 9.8)
        center = rng.uniform(-2.0, 2.0)
        fac = rng.uniform(0.6, 0.85)
        hold = rng.uniform(0.0, 0.25)
        b.jump(first)
        b.hold(rng.uniform(0.3, 0.8))
        a = abs(first - center)
        nrev = int(math.ceil(math.log(0.3 / a) / math.log(fac)))
        travel = a * (1.0 + fac) / (1.0 - fac)
        busy = rng.uniform(0.6, 0.85) * d["dur"] - nrev * hold - 1.0
        rate = min(max(travel / max(busy, 1.0), 3.0), 40.0)
        s = -sign
        while a > 0.3 and len(b.v) < n:
            a *= fac
            b.ramp(center + s * a, rate)
            b.hold(hold)
            s = -s
        b.hold(d["dur"])
    elif t == "multisine":
        k = rng.integers(3, 7)
        fr = np.sort(np.exp(rng.uniform(np.log(0.1), np.log(6.0), k)))
        ph = rng.uniform(0, 2 * np.pi, k)
        am = rng.uniform(0.3, 1.0, k) / np.sqrt(fr / fr[0]) ** 0.5
        tt = np.arange(n) * DT
        x = sum(am[i] * np.sin(2 * np.pi * fr[i] * tt + ph[i]) for i in range(k))
        x = rng.uniform(-1.5, 1.5) + x / np.max(np.abs(x)) * rng.uniform(6.5, 8.5)
        b.extend(x)
    elif t == "steps":
        while len(b.v) < n:
            b.jump(rng.uniform(-9.5, 9.5))
            b.hold(rng.uniform(0.4, 1.8))
    elif t == "noise":
        fc = rng.uniform(1.0, 6.0)
        bb, aa = signal.butter(2, fc / (FS / 2))
        x = signal.filtfilt(bb, aa, rng.standard_normal(n + 2000))[1000:1000 + n]
        x = x / np.std(x) * rng.uniform(3.0, 4.5) + rng.uniform(-1.0, 1.0)
        b.extend(np.clip(x, -9.5, 9.5))
    elif t == "triangles":
        f = rng.uniform(0.2, 0.6)
        center = rng.uniform(-1.5, 1.5)
        a0, a1 = rng.uniform(1.0, 3.0), rng.uniform(7.0, 9.0) - abs(center)
        if rng.random() < 0.5:
            a0, a1 = a1, a0
        b.ramp(center, 10.0)
        tt = np.arange(n) * DT
        amp = a0 + (a1 - a0) * tt / tt[-1]
        tri = 2.0 / np.pi * np.arcsin(np.sin(2 * np.pi * f * tt))
        b.extend(center + amp * tri)
    u = fit_len(b.array(), n)
    return np.clip(u, -10.0, 10.0)


def build_session(design, rise_ms):
    """Concatenate prefix, id sweep, gaps and experiments into one session."""
    L = int(round(rise_ms)) + 1 if rise_ms > 0 else 1
    parts, files = [], []
    # unrecorded prefix: decaying AC 'depoling to rest' then rest at 0 V
    tt = np.arange(int(4.0 / DT)) * DT
    parts.append(9.5 * np.exp(-tt / 0.8) * np.sin(2 * np.pi * 2.0 * tt))
    parts.append(np.zeros(int(design["pre_rest"] / DT)))
    pos = sum(len(p) for p in parts)
    uid = build_id(design["id"])  # slow ramps: no command shaping
    files.append(("id.csv", pos, len(uid)))
    parts.append(uid)
    pos += len(uid)
    for k, ed in enumerate(design["exps"]):
        last = parts[-1][-1]
        b = Builder(last)
        b.ramp(0.0, 20.0)
        b.hold(ed["gap"])
        g = b.array()
        parts.append(g)
        pos += len(g)
        ue = smooth_rise(build_exp(ed), L)
        name = "exp%d_%s.csv" % (k + 1, ed["type"])
        files.append((name, pos, len(ue)))
        parts.append(ue)
        pos += len(ue)
    b = Builder(parts[-1][-1])
    b.ramp(0.0, 20.0)
    b.hold(0.5)
    parts.append(b.array())
    u = np.concatenate(parts)
    return u, files


# ----------------------------------------------------------------------------
# Optional congruent-minor-loop (CML) experiment (--cml)
# ----------------------------------------------------------------------------
CML_TAG = 0x434D4C  # "CML": key of the separate random stream of the CML file


def _rect(F, a1, a2, b1, b2):
    """Preisach mass of alpha in (a1, a2], beta in (b1, b2]  (b2 <= a1)."""
    return F(a2, b1) - F(a2, b2) - F(a1, b1) + F(a1, b2)


def design_cml(rng, ev, min_off=0.06, tries=200):
    """Random CML design: the minor loop low..high and the histories that
    place the three traversals of it at different output levels.

    Only hysterons with alpha > high and beta < low carry the history into the
    loop, so the level offset between loop A (from `neg`) and loop B (from
    `peak`) is 2*mass{high < alpha <= peak, neg < beta <= low} of the device's
    Preisach density (normalised output units, range 2).  Like an experimenter
    who looks at the device first, the generator redraws span/position/peak
    (span log-uniform 3..10 V = 15..50 % of the input range, anywhere in
    [-7, 7] V) until that offset is >= min_off (else it keeps the best draw),
    and puts the trough so that loop C lies a random 35..65 % of the way from
    loop A to loop B (trough at least 15 % of the span below low)."""
    F = ev.F
    best = None
    for _ in range(tries):
        w = float(np.exp(rng.uniform(np.log(0.15), np.log(0.5)))) * (HI - LO)
        low = float(rng.uniform(-7.0, 7.0 - w))
        high = low + w
        neg = float(rng.uniform(-9.8, -9.0))                  # negative end
        peak = high + float(rng.uniform(0.5, 1.0)) * (9.6 - high)  # well above high
        off = 2.0 * _rect(F, high, peak, neg, low)
        if best is None or off > best[0]:
            best = (off, low, high, neg, peak)
        if off >= min_off:
            break
    off, low, high, neg, peak = best
    frac = float(rng.uniform(0.35, 0.65))
    a, b = neg, low
    for _ in range(60):  # bisection: offset(C - A) = frac * offset(B - A)
        mid = 0.5 * (a + b)
        if 2.0 * _rect(F, high, peak, neg, mid) < frac * off:
            a = mid
        else:
            b = mid
    trough = min(0.5 * (a + b), low - 0.15 * (high - low))
    offCA = 2.0 * _rect(F, high, peak, neg, trough)
    d = {"type": "cml", "low": low, "high": high, "peak": peak, "trough": trough,
         "neg": neg, "shape": str(rng.choice(["triangle", "cosine"])),
         "leg_s": float(0.5 / rng.uniform(0.6, 1.0)),      # low<->high leg
         "hold_s": float(rng.uniform(0.03, 0.2)),          # at every reversal
         "pre": float(rng.uniform(0.2, 0.5)), "post": float(rng.uniform(0.3, 0.8)),
         "level_offsets_preisach": {"B-A": off, "C-A": offCA, "B-C": off - offCA}}
    return d


def _cml_leg(b, to, T, shape):
    a = b.v[-1]
    n = max(1, int(round(T / DT)))
    if shape == "cosine":
        x = a + (to - a) * 0.5 * (1.0 - np.cos(np.pi * np.arange(1, n + 1) / n))
    else:
        x = np.linspace(a, to, n + 1)[1:]
    x[-1] = to
    b.extend(x)


def build_cml(d):
    """Input of the CML experiment; returns (u, marks) where marks lists the
    designed reversals [time in the file (s), label, value] (plus the
    non-reversal points high_pass / low_pass = ends of loops A / B, where the
    input holds and then goes on, and high_end) and the three loop
    segments [start, end] (s) of the low<->high traversals (designed times,
    i.e. before the per-case command shaping of a few ms)."""
    lo_, hi_, w, Tl, hold = d["low"], d["high"], d["high"] - d["low"], d["leg_s"], d["hold_s"]
    b = Builder(0.0)
    b.hold(d["pre"])
    rev, loops = [], {}

    def hist(to):  # history leg: longer for larger spans (<= 2 loop legs)
        span = abs(to - b.v[-1])
        _cml_leg(b, to, Tl * min(max(math.sqrt(span / w), 1.0), 2.0), d["shape"])

    def loop(to):
        _cml_leg(b, to, Tl, d["shape"])

    def mark(label, hold_it=True):
        rev.append([len(b.v) - 2, label, float(b.v[-1])])
        if hold_it:
            b.hold(hold)

    def here():
        return len(b.v) - 2
    hist(d["neg"]); mark("neg")
    hist(hi_); mark("high")
    sA = here(); loop(lo_); mark("low"); loop(hi_); loops["A"] = [sA, here()]
    mark("high_pass")                # loop A closes here; the input goes on up
    hist(d["peak"]); mark("peak")
    hist(lo_); mark("low")
    sB = here(); loop(hi_); mark("high"); loop(lo_); loops["B"] = [sB, here()]
    mark("low_pass")                 # loop B closes here; the input goes on down
    hist(d["trough"]); mark("trough")
    hist(hi_); mark("high")
    sC = here(); loop(lo_); mark("low"); loop(hi_); loops["C"] = [sC, here()]
    mark("high_end", hold_it=False)  # end of loop C (post hold follows)
    b.hold(d["post"])
    u = np.clip(b.array(), -10.0, 10.0)
    marks = {"reversals": [[i * DT, lab, v] for i, lab, v in rev],
             "loops_s": {k: [a * DT, e * DT] for k, (a, e) in loops.items()},
             "loop_order_by_level": ["A", "C", "B"]}
    return u, marks


def extend_session_cml(u, d, rise_ms, name):
    """Continue the session u (which ends at rest at 0 V) by a further gap of
    d['gap'] s at 0 V, the CML record and the usual return to 0 V."""
    L = int(round(rise_ms)) + 1 if rise_ms > 0 else 1
    g = np.zeros(int(round(d["gap"] / DT)))
    uc, marks = build_cml(d)
    uc = smooth_rise(uc, L)
    b = Builder(uc[-1])
    b.ramp(0.0, 20.0)
    b.hold(0.5)
    start = len(u) + len(g)
    return np.concatenate([u, g, uc, b.array()]), (name, start, len(uc)), marks


# ----------------------------------------------------------------------------
# Effects
# ----------------------------------------------------------------------------
def lp1(x, tau, x0=None):
    """Exact first-order lag with input held over each sample (end value)."""
    a = math.exp(-DT / tau)
    x0 = x[0] if x0 is None else x0
    y, _ = signal.lfilter([1.0 - a], [1.0, -a], x, zi=[a * x0])
    return y


def prefilter_viscous(u, p, s):
    """Viscous hysteron switching (dynamic Preisach): the hysteretic input v
    relaxes towards u with  dd/dt = -d/tau - a*d*|d|,  d = v-u."""
    tau = s * p["tau0"]
    a = p["a0"] / s
    out = np.empty(len(u))
    v = float(u[0])
    e = math.exp(DT / tau)
    at = a * tau
    for k, x in enumerate(np.asarray(u, dtype=float).tolist()):
        d = v - x
        if d != 0.0:
            ad = abs(d)
            z = (1.0 / ad + at) * e - at
            nd = 1.0 / z
            if nd < 1e-13:
                nd = 0.0
            v = x + (nd if d > 0 else -nd)
        out[k] = v
    return out


def prefilter_rate_thresholds(u, p, s):
    """Rate-dependent threshold widening: play (backlash) operator whose
    half-width grows with the filtered input rate."""
    du = np.abs(np.diff(u, prepend=u[0])) / DT
    r = lp1(du, p["tau_r"], 0.0)
    delta = s * p["delta0"] * np.tanh(p["b0"] * r / p["delta0"])
    out = np.empty(len(u))
    v = float(u[0])
    for k, (x, dl) in enumerate(zip(np.asarray(u, float).tolist(), delta.tolist())):
        if v < x - dl:
            v = x - dl
        elif v > x + dl:
            v = x + dl
        out[k] = v
    return out


def threshold_creep(u, p):
    """Kuhnen-type creep operator: elements dz/dt = lam*dz_r(u - z)."""
    out = np.zeros(len(u))
    ul = np.asarray(u, float).tolist()
    for lam, r, w in zip(p["lams"], p["rs"], p["ws"]):
        c = 1.0 - math.exp(-lam * DT)
        z = ul[0]
        zz = np.empty(len(u))
        for k, x in enumerate(ul):
            e = x - z
            if e > r:
                z += c * (e - r)
            elif e < -r:
                z += c * (e + r)
            zz[k] = z
        out += w * (zz - u)
    return out


def log_creep_kernel(n, t0, tref):
    t = np.arange(n) * DT
    return np.log10(1.0 + t / t0) - math.log10(1.0 + tref / t0)


def mode_filter(f, zeta, hp=False):
    w = 2 * np.pi * f
    wp = 2.0 * FS * math.tan(w * DT / 2.0)
    num = [1.0, 0.0, 0.0] if hp else [wp * wp]
    return signal.bilinear(num, [1.0, 2 * zeta * wp, wp * wp], fs=FS)


def filt_ss(b, a, x):
    zi = signal.lfilter_zi(b, a) * x[0]
    y, _ = signal.lfilter(b, a, x, zi=zi)
    return y


def apply_delay(y, form, p):
    if form == "transport_integer":
        n = int(p["samples"])
        return np.concatenate([np.full(n, y[0]), y[:-n]]) if n > 0 else y.copy()
    if form == "boxcar_decimation":
        L = int(p["length"])
        return filt_ss(np.ones(L) / L, np.array([1.0]), y)
    if form == "fractional_lagrange":
        D = p["delay_s"] / DT
        if D < 1.5:
            n0, Dl = 0, D
        else:
            n0 = int(math.floor(D)) - 1
            Dl = D - n0
        h = np.ones(4)
        for k in range(4):
            for m in range(4):
                if m != k:
                    h[k] *= (Dl - m) / (k - m)
        z = np.concatenate([np.full(n0, y[0]), y])[:len(y)] if n0 > 0 else y
        return filt_ss(h, np.array([1.0]), z)
    if form == "bessel_antialias":
        b, a = signal.bessel(p["order"], 1.0 / p["delay_s"], analog=True, norm="delay")
        bd, ad = signal.bilinear(b, a, fs=FS)
        return filt_ss(bd, ad, y)
    raise ValueError(form)


def drift_shape(form, p, n, n_ext=None):
    """Unit-RMS drift realisation over n samples.  With n_ext (--cml) the same
    realisation is continued to n_ext > n samples (later session time); all
    normalisations still refer to the first n samples, so x[:n] is unchanged."""
    n_ext = n if n_ext is None else n_ext
    rng = np.random.default_rng(p["seed"])
    t = np.arange(n_ext) * DT
    if form == "thermal_warmup":
        x = (1.0 - np.exp(-t / p["tau_w"])) + p["slope"] * t / ((n - 1) * DT)
    elif form == "random_walk":
        x = np.cumsum(rng.standard_normal(n_ext))
        x = lp1(x, p["tau_s"], 0.0)
    elif form == "flicker_1f":
        N = 1 << int(math.ceil(math.log2(n)))
        f = np.fft.rfftfreq(N, DT)
        amp = np.zeros_like(f)
        amp[1:] = f[1:] ** (-p["gamma"] / 2.0) / np.sqrt(1.0 + (f[1:] / p["f_c"]) ** 4)
        X = amp * (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f)))
        x = np.fft.irfft(X, N)[np.arange(n_ext) % N]  # periodic continuation beyond n
    elif form == "hvac_cycle":
        w = 2 * np.pi / p["period"]
        x = np.sin(w * t + p["phase"]) + p["h2"] * np.sin(2 * w * t + 2 * p["phase"] + 1.0)
    else:
        raise ValueError(form)
    x = x - x[0]
    return x / np.sqrt(np.mean(x[:n] * x[:n]))


class Case:
    """Holds the session input, base model and a cache of base outputs.
    n_norm (None by default) = length of the original session when u is the
    session extended by the --cml record (drift normalisation)."""

    def __init__(self, base, u, files):
        self.base = base
        self.u = u
        self.files = files
        self.ev = Everett(make_density(base["family"], base["dens"]))
        self.Y0 = self.hyst(u)
        self.mask = np.zeros(len(u), bool)
        for name, s, n in files:
            if name != "id.csv":
                self.mask[s:s + n] = True
        self.n_norm = None

    def hyst(self, v, K=None):
        P = Preisach(self.ev)
        if K is None:
            return P.run(v)
        return P.run_moving(v, K)

    def simulate(self, effects):
        b = self.base
        A, rho, off = b["A"], b["rho"], b["offset"]
        u = self.u
        fm = {e["form"]: e for e in effects}
        # --- hysteretic part -----------------------------------------------
        v = u
        if "viscous_switching" in fm:
            e = fm["viscous_switching"]
            v = prefilter_viscous(v, e["p"], e["s"])
        if "rate_dependent_thresholds" in fm:
            e = fm["rate_dependent_thresholds"]
            v = prefilter_rate_thresholds(v, e["p"], e["s"])
        if "moving_model" in fm:
            Y = self.hyst(v, K=fm["moving_model"]["s"])
        elif v is u:
            Y = self.Y0
        else:
            Y = self.hyst(v)
        Yp = Y
        if "electrostrictive_output" in fm:
            Yp = Y + fm["electrostrictive_output"]["s"] * (Y * Y - 1.0)
        rev = u / 10.0
        if "state_dependent_reversible" in fm:
            rev = rev * (1.0 + fm["state_dependent_reversible"]["s"] * Y)
        y = A * ((1.0 - rho) * Yp + rho * rev)
        if "debye_relaxation" in fm:
            e = fm["debye_relaxation"]
            y = y + A * e["s"] * (lp1(u / 10.0, e["p"]["tau"]) - u / 10.0)
        # --- creep ---------------------------------------------------------
        if "log_creep" in fm:
            e = fm["log_creep"]
            yh = A * (1.0 - rho) * Yp
            dy = np.diff(yh, prepend=yh[0])
            K = log_creep_kernel(len(u), e["p"]["t0"], e["p"]["t_ref"])
            y = y + e["s"] * signal.fftconvolve(dy, K)[:len(u)]
        if "kelvin_voigt_chain" in fm:
            e = fm["kelvin_voigt_chain"]
            c = sum(w * (lp1(u / 10.0, tau) - u / 10.0)
                    for tau, w in zip(e["p"]["taus"], e["p"]["ws"]))
            y = y + A * e["s"] * c
        if "threshold_creep_operator" in fm:
            e = fm["threshold_creep_operator"]
            y = y + A / 10.0 * e["s"] * threshold_creep(u, e["p"])
        y = y + off
        # --- structural resonance -----------------------------------------
        if "single_mode" in fm:
            e = fm["single_mode"]
            b_, a_ = mode_filter(e["p"]["f"], e["p"]["zeta"])
            y = y + e["s"] * (filt_ss(b_, a_, y) - y)
        if "two_mode_noncollocated" in fm:
            e = fm["two_mode_noncollocated"]
            p = e["p"]
            b1, a1 = mode_filter(p["f1"], p["zeta1"])
            b2, a2 = mode_filter(p["f2"], p["zeta2"])
            y = y + e["s"] * ((filt_ss(b1, a1, y) - y) + p["c2"] * (filt_ss(b2, a2, y) - y))
        if "frame_reaction_mode" in fm:
            e = fm["frame_reaction_mode"]
            b_, a_ = mode_filter(e["p"]["f"], e["p"]["zeta"], hp=True)
            yd = y - y[0]
            y = y - e["s"] * filt_ss(b_, a_, yd)
        # --- delay ---------------------------------------------------------
        for f in FORMS["delay"]:
            if f in fm:
                y = apply_delay(y, f, fm[f]["p"])
        # --- sensor drift --------------------------------------------------
        for f in FORMS["drift"]:
            if f in fm:
                if self.n_norm is None:
                    y = y + fm[f]["s"] * drift_shape(f, fm[f]["p"], len(u))
                else:
                    y = y + fm[f]["s"] * drift_shape(f, fm[f]["p"], self.n_norm, len(u))
        return y


# ----------------------------------------------------------------------------
# Random case construction
# ----------------------------------------------------------------------------
def draw_base(rng, forms):
    fam = str(rng.choice(["gauss_gauss", "lognormal_gauss", "diagonal_ridge",
                          "skewed_tilted", "two_component"]))
    if fam == "gauss_gauss":
        d = {"r0": rng.uniform(0.3, 1.8), "sr": rng.uniform(0.5, 1.5),
             "c0": rng.uniform(-1.5, 1.5), "sc": rng.uniform(2.0, 4.5)}
    elif fam == "lognormal_gauss":
        d = {"r0": rng.uniform(0.6, 2.2), "s": rng.uniform(0.4, 0.8),
             "c0": rng.uniform(-1.5, 1.5), "sc": rng.uniform(2.0, 4.5)}
    elif fam == "diagonal_ridge":
        d = {"lam": rng.uniform(0.3, 1.2), "w": rng.uniform(0.2, 0.8),
             "r1": rng.uniform(1.5, 3.5), "s1": rng.uniform(0.5, 1.2),
             "c0": rng.uniform(-1.5, 1.5), "sc": rng.uniform(1.5, 3.0)}
    elif fam == "skewed_tilted":
        d = {"k": rng.uniform(1.0, 3.0), "theta": rng.uniform(0.4, 1.2),
             "c0": rng.uniform(-1.5, 1.0), "tilt": rng.uniform(-0.4, 0.4),
             "sc": rng.uniform(2.0, 4.0), "skew": rng.uniform(-3.0, 3.0)}
    else:
        comps = []
        for _ in range(2):
            comps.append({"w": rng.uniform(0.3, 1.0), "r0": rng.uniform(0.3, 3.0),
                          "sr": rng.uniform(0.5, 1.5), "c0": rng.uniform(-4.0, 4.0),
                          "sc": rng.uniform(1.5, 3.0)})
        d = {"comps": comps}
    rho_lo = 0.15 if "state_dependent_reversible" in forms else 0.03
    base = {"family": fam, "dens": _pyify(d), "A": float(rng.uniform(6.5, 8.5)),
            "rho": float(rng.uniform(rho_lo, 0.4)), "offset": float(rng.uniform(-0.5, 0.5))}
    return base


def draw_effect(rng, kind, form):
    """Nominal parameters p and initial strength s for one effect."""
    p, s = {}, 1.0
    if form == "debye_relaxation":
        p = {"tau": rng.uniform(0.3e-3, 1.5e-3)}
        s = 0.1
    elif form == "viscous_switching":
        p = {"tau0": rng.uniform(0.3e-3, 1.0e-3), "a0": rng.uniform(2e3, 2e4)}
        s = 1.0
    elif form == "rate_dependent_thresholds":
        p = {"tau_r": rng.uniform(0.4e-3, 1.0e-3), "delta0": rng.uniform(0.2, 1.0),
             "b0": rng.uniform(2e-3, 1e-2)}
        s = 0.3
    elif form == "log_creep":
        p = {"t0": rng.uniform(0.01, 0.2), "t_ref": rng.uniform(0.5, 3.0)}
        s = 0.02
    elif form == "kelvin_voigt_chain":
        k = int(rng.integers(2, 4))
        taus = np.sort(np.exp(rng.uniform(np.log(0.2), np.log(20.0), k)))
        ws = rng.uniform(0.3, 1.0, k)
        p = {"taus": taus.tolist(), "ws": (ws / ws.sum()).tolist()}
        s = 0.03
    elif form == "threshold_creep_operator":
        lams = np.exp(np.linspace(np.log(rng.uniform(0.03, 0.1)), np.log(rng.uniform(3, 15)), 4))
        rs = [0.0, rng.uniform(0.2, 1.0), rng.uniform(1.0, 3.0)]
        L, R, W = [], [], []
        for lam in lams:
            for r in rs:
                L.append(float(lam)); R.append(float(r)); W.append(float(rng.uniform(0.2, 1.0)))
        W = (np.array(W) / np.sum(W)).tolist()
        p = {"lams": L, "rs": R, "ws": W}
        s = 0.03
    elif form == "transport_integer":
        p = {"samples": 2}
    elif form == "fractional_lagrange":
        p = {"delay_s": 2e-3}
    elif form == "bessel_antialias":
        p = {"order": int(rng.integers(2, 5)), "delay_s": 2e-3}
    elif form == "boxcar_decimation":
        p = {"length": 3}
    elif form == "single_mode":
        p = {"f": float(np.exp(rng.uniform(np.log(20), np.log(300)))),
             "zeta": float(np.exp(rng.uniform(np.log(0.005), np.log(0.15))))}
        s = 0.1
    elif form == "two_mode_noncollocated":
        f1 = float(np.exp(rng.uniform(np.log(20), np.log(120))))
        p = {"f1": f1, "zeta1": float(np.exp(rng.uniform(np.log(0.005), np.log(0.15)))),
             "f2": float(min(f1 * rng.uniform(2.5, 6.3), 400.0)),
             "zeta2": float(np.exp(rng.uniform(np.log(0.005), np.log(0.15)))),
             "c2": float(rng.choice([-1, 1]) * rng.uniform(0.3, 1.0))}
        s = 0.1
    elif form == "frame_reaction_mode":
        p = {"f": float(np.exp(rng.uniform(np.log(30), np.log(300)))),
             "zeta": float(np.exp(rng.uniform(np.log(0.005), np.log(0.15))))}
        s = 0.05
    elif form == "thermal_warmup":
        p = {"tau_w": rng.uniform(20, 150), "slope": rng.uniform(-1.0, 1.0),
             "seed": int(rng.integers(2 ** 31))}
        s = 0.01
    elif form == "random_walk":
        p = {"tau_s": rng.uniform(0.2, 2.0), "seed": int(rng.integers(2 ** 31))}
        s = 0.01
    elif form == "flicker_1f":
        p = {"gamma": rng.uniform(0.8, 1.6), "f_c": rng.uniform(0.3, 2.0),
             "seed": int(rng.integers(2 ** 31))}
        s = 0.01
    elif form == "hvac_cycle":
        p = {"period": rng.uniform(30, 150), "phase": rng.uniform(0, 2 * np.pi),
             "h2": rng.uniform(0.0, 0.4), "seed": int(rng.integers(2 ** 31))}
        s = 0.01
    elif form == "moving_model":
        p = {"sign": float(rng.choice([-1.0, 1.0]))}
        s = 0.3 * p["sign"]
    elif form == "electrostrictive_output":
        p = {"sign": float(rng.choice([-1.0, 1.0]))}
        s = 0.05 * p["sign"]
    elif form == "state_dependent_reversible":
        p = {"sign": float(rng.choice([-1.0, 1.0]))}
        s = 0.2 * p["sign"]
    return {"kind": kind, "form": form, "p": _pyify(p), "s": float(s)}


# strength caps (physically plausible ranges of the knob)
S_CAP = {"debye_relaxation": (1e-4, 0.6), "viscous_switching": (1e-3, None),
         "rate_dependent_thresholds": (1e-3, 4.0), "log_creep": (1e-4, 0.15),
         "kelvin_voigt_chain": (1e-4, 0.4), "threshold_creep_operator": (1e-4, 0.5),
         "single_mode": (1e-4, 1.0), "two_mode_noncollocated": (1e-4, 1.0),
         "frame_reaction_mode": (1e-4, 0.5), "thermal_warmup": (1e-5, 2.0),
         "random_walk": (1e-5, 2.0), "flicker_1f": (1e-5, 2.0), "hvac_cycle": (1e-5, 2.0),
         "moving_model": (1e-4, None), "electrostrictive_output": (1e-4, 0.45),
         "state_dependent_reversible": (1e-4, 1.0)}
LINEAR_FORMS = {"debye_relaxation", "log_creep", "kelvin_voigt_chain",
                "threshold_creep_operator", "single_mode", "two_mode_noncollocated",
                "frame_reaction_mode", "thermal_warmup", "random_walk", "flicker_1f",
                "hvac_cycle", "electrostrictive_output", "state_dependent_reversible"}


def rms(x):
    return float(np.sqrt(np.mean(np.asarray(x) ** 2))) if len(x) else 0.0


def calibrate(case, ybase, e, target, sigma):
    """Set the strength knob of effect e so that RMS(diff on experiments)
    / sigma equals target (within caps). Returns achieved ratio and status."""
    m = case.mask
    form = e["form"]

    def ratio(ee):
        return rms((case.simulate([ee]) - ybase)[m]) / sigma

    if e["kind"] == "delay":
        if form == "transport_integer":
            cands = [{"samples": k} for k in range(1, 6)]
        elif form == "boxcar_decimation":
            cands = [{"length": L} for L in range(2, 12)]
        else:
            cands = [dict(e["p"], delay_s=float(d)) for d in np.linspace(0.5e-3, 5e-3, 19)]
        rs = []
        for c in cands:
            rs.append(ratio(dict(e, p=c)))
        rs = np.array(rs)
        if form in ("transport_integer", "boxcar_decimation"):
            k = int(np.argmin(np.abs(np.log(rs / target))))
            e["p"] = cands[k]
            r = rs[k]
        else:
            lr = np.log(np.maximum(rs, 1e-9))
            ds = np.array([c["delay_s"] for c in cands])
            if target <= rs[0]:
                d = ds[0]
            elif target >= rs[-1]:
                d = ds[-1]
            else:
                d = float(np.interp(np.log(target), np.maximum.accumulate(lr), ds))
            e["p"] = dict(e["p"], delay_s=float(d))
            r = ratio(e)
        return r, bool(rs.min() <= min(30.0, 2.0 * max(target, 3.0)))
    lo, hi = S_CAP[form]
    sign = 1.0 if e["s"] >= 0 else -1.0
    if form == "moving_model":
        hi = 0.7 / case.ev.max_slope() if sign > 0 else 2.5
    if form == "viscous_switching":
        hi = 1.5e-3 / e["p"]["tau0"]
    s = abs(e["s"])
    r = ratio(e)
    if form in LINEAR_FORMS:
        s = min(max(s * target / max(r, 1e-12), lo), hi)
        e["s"] = sign * s
        return ratio(e), True
    # nonlinear knob: secant iterations in log-log
    pts = [(math.log(s), math.log(max(r, 1e-12)))]
    for it in range(8):
        if abs(math.log(r / target)) < 0.04:
            break
        if len(pts) >= 2 and pts[-1][0] != pts[-2][0]:
            slope = (pts[-1][1] - pts[-2][1]) / (pts[-1][0] - pts[-2][0])
            slope = min(max(slope, 0.3), 3.0)
        else:
            slope = 1.0
        ns = math.exp(pts[-1][0] + (math.log(target) - pts[-1][1]) / slope)
        ns = min(max(ns, lo), hi)
        if ns == s and it > 0:
            break
        s = ns
        e["s"] = sign * s
        r = ratio(e)
        pts.append((math.log(s), math.log(max(r, 1e-12))))
    return r, True


def _pyify(o):
    if isinstance(o, dict):
        return {k: _pyify(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_pyify(v) for v in o]
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return o


def write_csv(path, u, y):
    t = np.arange(len(u)) * DT
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",",
               header="# sample_time: 0.001\n# input_units: V\n# output_units: V\nt,u,y",
               comments="", fmt=["%.3f", "%.6f", "%.6f"])


def make_case(args):
    idx, kinds, forms, seed, outdir = args[:5]
    cml = bool(args[5]) if len(args) > 5 else False
    clean = bool(args[6]) if len(args) > 6 else False
    t0 = time.time()
    rng = np.random.default_rng(seed)
    base = draw_base(rng, forms)
    sigma = float(rng.uniform(1e-3, 3e-3))
    rise_ms = float(rng.choice([0, 0, 1, 2, 5, 10]))
    n_exp = int(rng.integers(4, 6))
    etypes = list(rng.permutation(EXP_TYPES))[:n_exp]
    design = {"id": design_id(rng), "pre_rest": float(rng.uniform(1.0, 3.0)), "exps": []}
    for et in etypes:
        d = design_exp(rng, str(et))
        d["gap"] = float(rng.uniform(2.0, 6.0))
        design["exps"].append(d)
    effects = [draw_effect(rng, k, f) for k, f in zip(kinds, forms)]
    targets = [float(np.exp(rng.uniform(np.log(3.0), np.log(30.0)))) for _ in effects]
    noise_seed = int(rng.integers(2 ** 31))
    for attempt in range(4):
        u, files = build_session(design, rise_ms)
        case = Case(base, u, files)
        ybase = case.simulate([])
        achieved, ok = [], True
        for e, tg in zip(effects, targets):
            r, feasible = calibrate(case, ybase, e, tg, sigma)
            achieved.append(float(r))
            ok = ok and feasible
        if ok:
            break
        if rise_ms >= 20.0:
            break
        rise_ms = {0.0: 2.0, 1.0: 2.0, 2.0: 5.0, 5.0: 10.0}.get(rise_ms, 20.0)
    yfin = case.simulate(effects)
    diff = yfin - ybase
    nrng = np.random.default_rng(noise_seed)
    ynoisy = yfin + sigma * nrng.standard_normal(len(u))
    codes = np.clip(np.round(ynoisy / QSTEP), -2 ** 13, 2 ** 13 - 1)
    ymeas = codes * QSTEP
    cdir = os.path.join(outdir, "case_%03d" % idx)
    os.makedirs(cdir, exist_ok=True)
    per_file, per_file_eff, clipped = {}, {}, {}
    single = {}
    for e in effects:
        single[e["form"]] = case.simulate([e]) - ybase if len(effects) > 1 else diff
    for name, s0, n in files:
        sl = slice(s0, s0 + n)
        write_csv(os.path.join(cdir, name), u[sl], ymeas[sl])
        per_file[name] = rms(diff[sl]) / sigma
        per_file_eff[name] = {f: rms(d[sl]) / sigma for f, d in single.items()}
        clipped[name] = int(np.sum(np.abs(ynoisy[sl]) >= 10.0 - QSTEP))
    files_out, n_session = files, len(u)
    if cml:
        # separate random stream: nothing above (and no other file) changes
        crng = np.random.default_rng([seed, CML_TAG])
        cd = design_cml(crng, case.ev)
        cd["gap"] = float(crng.uniform(2.0, 6.0))
        cnoise = np.random.default_rng(int(crng.integers(2 ** 31)))
        cname = "exp%d_cml.csv" % (len(design["exps"]) + 1)
        ux, cfile, marks = extend_session_cml(u, cd, rise_ms, cname)
        cd.update(marks)
        design["cml"] = cd
        casex = Case(base, ux, files + [cfile])
        casex.n_norm = len(u)  # drifts continue the same realisation
        ybx = casex.simulate([])
        yfx = casex.simulate(effects)
        dx = yfx - ybx
        _, s0, n = cfile
        sl = slice(s0, s0 + n)
        yn = yfx[sl] + sigma * cnoise.standard_normal(n)
        ym = np.clip(np.round(yn / QSTEP), -2 ** 13, 2 ** 13 - 1) * QSTEP
        write_csv(os.path.join(cdir, cname), ux[sl], ym)
        per_file[cname] = rms(dx[sl]) / sigma
        per_file_eff[cname] = {e["form"]: rms((casex.simulate([e]) - ybx)[sl]) / sigma
                               if len(effects) > 1 else per_file[cname] for e in effects}
        clipped[cname] = int(np.sum(np.abs(yn) >= 10.0 - QSTEP))
        files_out, n_session = files + [cfile], len(ux)
    if clean:
        # noiseless outputs with and without the effects, per file (no random draw)
        arrs = {}
        for name, s0, n in files:
            sl = slice(s0, s0 + n)
            arrs[name + ":u"], arrs[name + ":y"], arrs[name + ":y0"] = u[sl], yfin[sl], ybase[sl]
        if cml:
            _, s0, n = cfile
            sl = slice(s0, s0 + n)
            arrs[cname + ":u"], arrs[cname + ":y"], arrs[cname + ":y0"] = ux[sl], yfx[sl], ybx[sl]
        np.savez_compressed(os.path.join(outdir, "truth", "case_%03d_clean.npz" % idx), **arrs)
    m = case.mask
    truth = {
        "case": "case_%03d" % idx,
        "kinds": list(kinds) if kinds else ["none"],
        "forms": [{"kind": e["kind"], "form": e["form"], "params": e["p"],
                   "strength": e["s"], "target_ratio": tg, "ratio_experiments_alone": a}
                  for e, tg, a in zip(effects, targets, achieved)],
        "ratio_experiments": rms(diff[m]) / sigma,
        "ratio_experiments_mean_removed": rms((diff - np.mean(diff[m]))[m]) / sigma,
        "ratio_per_file": per_file,
        "ratio_per_file_per_effect": per_file_eff,
        "noise_rms": sigma, "quant_step": QSTEP,
        "clipped_samples_per_file": clipped,
        "base": base, "step_rise_ms": rise_ms,
        "design": design,
        "files": [{"name": nm, "session_start_s": s0 * DT, "duration_s": n * DT}
                  for nm, s0, n in files_out],
        "session_duration_s": n_session * DT,
        "gen_seconds": time.time() - t0,
    }
    with open(os.path.join(outdir, "truth", "case_%03d.json" % idx), "w") as fh:
        json.dump(_pyify(truth), fh, indent=1)
    return _pyify(truth)


def case_plan(n_per_kind, rng):
    specs = []
    for k in KINDS:
        forms = list(rng.permutation(FORMS[k]))
        for i in range(n_per_kind):
            specs.append(([k], [str(forms[i % len(forms)])]))
    for _ in range(n_per_kind):
        specs.append(([], []))
    n_mix = int(round(7 * n_per_kind / 4.0))
    for _ in range(n_mix):
        k1, k2 = rng.choice(len(KINDS), 2, replace=False)
        ks = [KINDS[k1], KINDS[k2]]
        specs.append((ks, [str(rng.choice(FORMS[k])) for k in ks]))
    order = rng.permutation(len(specs))
    return [specs[i] for i in order]


def case_jobs(outdir, n_per_kind, seed, cml=False, clean=False):
    """The make_case argument tuples of one run, in case order."""
    plan = case_plan(n_per_kind, np.random.default_rng(seed))
    seeds = np.random.SeedSequence(seed).spawn(len(plan))
    return [(i, ks, fs, int(seeds[i].generate_state(1)[0]), outdir, cml, clean)
            for i, (ks, fs) in enumerate(plan)]


def generate(outdir, n_per_kind, seed, workers, cml=False, clean=False):
    os.makedirs(os.path.join(outdir, "truth"), exist_ok=True)
    jobs = case_jobs(outdir, n_per_kind, seed, cml, clean)
    t0 = time.time()
    if workers > 1:
        from multiprocessing import Pool
        with Pool(workers) as pool:
            res = pool.map(make_case, jobs, chunksize=1)
    else:
        res = [make_case(j) for j in jobs]
    summary = {"generator": "blind2", "seed": seed, "cases_per_kind": n_per_kind,
               "n_cases": len(res), "seconds": time.time() - t0,
               "cases": [{"case": r["case"], "kinds": r["kinds"],
                          "forms": [f["form"] for f in r["forms"]],
                          "ratio_experiments": r["ratio_experiments"],
                          "noise_rms": r["noise_rms"]} for r in res]}
    if cml:
        summary["cml"] = True
    with open(os.path.join(outdir, "truth", "summary.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    for r in res:
        print("%s %-32s %-55s ratio=%6.2f" % (r["case"], "+".join(r["kinds"]),
              ",".join(f["form"] for f in r["forms"]) or "-", r["ratio_experiments"]))
    print("generated %d cases in %.1f s" % (len(res), time.time() - t0))


# ----------------------------------------------------------------------------
# Self test
# ----------------------------------------------------------------------------
def self_test():
    ok = True
    rng = np.random.default_rng(1)
    fams = [("gauss_gauss", {"r0": 1.0, "sr": 1.0, "c0": 0.5, "sc": 3.0}),
            ("diagonal_ridge", {"lam": 0.6, "w": 0.5, "r1": 2.0, "s1": 0.8, "c0": -0.5, "sc": 2.0}),
            ("skewed_tilted", {"k": 2.0, "theta": 0.7, "c0": 0.0, "tilt": 0.3, "sc": 3.0, "skew": 2.0})]
    for fam, d in fams:
        ev = Everett(make_density(fam, d))
        # 1) exact agreement with a brute-force sum of relays on grid inputs
        g = ev.grid
        idx = rng.integers(0, len(g), 400)
        v = g[idx]
        A, B = np.meshgrid(g, g, indexing="ij")
        w = ev.mu
        st = -np.ones_like(w)
        yr = np.empty(len(v))
        for k, x in enumerate(v):
            st[A <= x + 1e-9] = 1.0
            st[B >= x - 1e-9] = -1.0
            yr[k] = np.sum(w * st)
        P = Preisach(ev)
        yp = P.run(v)
        e1 = np.max(np.abs(yp - yr))
        # 2) wiping-out (return-point memory)
        seqA = [10, -5, 6, -2, 3, -1, 7, 1]
        seqB = [10, -5, 7, 1]
        ra = Preisach(ev).run(_ramps(seqA))
        rb = Preisach(ev).run(_ramps(seqB))
        e2 = abs(ra[-1] - rb[-1])
        pa = Preisach(ev); pa.run(_ramps(seqA[:6]))
        y_before = pa.peek(3.0)
        e2b = abs(pa.run(_ramps([3.0, 3.0]))[-1] - y_before)
        # return point: after a minor excursion, passing the previous extremum
        # restores the state exactly
        pc = Preisach(ev); pc.run(_ramps([10, -4, 5]))
        y5 = pc.peek(5.0)
        pc.run(_ramps([5, 0, 4, 1, 5]))
        e2c = abs(pc.peek(5.0) - y5)
        # 3) congruency of minor loops between u1=-1 and u2=2 at two levels
        loop = _ramps([-1, 2, -1])
        p1 = Preisach(ev); p1.run(_ramps([10, -1]))
        p2 = Preisach(ev); p2.run(_ramps([10, -5, 2.5, -1]))
        l1, l2 = p1.run(loop), p2.run(loop)
        off = abs(l1[0] - l2[0])
        e3 = np.max(np.abs((l1 - l1[0]) - (l2 - l2[0])))
        good = e1 < 1e-9 and e2 < 1e-12 and e2c < 1e-12 and e3 < 1e-12 and off > 0.01
        ok = ok and good
        print("[%s] %-15s relay-sum max err %.2e | wiping-out err %.2e, return-point err %.2e"
              " | congruent minor loops (level offset %.3f): max shape diff %.2e"
              % ("PASS" if good else "FAIL", fam, e1, e2, e2c, off, e3))
    # 4) rate effects: held input settles within a few ms
    base = {"family": "gauss_gauss", "dens": fams[0][1], "A": 8.0, "rho": 0.2, "offset": 0.0}
    b = Builder(0.0); b.hold(0.2); b.ramp(8.0, 60.0); b.hold(0.5); b.jump(-6.0); b.hold(0.5)
    u = b.array()
    case = Case(base, u, [("exp.csv", 0, len(u))])
    y0 = case.simulate([])
    hold_idx = [int(0.2 / DT) + int(8.0 / 60.0 / DT) + 1, len(u) - int(0.5 / DT)]
    rr = np.random.default_rng(3)
    for form in FORMS["rate"]:
        e = draw_effect(rr, "rate", form)
        if form == "viscous_switching":
            e["s"] = 1.5e-3 / e["p"]["tau0"]
        d = case.simulate([e]) - y0
        worst = 0.0
        for h in hold_idx:
            worst = max(worst, np.max(np.abs(d[h + 15:h + 400])))
        peak = np.max(np.abs(d))
        good = worst < 1e-3 * max(peak, 1e-9) + 1e-9
        ok = ok and good
        print("[%s] rate form %-26s peak diff %.3e V, |diff| 15 ms after hold start < %.1e V"
              % ("PASS" if good else "FAIL", form, peak, worst))
    d = case.simulate([]) - y0
    print("[%s] null case: max |diff| = %.1e" % ("PASS" if np.max(np.abs(d)) == 0 else "FAIL",
                                                   np.max(np.abs(d))))
    print("SELF-TEST", "PASSED" if ok else "FAILED")
    return ok


def _ramps(pts, rate=40.0):
    b = Builder(float(pts[0]))
    b.jump(float(pts[0]))
    for p in pts[1:]:
        b.ramp(float(p), rate)
    return b.array()


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir", nargs="?")
    ap.add_argument("--cases-per-kind", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--cml", action="store_true",
                    help="add a congruent-minor-loop experiment expN_cml.csv to every "
                         "case, recorded after the other experiments (other files "
                         "unchanged; see the module docstring)")
    ap.add_argument("--clean", action="store_true",
                    help="also write truth/case_NNN_clean.npz: every file's input and "
                         "noiseless output with ('FILE:y') and without ('FILE:y0') the "
                         "effects (no random draw added: the CSV files are unchanged)")
    a = ap.parse_args()
    if a.self_test:
        sys.exit(0 if self_test() else 1)
    if not a.outdir:
        ap.error("OUTDIR required")
    generate(a.outdir, a.cases_per_kind, a.seed, a.workers, cml=a.cml, clean=a.clean)


if __name__ == "__main__":
    main()
