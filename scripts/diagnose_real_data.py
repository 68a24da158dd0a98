"""Diagnose the real piezo recording yan9a-piezo/Model_Vi_Do.dat (see ../shared/data/README.md).

The file holds about 40 cycles of a 1 Hz, 0-3.6 V sinusoidal drive (column 1) and the
capacitive sensor reading (column 5, unit undocumented; called V here), sampled at 200 Hz.
The first ``--ident-cycles`` cycles identify a model by least squares
(:func:`preisach.identify.identify_lsq`, 21 levels, no output delay assumed - the authors
assume one sample, which is left for diagnosis to find); the rest is cut into ``--pieces``
recordings and diagnosed, with the identification part given as identification data.

    python scripts/diagnose_real_data.py [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DATA = (
    Path(os.environ.get("PREISACH_DATA") or ROOT.parent / "shared" / "data")
    / "yan9a-piezo"
    / "Model_Vi_Do.dat"
)


def load(path: Path = DATA, ident_cycles: int = 10, pieces: int = 4):
    """``(identification recording, diagnosis recordings)`` from the data file."""
    from preisach import Recording

    d = np.loadtxt(path)
    dt = 0.005
    u, y = d[:, 0], d[:, 4]
    n_id = int(round(ident_cycles / dt))
    ident = Recording.from_arrays(
        u=u[:n_id],
        y=y[:n_id],
        sample_time=dt,
        experiment="identification",
        metadata={"initial_state": "unknown", "source": str(path.name)},
    )
    rest = np.arange(n_id, u.size)
    recs = []
    for k, idx in enumerate(np.array_split(rest, pieces)):
        recs.append(
            Recording.from_arrays(
                t=idx * dt,
                u=u[idx],
                y=y[idx],
                experiment=f"cycles_{k}",
                metadata={"initial_state": "unknown", "source": str(path.name)},
            )
        )
    return ident, recs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--ident-cycles", type=int, default=10)
    ap.add_argument("--pieces", type=int, default=4)
    ap.add_argument("--levels", type=int, default=21)
    ap.add_argument(
        "--out", default="", help="folder for report.json, diagnosis.png, augmented.npz"
    )
    a = ap.parse_args(argv)
    from preisach.diagnose import diagnose
    from preisach.identify import identify_lsq

    ident, recs = load(Path(a.data), a.ident_cycles, a.pieces)
    model, ident_report = identify_lsq(ident, a.levels, name="yan9a, least squares")
    print(f"identified {model} from {ident.duration:.1f} s ({a.ident_cycles} cycles)")
    rep = diagnose(model, recs, identification=ident, progress=print)
    print(rep.summary())
    if a.out:
        import matplotlib

        matplotlib.use("Agg")
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        rep.to_json(out / "report.json")
        rep.plot().savefig(out / "diagnosis.png", dpi=110)
        rep.model.save(out / "augmented.npz")
        print(f"wrote {out}/report.json, diagnosis.png, augmented.npz")
    return 0


if __name__ == "__main__":
    sys.exit(main())
