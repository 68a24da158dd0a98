"""Feedforward compensation on the virtual SS15 rig: identify, invert, track.

1. Record the FOD identification sweep on the virtual rig and identify a model from it (the
   rig's truth is the 1 Hz surface of Table 3.1; the model only sees the recording).
2. Run sine references (1, 5 and 20 Hz), a triangle, random reversals and the FOD pattern
   four ways: a linear gain, the inverse model as feedforward, the chapter 5 PI loop, and
   PI + feedforward.
3. Print the table of tracking errors (% of stroke) and save the figure and the JSON.

Run:  python examples/compensate.py     -> writes tracking.png and tracking.json
"""

import json

import matplotlib

matplotlib.use("Agg")

from preisach import daq  # noqa: E402
from preisach.compensate.rig import identify_from_device  # noqa: E402
from preisach.compensate.tracking import (  # noqa: E402
    device_loop,
    run_tracking,
    tracking_references,
)

rig = daq.virtual_ss15("ss15-1hz", "anhysteretic", seed=1)  # 14-bit ADC, 0.5 mV noise
model, report = identify_from_device(rig)
print(f"identified from the rig's sweep: {model}")

refs = tracking_references((model.y_min, model.y_max), frequencies=(1.0, 5.0, 20.0))
result = run_tracking(model, device_loop(rig, 1e-3), refs)
print(f"stroke {result.stroke:.3f} V; max / RMS tracking error in % of the stroke:")
print(result.table())
ff, lin = result.get("sine-1Hz", "feedforward"), result.get("sine-1Hz", "uncompensated")
print(
    f"1 Hz sine: feedforward {ff.max_error_pct:.2f} % vs linear gain {lin.max_error_pct:.2f} % "
    f"({lin.max_error_pct / ff.max_error_pct:.0f}x better)"
)
result.plot().savefig("tracking.png", dpi=90)
with open("tracking.json", "w") as f:
    json.dump(result.to_dict(), f, indent=2)
print("wrote tracking.png and tracking.json")
