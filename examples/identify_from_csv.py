"""Identify a Preisach model from a recording in the project's CSV format, and check it.

Run:  python examples/identify_from_csv.py [RECORDING.csv]

With a file, that recording is identified (CSV with optional ``# key: value`` metadata lines,
then a header row with at least the columns t, u, y in s, V, V; see README "Data formats").
Without one, the script first writes ``fod_sweep.csv``: the FOD identification sweep of thesis
Fig 3.17 (21 levels, 1 Hz) played on the built-in 1 Hz SS15 model, with 1 mV measurement noise
and 14-bit quantisation over +/-5 V - put your own recording in its place.

It identifies the model by Mayergoyz's method (Eq 2.12-2.14; the FOD curves are found in the
recording by themselves, cells projected to mu >= 0), prints the report, predicts a
congruent-minor-loop experiment (Fig 3.13) it has not seen, and writes ``identified.npz``
(load it with ``preisach.PreisachModel.load``) and ``identify.png``.
"""

import sys

import numpy as np
from preisach import PreisachModel, Recording
from preisach.identify import identify_fod
from preisach.plotting import plot_identification
from preisach.waveforms import cml_input, fod_sweep

truth = PreisachModel.builtin("ss15-1hz")
rng = np.random.default_rng(0)


def measure(u):
    """The 'device': the 1 Hz SS15 model, 1 mV noise, 14 bits over +/-5 V (volts)."""
    y = truth.simulate(u, truth.negative_saturation()).output + rng.normal(0.0, 1e-3, u.size)
    lsb = 10.0 / 2**14
    return np.round(y / lsb) * lsb


if len(sys.argv) > 1:
    path = sys.argv[1]
else:
    path = "fod_sweep.csv"
    t, u = fod_sweep(21, frequency=1.0, sample_time=1e-3)  # 20 s at 1 kHz
    Recording.from_arrays(
        t=t,
        u=u,
        y=measure(u),
        sample_time=1e-3,
        experiment="fod_sweep",
        metadata={"device": "built-in ss15-1hz + noise", "initial_state": "negative_saturation"},
    ).save(path)
    print(f"wrote {path}; its first lines:")
    with open(path) as f:
        print("".join(next(f) for _ in range(8)), end="")

rec = Recording.load(path)
print(
    f"\nloaded {path}: {rec.u.size} samples over {rec.duration:.1f} s, "
    f"u in [{rec.u.min():.1f}, {rec.u.max():.1f}] V"
)
model, report = identify_fod(rec, project=True, name=f"identified from {path}")
print(report.summary())

# Predict an experiment the identification has not seen: the CML test of Fig 3.13.
t, u = cml_input(frequency=1.0)
y_pred = model.simulate(u, model.negative_saturation()).output
err = y_pred - measure(u)
span = truth.y_max - truth.y_min
print(
    f"\nCML test predicted: max error {np.abs(err).max() * 1e3:.1f} mV "
    f"({100 * np.abs(err).max() / span:.2f} % of the {span:.2f} V output range)"
)

model.save("identified.npz")
plot_identification(report).savefig("identify.png", dpi=70)
print("wrote identified.npz and identify.png")
