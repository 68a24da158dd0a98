# %% [markdown]
# # 04 — Closed-loop PI regulation and control effort
#
# Chapter 5 of the thesis closes the loop: a PI regulator holds the output at y_d = 1 V
# while noise is injected at the input, and the question becomes *how much the controller
# has to work*. If ψn is the better starting point, the controller should spend less
# effort from it. The discrete PI law (Eq 5.1 → 5.2), sampled at T_s = 1 ms
# (0.5 ms for the 4 Hz initialisation),
#
# $$u_c(k) = K_p\,e(k) + K_i T_s \sum_{j\le k} e(j), \qquad e = y_d - y,$$
#
# with K_p = 1.5 and K_i = 30 (controller units = DAQ volts, ×14.12 at the actuator). The
# controller starts at t₁ + 1 s, noise runs from t₁ + 2 to t₁ + 10 s, the trial ends at
# t₁ + 12 s. The control effort (Eq 5.3) is the 2-norm of what the controller does
# *against the noise*, $n_c = \lVert u_{cn} - \bar u_c \rVert_2$, with $\bar u_c$ its mean
# just before the noise. The loop runs in C++, a batch of trials per call.

# %%
import matplotlib.pyplot as plt
import numpy as np
from preisach import PreisachModel, daq, plotting
from preisach.experiments import (
    THESIS_GAINS,
    ClosedLoopProtocol,
    ModelPlant,
    closed_loop_test,
    drive_to_state,
    regulation_sweep,
    thesis_sample_time,
)

# %matplotlib inline
print(ClosedLoopProtocol())

# %% [markdown]
# ## 1. One trial per initial state (Figs 5.2–5.4)
#
# The same three initial states as in notebook 03, at 1 Hz, noise gain K_n = 1.6. Watch the
# controller output u_c: from ψa and ψd it has to work off the ratchet that the noise
# drives, from ψn much less.

# %%
m = PreisachModel.builtin("ss15-1hz")
plant = ModelPlant(m, thesis_sample_time(1.0))
inits = {k: drive_to_state(plant, k, y_d=1.0, frequency=1.0) for k in ("n", "a", "d")}
fig, (ax_y, ax_c) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
for c, init in zip(("C0", "C3", "C2"), inits.values()):
    r = closed_loop_test(plant, init, gain=1.6, seed=0)
    ax_y.plot(r.time, r.output, lw=0.6, color=c, label=f"{init.name}")
    ax_c.plot(r.time, r.control, lw=0.6, color=c, label=f"{init.name}: n_c = {r.nc:.2f}")
ax_y.axhline(1.0, color="k", ls=":")
ax_y.set_ylabel("output y (V)")
ax_y.legend()
ax_c.set_ylabel("controller output u_c (DAQ V)")
ax_c.set_xlabel("time after t1 (s)")
ax_c.legend()
ax_y.set_title("closed loop at K_n = 1.6, f = 1 Hz (Fig 5.2 style)");

# %% [markdown]
# ## 2. Control effort over gains, states, frequencies and seeds (Figs 5.5–5.7)
#
# Each frequency uses the model identified at that frequency (Table 3.1). Five seeds per
# cell keep this quick; markers are means, bars one standard deviation.

# %%
effort = regulation_sweep("closed-loop", gains=THESIS_GAINS, seeds=range(5), y_d=1.0)
print(effort.format_summary())
plotting.plot_effort_summary(effort)

# %% [markdown]
# ## 3. Table 5.1: how much more effort ψa and ψd need
#
# Table 5.1 of the thesis gives 100 (n_c(ψx) − n_c(ψn)) / n_c(ψn) for each normalised
# noise gain and frequency. Note that the thesis's table is **experimental** (the real SS15,
# means of seven trials): it finds the advantage of ψn real but small ("not significant",
# mostly 1–3 %). Our numbers are **simulated** on the identified models; compare them to
# the thesis's simulated Figs 5.5–5.7 rather than to its table.

# %%
thesis_table_5_1 = np.array([  # K_n/max, a: 1, 2, 4 Hz, d: 1, 2, 4 Hz (experimental, %)
    [0.1429, 0.2277, 1.9916, 0.2666, 6.6523, 6.3656, 18.0776],
    [0.2857, 1.1494, 0.7452, 2.2912, 2.3129, 2.8210, 3.3733],
    [0.4286, 2.6548, 1.7425, -0.0032, 1.9575, 1.5881, 2.0138],
    [0.5714, 1.2536, 1.6094, 0.9816, 1.9920, 0.8368, 1.1421],
    [0.7143, 1.4988, 1.2737, 1.1755, 1.3567, 1.2008, 1.0495],
    [0.8571, 1.5130, 1.2553, 1.4559, 1.4250, 1.0649, 0.7772],
    [1.0, 2.0443, 1.3737, 1.2434, 1.4365, 0.7818, 1.5092]])
