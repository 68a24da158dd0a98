"""Where the real recordings are: ``$PREISACH_DATA``, else ``../shared/data`` beside the repo.

They are never copied into the repository (see ``../shared/data/README.md`` for their licences);
tests that need them skip, naming this folder, when it does not hold them.
"""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("PREISACH_DATA") or ROOT.parent / "shared" / "data")
YAN9A = DATA_DIR / "yan9a-piezo" / "Model_Vi_Do.dat"
PMAGPY_FORC = DATA_DIR / "pmagpy-forc" / "conventional_example.forc"
