"""How far a grid's interpolation of the Everett function is from a blind device's own.

Reads the truth files of a blind2 set (``scripts/blind2/generator.py OUT ...``; the base
density of every case) and prints, per case, the RMS error (mV of output) of the Everett
function interpolated from its values on an n-level grid, bilinearly (a bilinear table), by the
core's cubic interpolation (a cubic table, ``EverettTable(..., interpolation="cubic")``) and by
a bicubic spline of the antisymmetric extension (the diagnosis's finer-grid prior of a
bilinear model, ``preisach.diagnose.context.prior_everett``), at 4000 random
``(alpha, beta)`` with ``alpha - beta`` up to 8 V.  A study of the base's resolution floor
(docs/diagnosis.md section 5e); it reads the generator's truth, so run it on seen sets only.

    python scripts/everett_interpolation_error.py /work/blindgen6/out
"""

from __future__ import annotations

import glob
import json
import os
import sys

import numpy as np
from preisach import _core
from scipy.interpolate import RectBivariateSpline, RegularGridInterpolator

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blind2"))
import generator  # noqa: E402  (the blind generator's own Everett tables)


def main(out: str, grids: tuple[int, ...] = (22, 41, 61, 81)) -> None:
    rng = np.random.default_rng(0)
    a = rng.uniform(-10.0, 10.0, 4000)
    b = np.maximum(a - rng.uniform(0.0, 8.0, a.size), -10.0)
    print(
        f"{'case':9s} {'density':16s} " + " ".join(f"{n:>3d}: bilinear cubic spline" for n in grids)
    )
    for path in sorted(glob.glob(os.path.join(out, "truth", "case_*.json"))):
        base = json.load(open(path))["base"]
        ev = generator.Everett(generator.make_density(base["family"], base["dens"]))
        g = ev.grid
        A, B = np.meshgrid(g, g, indexing="ij")
        full = RegularGridInterpolator((g, g), np.where(A >= B, ev.table, -ev.table.T))
        true = full(np.c_[a, b])
        volts = 2.0 * base["A"] * (1.0 - base["rho"])  # output volts per unit of F
        cols = []
        for n in grids:
            lv = np.linspace(-10.0, 10.0, n)
            nodes = full(np.stack(np.meshgrid(lv, lv, indexing="ij"), -1).reshape(-1, 2))
            nodes = nodes.reshape(n, n)
            lin = RegularGridInterpolator((lv, lv), nodes)(np.c_[a, b])
            low = np.tril(nodes, -1)
            core = _core.EverettTable(lv, low, 0.0, "cubic")(a, b)
            cub = RectBivariateSpline(lv, lv, nodes, kx=3, ky=3).ev(a, b)
            rms = [1e3 * volts * float(np.sqrt(np.mean((x - true) ** 2))) for x in (lin, core, cub)]
            cols.append(f"{rms[0]:13.1f} {rms[1]:5.1f} {rms[2]:6.1f}")
        name = os.path.basename(path)[:-5]
        print(f"{name:9s} {base['family']:16s} " + " ".join(cols))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python scripts/everett_interpolation_error.py BLIND_SET_DIR")
    main(sys.argv[1])
