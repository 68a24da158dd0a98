"""Write the teaching notebooks in notebooks/ (without outputs) from the cell lists below.

Run:  python scripts/make_notebooks.py     (tests/test_notebooks.py executes them)
"""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parents[1] / "notebooks"

NB01 = [
    new_markdown_cell(
        "# 01 — Preisach basics\n\n"
        "The classical Preisach model (thesis chapter 2): relays, the Preisach plane, the boundary "
        "ψ as the state, wiping-out, congruent minor loops and the Everett function.\n\n"
        "Conventions: volts in, volts out. A relay γ(α, β) switches to +1 when the input reaches "
        "α and to −1 when it falls to β, with α ≥ β; in the other coordinates r = (α − β)/2 is "
        "its half-width and s = (α + β)/2 its offset (Eq 2.9–2.10)."
    ),
    new_code_cell(
        "import numpy as np\n"
        "import matplotlib.pyplot as plt\n"
        "from preisach import PreisachModel, TABLE_3_1\n"
        "from preisach.plotting import plot_boundary, plot_major_loop\n"
        "%matplotlib inline"
    ),
    new_markdown_cell("## One relay\nThe elementary hysteresis operator of Eq 2.3, here with α = 20 V, β = −10 V."),
    new_code_cell(
        "alpha, beta = 20.0, -10.0\n"
        "u = np.r_[np.linspace(-40, 40, 200), np.linspace(40, -40, 200)]\n"
        "state, out = -1.0, []\n"
        "for x in u:\n"
        "    state = 1.0 if x >= alpha else (-1.0 if x <= beta else state)\n"
        "    out.append(state)\n"
        "fig, ax = plt.subplots(figsize=(4, 3))\n"
        "ax.plot(u, out)\n"
        "ax.set_xlabel('input u (V)'); ax.set_ylabel('relay output'); ax.set_title('relay γ(20, −10)')"
    ),
    new_markdown_cell(
        "## A model: the SS15 bimorph at 1 Hz\n"
        "`PreisachModel.builtin` rebuilds the identified surface of Table 3.1 through Eq 3.2. "
        "Its major loop and first-order descending (FOD) curves:"
    ),
    new_code_cell("m = PreisachModel.builtin('ss15-1hz')\nprint(m)\nplot_major_loop(m, n_fod=10)"),
    new_markdown_cell(
        "## The boundary ψ is the state\n"
        "Relays with α ≤ φ(β) are at +1 (P⁺, shaded blue). Each input extremum leaves a corner; "
        "the staircase is the reduced memory sequence. Step through an input history:"
    ),
    new_code_cell(
        "history = [60.0, -40.0, 30.0, -10.0]\n"
        "fig, axes = plt.subplots(1, len(history), figsize=(16, 4))\n"
        "for k, ax in enumerate(axes):\n"
        "    s = m.state_from_extrema(history[: k + 1])\n"
        "    plot_boundary(s, ax=ax)\n"
        "    ax.set_title(f'after {history[: k + 1]} V\\ny = {m.readout(s):.3f} V')\n"
        "fig.tight_layout()"
    ),
    new_markdown_cell(
        "## Wiping-out\nReaching 70 V wipes out every corner made by smaller maxima: the state after "
        "`[60, -40, 30, -10, 70]` equals the state after `[70]` (Mayergoyz's first property)."
    ),
    new_code_cell(
        "a = m.state_from_extrema([60, -40, 30, -10, 70])\n"
        "b = m.state_from_extrema([70])\n"
        "print('same state:', a == b, '| extrema left:', a.extrema())"
    ),
    new_markdown_cell(
        "## Congruent minor loops\nTwo different histories, then the same input excursion between "
        "−20 V and 40 V: the loops differ by a vertical shift only (the second property)."
    ),
    new_code_cell(
        "loop = np.r_[np.linspace(40, -20, 300), np.linspace(-20, 40, 300)]\n"
        "fig, ax = plt.subplots(figsize=(5, 4))\n"
        "shapes = []\n"
        "for hist in ([90, -20, 40], [-100, 80, -20, 40]):\n"
        "    s = m.state_from_extrema(hist)\n"
        "    y = m.simulate(loop, s).output\n"
        "    shapes.append(y - y[0])\n"
        "    ax.plot(loop, y, label=f'history {hist}')\n"
        "ax.set_xlabel('input u (V)'); ax.set_ylabel('output y (V)'); ax.legend()\n"
        "print('largest shape difference (V):', np.abs(shapes[0] - shapes[1]).max())"
    ),
    new_markdown_cell(
        "## The Everett function\nE(α, β) = (y(α, α) − y(α, β))/2 from FOD data (Mayergoyz). "
        "Its mixed second difference per grid cell is the relay weight μ; on the thesis's 1 Hz "
        "surface every weight is non-negative (μ ∈ Mp)."
    ),
    new_code_cell(
        "lv = m.levels[::10]\n"
        "A, B = np.meshgrid(lv, lv, indexing='ij')\n"
        "E = np.where(A >= B, m.everett(A, B), np.nan)\n"
        "fig = plt.figure(figsize=(10, 4))\n"
        "ax = fig.add_subplot(1, 2, 1, projection='3d')\n"
        "ax.plot_surface(A, B, E, cmap='viridis')\n"
        "ax.set_xlabel('α (V)'); ax.set_ylabel('β (V)'); ax.set_zlabel('E (V)')\n"
        "w = PreisachModel.builtin('ss15-1hz', levels=21).cell_weights()\n"
        "ax2 = fig.add_subplot(1, 2, 2)\n"
        "im = ax2.imshow(np.where(np.tril(np.ones_like(w, bool)), w, np.nan), origin='lower',\n"
        "                extent=[-100, 100, -100, 100])\n"
        "ax2.set_xlabel('β (V)'); ax2.set_ylabel('α (V)'); ax2.set_title('cell weights (V)')\n"
        "fig.colorbar(im, ax=ax2)\n"
        "print('smallest cell weight:', w[np.tril_indices(20)].min())"
    ),
    new_markdown_cell(
        "## Neutral states\nψₙˡ (Eq 2.17) has a horizontal segment s = l in the (r, s) plane — held "
        "exactly here, not as a fine staircase. It is the limit of a slowly decaying oscillation "
        "about l, and its slopes up and down are both the reversible slope 2κ(l)."
    ),
    new_code_cell(
        "s_n = m.neutral_state(20.0)\n"
        "fig, axes = plt.subplots(1, 2, figsize=(10, 4))\n"
        "plot_boundary(s_n, ax=axes[0]); plot_boundary(s_n, ax=axes[1], coords='r-s')\n"
        "print('N(20 V) =', round(m.readout(s_n), 4), 'V;', m.slopes(s_n))\n"
        "print('2 kappa(20 V) =', 2 * TABLE_3_1[1].kappa(20.0))"
    ),
]


def write(name: str, cells: list) -> Path:
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    path = HERE / name
    HERE.mkdir(exist_ok=True)
    nbformat.write(nb, path)
    return path


if __name__ == "__main__":
    print(write("01_preisach_basics.ipynb", NB01))
