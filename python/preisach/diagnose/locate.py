"""Locate a mismatch: where, when and in which band the residual lives, and what it follows.

The residual ``r = y_meas - y_sim`` (V) of every recording is related to

* the recording and the time within it (RMS in time windows),
* the input level and direction (rising, falling, holding): a residual map,
* the time since the last input reversal and since the input last moved, with the residual
  signed by the direction of that move (creep continues in the direction of the move),
* the input rate ``du/dt`` (V/s), the model's output rate ``dy/dt`` (V/s; a delay leaves
  ``-tau dy/dt``), the output level (V) and the absolute time (s),
* frequency: Welch spectra of ``r`` and of ``y``, the share of residual power per band and
  narrow peaks in the residual spectrum.

For every covariate the strength of the relation is the correlation ratio ``eta^2`` (the share
of the residual variance explained by its mean in bins of the covariate, which catches
non-monotone relations) with a block-permutation p-value: the residual is cut into blocks of
``perm_block`` seconds, which are shuffled against the covariate, so that the residual's
autocorrelation is kept under the null hypothesis of no relation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.integrate import trapezoid

__all__ = [
    "Covariate",
    "ResidualAnalysis",
    "amount_text",
    "analyse_residuals",
    "display_unit",
    "motion_features",
]

Array = NDArray[np.float64]

BANDS_HZ: tuple[tuple[float, float], ...] = (
    (0.0, 1.0),
    (1.0, 5.0),
    (5.0, 20.0),
    (20.0, 60.0),
    (60.0, math.inf),
)


def display_unit(unit: str = "V") -> tuple[float, str]:
    """Factor and name to show output amounts in: millivolts for volts, else the unit itself.

    Diagnosis computes in the recordings' output unit (``Recording.metadata["output_units"]``,
    ``"V"`` by default); a report on another quantity (a magnetometer's moment in ``A m^2``,
    say) states it in that unit, unscaled.
    """
    return (1e3, "mV") if unit == "V" else (1.0, unit)


def amount_text(value: float, unit: str, fmt: str = ".3g") -> str:
    """``value`` (in ``unit``) as text with its display unit: ``0.0123, "V"`` -> ``12.3 mV``."""
    k, name = display_unit(unit)
    return f"{k * value:{fmt}} {name}"


@dataclass
class Covariate:
    """Binned relation of the residual to one covariate."""

    name: str
    unit: str
    centers: Array
    mean: Array
    rms: Array
    count: Array
    eta2: float
    p_value: float
    signed_by_move: bool = False

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form."""
        return {
            "unit": self.unit,
            "eta2": self.eta2,
            "p_value": self.p_value,
            "signed_by_move": self.signed_by_move,
            "bins": [float(c) for c in self.centers],
            "mean": [float(m) for m in self.mean],
            "rms": [float(m) for m in self.rms],
            "count": [int(c) for c in self.count],
        }


