"""Diagnose what a Preisach model leaves out, on recordings with a concealed effect.

Run:  python examples/diagnose.py [KIND]

KIND is one of delay (default), creep, rate_dependence, structural_resonance, sensor_drift,
non_congruence or none.  The script writes a case folder case/ (the files a user would bring:
an FOD identification sweep and six other experiments of one virtual device, in the NPZ
recording format, 1 mV noise, 14 bits) where ONE small effect is present - a few times the
noise, invisible on a loop plot - then, as a user would:

1. identifies a model from case/identification.npz (Mayergoyz);
2. diagnoses the other recordings (``preisach.diagnose``): where the residual lives, which
   physics explains it on held-out data, the fitted parameters;
3. compares the verdict with the truth (case/truth.json) and writes diagnosis.json,
   diagnosis.png and the augmented model augmented.npz (``preisach.load_model``).

The same from the command line (the identification sweep is given once, as identification -
not also among the diagnosed recordings; a duplicate would be left out with a warning):
``preisach diagnose MODEL case/{wiping_out,cml,minor_loops,multisine,step_hold,noise}.npz
--identification case/identification.npz --json R.json``.
"""

import json
import sys
from pathlib import Path

from preisach import diagnose
from preisach.identify import identify_fod
from preisach.recording import Recording
from preisach.studies.diagnosis_cases import make_case

kind = sys.argv[1] if len(sys.argv) > 1 else "delay"
make_case(kind, seed=31, scale=0.2, effect_size=3.5).save("case")
truth = json.loads(Path("case/truth.json").read_text())
print(f"wrote case/ ({truth['kind']}, {len(truth['recordings'])} experiments)")

sweep = Recording.load("case/identification.npz")
model, _ = identify_fod(sweep, name="identified from the sweep")
recordings = [f"case/{name}.npz" for name in truth["recordings"]]
report = diagnose(model, recordings, identification=sweep)

print(report.summary())
print(
    f"\ntruth: {truth['kind']} (size {truth['effect_size']:.1f} x the noise); "
    f"verdict: {report.verdict}"
)
report.to_json("diagnosis.json")
report.plot().savefig("diagnosis.png", dpi=70)
report.model.save("augmented.npz")
print("wrote diagnosis.json, diagnosis.png and augmented.npz")
