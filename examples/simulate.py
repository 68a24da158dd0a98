"""Simulate the built-in SS15 bimorph model (1 Hz surface of Table 3.1) and plot the loops.

Run:  python examples/simulate.py            -> writes simulate.png in the current folder
"""

import numpy as np
from preisach import PreisachModel

model = PreisachModel.builtin("ss15-1hz")  # V_in on [-100, 100] V -> strain gauge V

# A decaying 1 Hz sinusoid about 20 V, sampled at 1 kHz, from the anhysteretic state.
t = np.arange(0.0, 8.0, 1e-3)
u = 20.0 + 80.0 * np.exp(-t / 3.0) * np.sin(2 * np.pi * 1.0 * t)
result = model.simulate(u, state=model.anhysteretic_state(), t=t)

print(model)
print(f"final input {result.final_state.input:.2f} V, output {result.output[-1]:.4f} V")
print(f"slopes at the final state (V/V): {model.slopes(result.final_state)}")
result.plot().savefig("simulate.png", dpi=100)
print("wrote simulate.png")
