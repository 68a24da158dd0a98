# %% [markdown]
# # 01 — Preisach basics
#
# The classical Preisach model (thesis chapter 2): relays, the Preisach plane, the boundary ψ as the
# state, wiping-out, congruent minor loops and the Everett function.
#
# Conventions: volts in, volts out. A relay γ(α, β) switches to +1 when the input reaches α and to
# −1 when it falls to β, with α ≥ β; in the other coordinates r = (α − β)/2 is its half-width and s
# = (α + β)/2 its offset (Eq 2.9–2.10).

# %%
import matplotlib.pyplot as plt
import numpy as np
from preisach import TABLE_3_1, PreisachModel
from preisach.plotting import plot_boundary, plot_major_loop

# %matplotlib inline

# %% [markdown]
# ## One relay
# The elementary hysteresis operator of Eq 2.3, here with α = 20 V, β = −10 V.

# %%
alpha, beta = 20.0, -10.0
u = np.r_[np.linspace(-40, 40, 200), np.linspace(40, -40, 200)]
state, out = -1.0, []
for x in u:
    state = 1.0 if x >= alpha else (-1.0 if x <= beta else state)
    out.append(state)
fig, ax = plt.subplots(figsize=(4, 3))
ax.plot(u, out)
ax.set_xlabel('input u (V)')
ax.set_ylabel('relay output (1)')
ax.set_title('relay γ(20, −10)');

# %% [markdown]
# ## A model: the SS15 bimorph at 1 Hz
# `PreisachModel.builtin` rebuilds the identified surface of Table 3.1 through Eq 3.2. Its major
# loop and first-order descending (FOD) curves:

# %%
m = PreisachModel.builtin('ss15-1hz')
print(m)
plot_major_loop(m, n_fod=10)

# %% [markdown]
# In Jupyter a model displays as a table - levels, input and output range, whether every relay
# mass is non-negative - with a thumbnail of its major loop; `print(m)` is the one-line form.

# %%
m

# %% [markdown]
# ## The boundary ψ is the state
# Relays with α ≤ φ(β) are at +1 (P⁺, shaded blue). Each input extremum leaves a corner; the
# staircase is the reduced memory sequence. Step through an input history:

# %%
history = [60.0, -40.0, 30.0, -10.0]
fig, axes = plt.subplots(1, len(history), figsize=(16, 4))
for k, ax in enumerate(axes):
    s = m.state_from_extrema(history[: k + 1])
    plot_boundary(s, ax=ax)
    ax.set_title(f'after {history[: k + 1]} V\ny = {m.readout(s):.3f} V')
fig.tight_layout()

# %% [markdown]
# ## Wiping-out
# Reaching 70 V wipes out every corner made by smaller maxima: the state after `[60, -40, 30, -10,
# 70]` equals the state after `[70]` (Mayergoyz's first property).

# %%
a = m.state_from_extrema([60, -40, 30, -10, 70])
b = m.state_from_extrema([70])
print('same state:', a == b, '| extrema left:', a.extrema())

# %% [markdown]
# ## Congruent minor loops
# Two different histories, then the same input excursion between −20 V and 40 V: the loops differ by
# a vertical shift only (the second property).

# %%
loop = np.r_[np.linspace(40, -20, 300), np.linspace(-20, 40, 300)]
fig, ax = plt.subplots(figsize=(5, 4))
shapes = []
for hist in ([90, -20, 40], [-100, 80, -20, 40]):
    s = m.state_from_extrema(hist)
    y = m.simulate(loop, s).output
    shapes.append(y - y[0])
    ax.plot(loop, y, label=f'history {hist}')
ax.set_xlabel('input u (V)')
ax.set_ylabel('output y (V)')
ax.legend()
print('largest shape difference (V):', np.abs(shapes[0] - shapes[1]).max())

# %% [markdown]
# ## The Everett function
# E(α, β) = (y(α, α) − y(α, β))/2 from FOD data (Mayergoyz). Its mixed second difference per grid
# cell is the relay weight μ; on the thesis's 1 Hz surface every weight is non-negative (μ ∈ Mp).

# %%
lv = m.levels[::10]
A, B = np.meshgrid(lv, lv, indexing='ij')
E = np.where(A >= B, m.everett(A, B), np.nan)
fig = plt.figure(figsize=(10, 4))
ax = fig.add_subplot(1, 2, 1, projection='3d')
ax.plot_surface(A, B, E, cmap='viridis')
ax.set_xlabel('α (V)')
ax.set_ylabel('β (V)')
ax.set_zlabel('E (V)')
w = PreisachModel.builtin('ss15-1hz', levels=21).cell_weights()
ax2 = fig.add_subplot(1, 2, 2)
im = ax2.imshow(np.where(np.tril(np.ones_like(w, bool)), w, np.nan), origin='lower',
                extent=[-100, 100, -100, 100])
ax2.set_xlabel('β (V)')
ax2.set_ylabel('α (V)')
ax2.set_title('cell weights (V)')
fig.colorbar(im, ax=ax2)
print('smallest cell weight:', w[np.tril_indices(20)].min())

# %% [markdown]
# ## Neutral states
# ψₙˡ (Eq 2.17) has a horizontal segment s = l in the (r, s) plane — held exactly here, not as a
# fine staircase. It is the limit of a slowly decaying oscillation about l, and its slopes up and
# down are both the reversible slope 2κ(l).

# %%
s_n = m.neutral_state(20.0)
fig, axes = plt.subplots(1, 2, figsize=(10, 4))
plot_boundary(s_n, ax=axes[0])
plot_boundary(s_n, ax=axes[1], coords='r-s')
print('N(20 V) =', round(m.readout(s_n), 4), 'V;', m.slopes(s_n))
print('2 kappa(20 V) =', 2 * TABLE_3_1[1].kappa(20.0))
