"""Draw the README's concept figure: docs/concepts.png.

Run:  python scripts/make_readme_figure.py [--out docs/concepts.png]

Four panels on the built-in 1 Hz SS15 model (Table 3.1 through Eq 3.2): (a) one relay
gamma(alpha, beta) (Eq 2.3); (b) the Preisach plane with P+ / P- and the boundary psi left by
the input history 60, -40, 20 V; (c) the major loop and first-order descending curves (the
identification data, Fig 3.17-3.20); (d) the neutral locus N(l) with psi_n, psi_a and psi_d for
y_d = 1 V (Figs 4.6-4.8).  Everything comes from ``preisach.plotting``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from preisach import PreisachModel, plotting

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "concepts.png"))
    a = ap.parse_args(argv)
    m = PreisachModel.builtin("ss15-1hz")
    fig = Figure(figsize=(17, 4.2))
    ax = fig.subplots(1, 4)

    alpha, beta = 20.0, -10.0
    u = np.r_[np.linspace(-40, 40, 200), np.linspace(40, -40, 200)]
    state, out = -1.0, []
    for x in u:
        state = 1.0 if x >= alpha else (-1.0 if x <= beta else state)
        out.append(state)
    ax[0].plot(u[:200], out[:200], color="tab:red", label="rising: on at alpha")
    ax[0].plot(u[200:], out[200:], color="tab:blue", ls="--", label="falling: off at beta")
    ax[0].set_xlabel("input u (V)")
    ax[0].set_ylabel("relay output (1)")
    ax[0].set_title("(a) one relay, alpha = 20 V, beta = -10 V")
    ax[0].legend(fontsize=8, loc="center right")

    plotting.plot_boundary(m.state_from_extrema([60.0, -40.0, 20.0]), ax=ax[1])
    ax[1].set_title("(b) state = boundary psi after 60, -40, 20 V")
    plotting.plot_major_loop(m, n_fod=10, ax=ax[2], title="(c) major loop and FOD curves")
    plotting.plot_neutral_locus(m, y_d=1.0, ax=ax[3], title="(d) N(l) and three states, y = 1 V")
    ax[3].set_xlim(-20, 60)
    ax[3].set_ylim(-1.0, 2.5)
    fig.tight_layout()
    out_path = Path(a.out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=90)
    print(f"wrote {out_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