@dataclass
class ResidualAnalysis:
    """Where the residual lives and what it follows (outputs in the recordings' unit; s)."""

    noise_sigma: float
    rms: float
    per_recording: list[dict[str, Any]]
    covariates: dict[str, Covariate]
    input_map: dict[str, Array]
    spectrum: dict[str, Any]
    time_maps: list[dict[str, Array]] = field(default_factory=list)

    def strongest(self, k: int = 3, alpha: float = 0.01) -> list[Covariate]:
        """Covariates with significant relations, strongest first."""
        sig = [c for c in self.covariates.values() if c.p_value < alpha]
        return sorted(sig, key=lambda c: -c.eta2)[:k]

    def summary(self, unit: str = "V") -> list[str]:
        """Readable lines; amounts in ``unit`` (the output's: volts are shown in mV)."""
        k, name = display_unit(unit)
        lines = [
            f"residual RMS {k * self.rms:.4g} {name}, noise {k * self.noise_sigma:.3g} {name} "
            f"(ratio {self.rms / self.noise_sigma if self.noise_sigma > 0 else float('nan'):.3g})"
        ]
        for p in sorted(self.per_recording, key=lambda d: -d["rms"]):
            lines.append(f"  {p['name']}: RMS {k * p['rms']:.4g} {name} over {p['duration']:.3g} s")
        for c in sorted(self.covariates.values(), key=lambda c: -c.eta2):
            lines.append(f"  follows {c.name}: eta^2 = {c.eta2:.3f} (p = {c.p_value:.3g})")
        b = self.spectrum.get("bands", [])
        if b:
            top = max(b, key=lambda d: d["residual_share"])
            lines.append(
                f"  most residual power in {top['lo']:g}-{top['hi']:g} Hz "
                f"({100 * top['residual_share']:.0f} %)"
            )
        for pk in self.spectrum.get("peaks", []):
            lines.append(
                f"  residual spectrum peak at {pk['f']:.3g} Hz ({pk['prominence_db']:.1f} dB)"
            )
        return lines

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form (without the spectra arrays)."""
        return {
            "noise_sigma": self.noise_sigma,
            "rms": self.rms,
            "per_recording": self.per_recording,
            "covariates": {k: c.to_dict() for k, c in self.covariates.items()},
            "bands": self.spectrum.get("bands", []),
            "peaks": self.spectrum.get("peaks", []),
        }


def motion_features(u: Array, dt: float, tol: float) -> dict[str, Array]:
    """Input rate, direction, time since the last reversal and since the last move.

    ``direction`` is +1 (rising), -1 (falling) or 0 (holding, ``|du/dt|`` below ``tol`` V per
    sample); ``last_dir`` is the direction of the last move (holds keep it).  A reversal is a
    change of ``last_dir``.
    """
    du = np.gradient(u) if u.size > 1 else np.zeros_like(u)
    moving = np.abs(du) > tol
    direction = np.where(moving, np.sign(du), 0.0)
    # last direction of motion, carried through holds
    idx = np.where(moving, np.arange(u.size), -1)
    idx = np.maximum.accumulate(idx)
    last_dir = np.where(idx >= 0, direction[np.clip(idx, 0, None)], 0.0)
    since_move = (np.arange(u.size) - np.where(idx >= 0, idx, 0)) * dt
    since_move[idx < 0] = np.nan
    rev = np.flatnonzero(np.diff(last_dir) != 0) + 1
    rev = rev[last_dir[rev - 1] != 0]
    last_rev = np.full(u.size, -1)
    last_rev[rev] = rev
    last_rev = np.maximum.accumulate(last_rev)
    since_rev = (np.arange(u.size) - last_rev) * dt
    since_rev[last_rev < 0] = np.nan
    return {
        "rate": du / dt,
        "direction": direction,
        "last_dir": last_dir,
        "since_move": since_move,
        "since_reversal": since_rev,
    }


def _bins(x: Array, n: int, log: bool) -> Array:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return np.array([0.0, 1.0])
    if log:
        pos = x[x > 0]
        if pos.size == 0:
            return np.array([0.0, 1.0])
        lo, hi = np.quantile(pos, 0.01), pos.max()
        lo = max(lo, hi * 1e-6)
        return np.concatenate([[0.0], np.geomspace(lo, hi * (1 + 1e-9), n)])
    e = np.unique(np.quantile(x, np.linspace(0, 1, n + 1)))
    if e.size < 2:
        e = np.array([x.min() - 0.5, x.max() + 0.5])
    e[-1] += 1e-9 * max(1.0, abs(e[-1]))
    return e


def _eta2(
    r: Array, code: NDArray[np.integer[Any]], nb: int, cnt: NDArray[np.integer[Any]] | None = None
) -> float:
    if cnt is None:  # the bin counts (the same for every permutation of r)
        cnt = np.bincount(code, minlength=nb)
    s = np.bincount(code, weights=r, minlength=nb)
    tot = float(np.sum((r - r.mean()) ** 2))
    if tot <= 0:
        return 0.0
    ok = cnt > 0
    between = float(np.sum(s[ok] ** 2 / cnt[ok]) - r.sum() ** 2 / r.size)
    return max(between / tot, 0.0)


def _covariate(
    name: str,
    unit: str,
    x: Array,
    r: Array,
    blocks: Array,
    rng: np.random.Generator,
    n_perm: int,
    log: bool = False,
    signed_by_move: bool = False,
    n_bins: int = 12,
) -> Covariate:
    ok = np.isfinite(x) & np.isfinite(r)
    x, r, blocks = x[ok], r[ok], blocks[ok]
    edges = _bins(x, n_bins, log)
    code = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    nb = edges.size - 1
    # merge sparse bins into neighbours: drop bins with < 20 samples from the statistic
    cnt = np.bincount(code, minlength=nb)
    eta = _eta2(r, code, nb) if r.size > 30 else 0.0
    # block permutation: shuffle residual blocks against the covariate
    ub, start = np.unique(blocks, return_index=True)
    first = start if ub.size > 1 else np.zeros(1, np.int64)
    length = np.diff(np.append(first, r.size))
    exceed = 0
    if first.size >= 4 and eta > 0:
        pos = np.arange(r.size)
        for _ in range(n_perm):
            perm = rng.permutation(first.size)
            # the blocks in the permuted order: block k's samples first[k] .. first[k] + length[k]
            n_k = length[perm]
            ends = np.cumsum(n_k)
            idx = pos + np.repeat(first[perm] - (ends - n_k), n_k)
            if _eta2(r[idx], code, nb, cnt) >= eta:
                exceed += 1
        p = (1 + exceed) / (1 + n_perm)
    else:
        p = 1.0
    s = np.bincount(code, weights=r, minlength=nb)
    s2 = np.bincount(code, weights=r * r, minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, s / np.maximum(cnt, 1), np.nan)
        rms = np.where(cnt > 0, np.sqrt(s2 / np.maximum(cnt, 1)), np.nan)
    centers = 0.5 * (edges[:-1] + edges[1:])
    return Covariate(
        name, unit, centers, mean, rms, cnt.astype(float), float(eta), float(p), signed_by_move
    )


def analyse_residuals(
    recs: Sequence[Any],
    residuals: Sequence[Array],
    predictions: Sequence[Array],
    noise_sigma: float,
    *,
    u_span: float,
    perm_block: float = 0.25,
    n_perm: int = 199,
    seed: int = 0,
) -> ResidualAnalysis:
    """Analyse residuals of prepared recordings (see the module docstring).

    Parameters
    ----------
    recs : sequence of prepared recordings
        Objects with ``name``, ``t``, ``u``, ``y``, ``dt`` and ``usable`` (see
        :func:`preisach.diagnose.data.prepare_recordings`).
    residuals, predictions : sequence of ndarray
        ``y - y_sim`` and ``y_sim`` (V) per recording; NaN residuals are ignored.
    noise_sigma : float
        Noise standard deviation (V).
    u_span : float
        Input range (V); 0.05 % of it per sample is the threshold between moving and holding.
    perm_block : float
        Length (s) of the residual blocks shuffled by the permutation test.
    n_perm : int
        Number of permutations (p-values are at least ``1 / (n_perm + 1)``).
    seed : int
        Seed of the permutations.

    """
    rng = np.random.default_rng(seed)
    tol = 5e-4 * u_span
    cols: dict[str, list[Array]] = {
        k: []
        for k in (
            "r",
            "rs",
            "u",
            "dir",
            "rate",
            "yrate",
            "since_rev",
            "since_move",
            "ylev",
            "time",
            "blk",
        )
    }
    per_rec, time_maps = [], []
    spectra = []
    next_blk = 0
    for rec, res, pred in zip(recs, residuals, predictions):
        m = rec.usable & np.isfinite(res)
        f = motion_features(rec.u, rec.dt, tol)
        yrate = np.gradient(pred, rec.dt)
        blk = np.floor((rec.t - rec.t[0]) / perm_block).astype(np.int64) + next_blk
        next_blk = int(blk[-1]) + 1
        cols["r"].append(res[m])
        cols["rs"].append((res * np.where(f["last_dir"] == 0, 1.0, f["last_dir"]))[m])
        cols["u"].append(rec.u[m])
        cols["dir"].append(f["direction"][m])
        cols["rate"].append(f["rate"][m])
        cols["yrate"].append(yrate[m])
        cols["since_rev"].append(f["since_reversal"][m])
        cols["since_move"].append(f["since_move"][m])
        cols["ylev"].append(pred[m])
        cols["time"].append((rec.t - rec.t[0])[m])
        cols["blk"].append(blk[m])
        rr = res[m]
        per_rec.append(
            {
                "name": rec.name,
                "rms": float(np.sqrt(np.mean(rr**2))) if rr.size else float("nan"),
                "mean": float(rr.mean()) if rr.size else float("nan"),
                "duration": float(rec.t[-1] - rec.t[0]),
                "samples": int(rr.size),
            }
        )
        # time map: RMS per window
        win = max(1, int(round(0.1 / rec.dt)))
        nwin = rec.n // win
        if nwin >= 2:
            sq = np.where(m, np.nan_to_num(res) ** 2, 0.0)[: nwin * win].reshape(nwin, win)
            cnt = m[: nwin * win].reshape(nwin, win).sum(axis=1)
            tm = np.full(nwin, np.nan)
            tm[cnt > 0] = np.sqrt(sq.sum(axis=1)[cnt > 0] / cnt[cnt > 0])
            time_maps.append({"t": rec.t[: nwin * win].reshape(nwin, win).mean(axis=1), "rms": tm})
        # spectra on the longest usable stretch
        good = np.flatnonzero(m)
        if good.size > 64:
            seg = slice(good[0], good[-1] + 1)
            rseg = np.nan_to_num(res[seg])
            nper = int(
                min(
                    rseg.size,
                    2 ** int(math.floor(math.log2(max(64, min(rseg.size, 2.0 / rec.dt))))),
                )
            )
            fr, pr = signal.welch(rseg - rseg.mean(), fs=1 / rec.dt, nperseg=nper)
            _, py_ = signal.welch(rec.y[seg] - rec.y[seg].mean(), fs=1 / rec.dt, nperseg=nper)
            spectra.append((fr, pr, py_, rseg.size))
    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in cols.items()}
    r = cat["r"]
    covs: dict[str, Covariate] = {}
    blk = cat["blk"]
    covs["input_rate"] = _covariate("input rate du/dt", "V/s", cat["rate"], r, blk, rng, n_perm)
    covs["output_rate"] = _covariate(
        "model output rate dy/dt", "V/s", cat["yrate"], r, blk, rng, n_perm
    )
    covs["time_since_reversal"] = _covariate(
        "time since the last input reversal",
        "s",
        cat["since_rev"],
        cat["rs"],
        blk,
        rng,
        n_perm,
        log=True,
        signed_by_move=True,
    )
    covs["time_since_move"] = _covariate(
        "time since the input last moved",
        "s",
        cat["since_move"],
        cat["rs"],
        blk,
        rng,
        n_perm,
        log=True,
        signed_by_move=True,
    )
    covs["output_level"] = _covariate("model output level", "V", cat["ylev"], r, blk, rng, n_perm)
    covs["time"] = _covariate("time in the recording", "s", cat["time"], r, blk, rng, n_perm)
    # residual map over input level and direction
    edges = np.linspace(
        np.min(cat["u"]) if r.size else 0.0, np.max(cat["u"]) if r.size else 1.0, 21
    )
    code = np.clip(np.searchsorted(edges, cat["u"], side="right") - 1, 0, 19)
    imap: dict[str, Array] = {"levels": 0.5 * (edges[:-1] + edges[1:])}
    for key, sel in (
        ("rising", cat["dir"] > 0),
        ("falling", cat["dir"] < 0),
        ("holding", cat["dir"] == 0),
    ):
        cnt = np.bincount(code[sel], minlength=20)
        s = np.bincount(code[sel], weights=r[sel], minlength=20)
        s2 = np.bincount(code[sel], weights=r[sel] ** 2, minlength=20)
        with np.errstate(invalid="ignore", divide="ignore"):
            imap[f"{key}_mean"] = np.where(cnt >= 5, s / np.maximum(cnt, 1), np.nan)
            imap[f"{key}_rms"] = np.where(cnt >= 5, np.sqrt(s2 / np.maximum(cnt, 1)), np.nan)
        imap[f"{key}_count"] = cnt.astype(float)
    spec: dict[str, Any] = {}
    if spectra:
        f0 = max(spectra, key=lambda s: s[3])[0]
        w = np.array([s[3] for s in spectra], float)
        pr = sum(np.interp(f0, s[0], s[1]) * wi for s, wi in zip(spectra, w)) / w.sum()
        py_ = sum(np.interp(f0, s[0], s[2]) * wi for s, wi in zip(spectra, w)) / w.sum()
        spec = {"f": f0, "residual_psd": pr, "output_psd": py_}
        tot = float(trapezoid(pr, f0)) if f0.size > 1 else 0.0
        bands = []
        for lo, hi in BANDS_HZ:
            sel = (f0 >= lo) & (f0 < hi)
            if sel.sum() < 2 or tot <= 0:
                continue
            pr_b = float(trapezoid(pr[sel], f0[sel]))
            py_b = float(trapezoid(py_[sel], f0[sel]))
            bands.append(
                {
                    "lo": lo,
                    "hi": float(min(hi, f0[-1])),
                    "residual_share": pr_b / tot,
                    "residual_to_output": pr_b / py_b if py_b > 0 else float("inf"),
                }
            )
        spec["bands"] = bands
        # narrow peaks of the residual spectrum above 5 Hz, >= 10 dB above the local median
        lp = 10 * np.log10(np.maximum(pr, 1e-300))
        k = max(3, int(len(f0) / 40))
        base = np.array([np.median(lp[max(0, i - k) : i + k + 1]) for i in range(lp.size)])
        prom = lp - base
        idx, _ = signal.find_peaks(prom, height=10.0)
        idx = [i for i in idx if f0[i] > 5.0]
        spec["peaks"] = [
            {"f": float(f0[i]), "prominence_db": float(prom[i])}
            for i in sorted(idx, key=lambda i: -prom[i])[:3]
        ]
    total_rms = float(np.sqrt(np.mean(r**2))) if r.size else float("nan")
    return ResidualAnalysis(noise_sigma, total_rms, per_rec, covs, imap, spec, time_maps)
