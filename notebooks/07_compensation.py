# %% [markdown]
# # 07 — Compensation: the inverse model as feedforward
#
# An open-loop piezo stage driven through a linear gain misses its target by several percent
# of its stroke: the hysteresis. The Preisach model predicts the output from the input; its
# **inverse** gives the input that makes the output follow a reference. Put in front of the
# actuator (feedforward), it cancels the hysteresis up to the model's error.
#
# The inverse here is exact, not iterative: along a monotone input excursion the model's
# output is piecewise linear in the input inside each cell of the bilinear Everett table
# (quadratic for the antidiagonal pieces of neutral states), and the excursion wipes out
# memory as the model does. So each target is a search over table cells plus a closed-form
# root, from the model's current state, and `simulate(inverse(y).input)` gives `y` back.

# %%
import matplotlib.pyplot as plt
import numpy as np
from preisach import PreisachModel, daq
from preisach.compensate.rig import identify_from_device
from preisach.compensate.tracking import device_loop, run_tracking, tracking_references

# %matplotlib inline
model = PreisachModel.builtin("ss15-1hz")
print(model)

# %% [markdown]
# ## 1. The inverse reproduces the reference, memory included
#
# A reference with reversals, from the anhysteretic state: the input the inverse finds, the
# output it gives back, and the input-output loop that it traces (minor loops closing where
# the model's memory says they must).

# %%
t = np.arange(0, 3, 1e-3)
y_ref = 1.5 * np.sin(2 * np.pi * 1.0 * t) * np.exp(-t / 2) + 0.6 * np.sin(2 * np.pi * 3 * t)
inv = model.inverse(y_ref, model.anhysteretic_state(), t=t)
check = model.simulate(inv.input, model.anhysteretic_state())
print(f"unreachable targets: {inv.unreachable}")
print(f"max |simulate(inverse(y)) - y| = {np.max(np.abs(check.output - y_ref)):.2e} V")
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
ax1.plot(t, inv.input, lw=0.8)
ax1.set(xlabel="t (s)", ylabel="drive u (V)", title="the inverse's input")
ax2.plot(inv.input, y_ref, lw=0.8)
ax2.set(xlabel="u (V)", ylabel="y (V)", title="input-output: the hysteresis it undoes")
fig.tight_layout()

# %% [markdown]
# ## 2. Sample by sample, for a real-time loop
#
# `model.inverter(state)` keeps the state between calls; `step(y)` returns the input for the
# next target. A target beyond saturation gets the saturated input and is counted, never an
# exception in the middle of a run.

# %%
stepper = model.inverter(model.negative_saturation())
for target in (0.0, 1.0, 0.5, 1.0, model.y_max + 1.0):
    u = stepper.step(target)
    print(f"target {target:+.3f} V -> u = {u:+8.3f} V, output {stepper.output:+.4f} V")
print(f"unreachable so far: {stepper.unreachable}")

# %% [markdown]
# ## 3. On the virtual SS15 rig, with a model identified from the rig's own sweep
#
# The rig simulates the 1 Hz surface of Table 3.1 behind the Appendix B calibration and a
# noisy 14-bit ADC. The feedforward model is *not* that truth: it is identified (Mayergoyz,
# 21 levels) from an FOD sweep recorded on the rig. Each reference runs four ways: a linear
# gain, the inverse as feedforward, the chapter 5 PI loop alone, and PI + feedforward.

# %%
rig = daq.virtual_ss15("ss15-1hz", "anhysteretic", seed=3)
identified, _ = identify_from_device(rig)
refs = tracking_references((identified.y_min, identified.y_max), frequencies=(0.5, 1, 5, 20))
result = run_tracking(identified, device_loop(rig, 1e-3), refs)
result

# %% [markdown]
# The figure: the 1 Hz sine, the tracking error of each way over time, and how the maximum
# error grows with frequency (the rig has no dynamics here, so what grows is the PI loop's
# lag; the feedforward stays at the identification error).

# %%
fig = result.plot("sine-1Hz")

# %% [markdown]
# ## 4. Physics around the hysteresis
#
# When diagnosis (notebook 05) finds a delay, a structural mode or creep, the augmented model
# can be inverted too: the blocks are undone last-first (a delay by preview of the reference,
# a mode by a stable inverse filter, creep exactly), then the hysteresis. Here a delay of
# 2.5 ms and a 150 Hz mode after the hysteresis: the classical inverse against the augmented
# one.

# %%
from preisach import AugmentedModel  # noqa: E402
from preisach.compensate.augmented import invert_augmented  # noqa: E402
from preisach.diagnose.effects import FractionalDelay, SecondOrderMode  # noqa: E402

dt = 1e-3
aug = AugmentedModel(
    model,
    [SecondOrderMode(dt, f_n=150.0, zeta=0.05, participation=0.5), FractionalDelay(dt, tau=2.5e-3)],
)
s0 = model.negative_saturation()
tt = np.arange(0, 2, dt)
ramp = 0.5 * (1 - np.cos(np.pi * np.minimum(tt / 0.25, 1)))
ref = model.y_min + ramp * (1.2 - model.y_min) + 1.5 * np.sin(2 * np.pi * 5 * tt) * ramp
classical = aug.simulate(model.inverse(ref, s0).input, s0).output
augmented = invert_augmented(aug, ref, s0, sample_time=dt)
fig, ax = plt.subplots(figsize=(10, 4))
span = model.y_max - model.y_min
ax.plot(tt, 100 * (classical - ref) / span, lw=0.8, label="classical inverse")
ax.plot(tt, 100 * (augmented.output - ref) / span, lw=0.8, label="augmented inverse")
ax.set(xlabel="t (s)", ylabel="error (% of stroke)", title="5 Hz reference through delay + mode")
ax.legend()
print(
    f"max error: classical {100 * np.max(np.abs(classical - ref)) / span:.2f} %, augmented "
    f"{100 * np.max(np.abs(augmented.output - ref)[:-4]) / span:.4f} % of stroke"
)

# %% [markdown]
# ## 5. On the rig with physics blocks: diagnose, then compensate
#
# Section 4 knew the blocks. On a device they must be learned from it. Here the virtual rig
# carries a bending mode (120 Hz, damping 0.05), creep and a 2-sample measurement delay after
# the hysteresis. The classical model is identified from the rig's own sweep (which carries the
# physics too); short diagnosis experiments recorded on the rig go to `preisach.diagnose`,
# which names the missing physics and fits it; then each reference is tracked on the rig
# with the classical inverse and with the inverse of the diagnosed (augmented) model. Only
# three candidates are tested here to keep the notebook short
# (`preisach.studies.compensation_physics` tests all of them by default).

# %%
from preisach.studies.compensation_physics import physics_compensation  # noqa: E402

phys = physics_compensation(
    frequencies=(1.0, 5.0, 10.0), scale=0.2, candidates=("structural_resonance", "creep", "delay")
)
print("diagnosed:", ", ".join(phys.blocks))
print(phys.markdown())

# %%
run_c = phys.tracking["classical"].get("sine-10Hz", "feedforward")
run_a = phys.tracking["augmented"].get("sine-10Hz", "feedforward")
fig, ax = plt.subplots(figsize=(10, 4))
ax.plot(run_c.t, 100 * (run_c.r - run_c.y) / phys.stroke, lw=0.8, label="classical inverse")
ax.plot(run_a.t, 100 * (run_a.r - run_a.y) / phys.stroke, lw=0.8, label="augmented inverse")
ax.set(xlabel="t (s)", ylabel="error (% of stroke)", title="10 Hz sine on the rig with physics")
ax.legend();
