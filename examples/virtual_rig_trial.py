"""Run a scripted rig trial (examples/trials/*.toml) on the virtual SS15, then use its recordings.

Run:  python examples/virtual_rig_trial.py [TRIAL.toml]

Default trial: examples/trials/fod_sweep.toml - the initialisation of section 3.2 and the FOD
identification sweep of Fig 3.17 at 1 Hz.  The same file runs on a real rig with
``preisach trial run FILE --device comedi:/dev/comedi0 -o OUT`` (see README "Running on a real
rig").  The trial runs in C++ on the virtual rig (as fast as it can: no --realtime), writes
one recording per step and summary.json into trial_out/; this script then identifies a model
from any FOD sweep among the recordings and draws every step into virtual_rig_trial.png.
"""

import json
import sys
from pathlib import Path

from matplotlib.figure import Figure
from preisach import Recording
from preisach.identify import identify_fod
from preisach.trials import check_trial, run_trial_file

DEFAULT = Path(__file__).parent / "trials" / "fod_sweep.toml"
trial = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT
plan = check_trial(trial)  # validates the file and its planned waveforms; names every error
print(
    f"{trial.name}: {plan.name!r}, {len(plan.steps)} steps on the "
    f"{plan.device['kind']} device, sample time {plan.sample_time:g} s"
)

outcome = run_trial_file(trial, "trial_out", overwrite=True, fsync=False)
print(f"trial {outcome.end_status} on {outcome.device}")
fig = Figure(figsize=(10, 2.4 * len(outcome.steps)))
axes = fig.subplots(len(outcome.steps), 1, squeeze=False)[:, 0]
for ax, step in zip(axes, outcome.steps):
    rec = Recording.load(step.file)
    print(
        f"  {Path(step.file).name}: {step.result.end_status}, {step.result.samples} samples, "
        f"y in [{rec.y.min():.3f}, {rec.y.max():.3f}] V"
    )
    ax.plot(rec.t, rec.u, lw=0.6, color="0.5")
    ax.set_ylabel("input u (V)")
    ax2 = ax.twinx()
    ax2.plot(rec.t, rec.y, lw=0.7, color="tab:blue")
    ax2.set_ylabel("output y (V)", color="tab:blue")
    ax.set_title(f"step {step.index + 1}: {step.kind} ({step.name})")
    if step.kind == "fod_sweep":
        model, report = identify_fod(rec, name="identified on the virtual rig")
        nodes = report.node_residuals
        print(
            f"    identified {model}; FOD node residual max {nodes.max_error * 1e3:.1f} mV "
            f"({nodes.max_pct:.2f} % of range)"
        )
        model.save("virtual_rig_model.npz")
axes[-1].set_xlabel("time t (s)")
fig.tight_layout()
fig.savefig("virtual_rig_trial.png", dpi=90)
summary = json.loads(Path(outcome.summary_file).read_text())
print(f"wrote {outcome.summary_file} ({summary['steps_run']} steps) and virtual_rig_trial.png")