print("simulated here (%):")
print(effort.format_percentage_table())
print("\nthesis Table 5.1, measured on the SS15 (%):")
print("\n".join(" ".join(f"{v:9.4f}" for v in row) for row in thesis_table_5_1))
plotting.plot_effort_increase(effort)

# %%
plotting.plot_paired_differences(effort)

# %% [markdown]
# The sweep result displays as tables: n_c mean ± std per state, Table 5.1's layout, and the
# thesis's claims checked cell by cell.

# %%
effort

# %% [markdown]
# Where does ψn need the least effort? The thesis's simulations (Figs 5.5–5.7) say: at
# every gain at 1 and 2 Hz, and at 4 Hz only up to K_n = 4.0 (Fig 5.7); its *experiments*
# kept the advantage at 4 Hz too (Table 5.1: ψa 1.2–1.5 % above ψn at K_n ≥ 4.0).
# Count it here, frequency by frequency, on the means over seeds and seed by seed:

# %%
for f in effort.frequencies:
    rows = [c for c in effort.comparisons() if c["frequency"] == f]
    print(f"{f:g} Hz: n_c(psi_n) smallest at {sum(c['n_smallest'] for c in rows)}/"
          f"{len(rows)} gains; seed by seed below psi_a in "
          f"{min(c['frac_n_below_a'] for c in rows):.0%}+ and below psi_d in "
          f"{min(c['frac_n_below_d'] for c in rows):.0%}+ of the seeds at every gain")

# %% [markdown]
# ## 4. The same experiment on a rig
#
# Nothing above depends on where the output comes from: the experiments talk to a *plant*.
# `daq.DevicePlant` makes any DAQ device a plant — every run is a trial of the C++ runner,
# recorded to a file — so the same code runs on the virtual SS15 (below) or on a Comedi card.
# The rig adds what a model does not have: the amplifier calibration, ADC noise and
# quantisation, and the clocked loop's one-sample delay. On a device `drive_to_state`
# uses the thesis's experimental landing windows (Table 4.1) by default; here we ask for
# the simulation's tighter ones so that the rig starts from the same states as the model.

# %%
rig_plant = daq.DevicePlant(daq.virtual_ss15("ss15-1hz", seed=4), model=m)
for k in ("n", "a"):
    init = drive_to_state(rig_plant, k, y_d=1.0, frequency=1.0, thresholds="simulation")
    r = closed_loop_test(rig_plant, init, gain=1.6, seed=0)
    print(f"rig, {init.name}: landed at y = {init.y_end:.4f} V after {init.iterations} "
          "runs; "
          f"n_c = {r.nc:.2f} (the model plant gave "
          f"{closed_loop_test(plant, inits[k], gain=1.6, seed=0).nc:.2f})")
print(f"{len(rig_plant.results)} trials recorded in {rig_plant.record_dir}")

# %% [markdown]
# ## What to take away
#
# * In simulation n_c(ψn) is below n_c(ψa) and n_c(ψd) at every gain at 1 and 2 Hz, as the
#   thesis reports.
# * At 4 Hz the simulation **disagrees** with the thesis's own simulation (Fig 5.7, where
#   ψn's advantage disappears above K_n = 4.0): the count above (and the full study, 20
#   seeds: ψn smallest at 7/7 gains, below ψa on every seed and below ψd on ≥ 90 % of
#   seeds) keeps ψn best at every gain. The thesis's *rig* agrees with us, not with its
#   Fig 5.7: Table 5.1's 4 Hz column has ψa 1.2–1.5 % above ψn at K_n ≥ 4.0.
#   `python scripts/chapter5_study.py` tests the candidates one at a time (μ ≥ 0, 1 ms
#   sampling, a coarse quantised table, the noise's units, the rate-dependent model
#   `ss15-rate`): none reproduces Fig 5.7.
# * The thesis's experiments found the ordering with a much smaller margin (Table 5.1,
#   mostly 1–3 %, against 10–43 % here). Of the left-out physics the study tries (rate
#   dependence, sensor noise with the 25 ms error averaging, creep, amplifier lag) only the
#   rate-dependent model moves the table toward the rig — its margins no longer grow with the
#   initialisation frequency — and none closes the ~10 × gap at 1 Hz, not even rate
#   dependence with creep and the amplifier lag in one plant (`RatePlant` with
#   `input_blocks`/`output_blocks`: ψa 13 % median at every frequency). Notebook 05 shows how to
#   look for such physics in recordings.
#
# **Full study.** `python scripts/regulation_study.py --seeds 20` (3 frequencies × 3 states ×
# 7 gains × 20 seeds, Table 5.1 and the sensitivity of the verdicts), or
# `preisach experiment closed-loop --model ss15 --json effort.json --plot effort.png`.
# Speed: `python benchmarks/bench_experiments.py`.
