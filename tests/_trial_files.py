"""Trial-file text the trial tests share: a trial on the virtual SS15 rig, steps to follow."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

#: The ``[trial]``, ``[device]`` (the virtual rig), ``[output]`` and ``[input]`` sections.
SIM_HEAD = """
[trial]
sample_time = 0.001
[device]
kind = "sim"
[output]
name = "V_in"
channel = 1
range = [-10.0, 10.0]
calibration = "ss15-b"
[input]
name = "V_out"
channel = 1
range = [-5.0, 5.0]
"""


def sim_head(name: str | None = None, **device: str | int) -> str:
    """:data:`SIM_HEAD` with a trial ``name`` and further ``[device]`` keys (``model=...``)."""
    head = SIM_HEAD if name is None else SIM_HEAD.replace("[trial]", f'[trial]\nname = "{name}"')
    keys = "".join(
        f"\n{k} = {v!r}" if isinstance(v, int) else f'\n{k} = "{v}"' for k, v in device.items()
    )
    return head.replace('kind = "sim"', 'kind = "sim"' + keys)


#: A ``[safety]`` section that tolerates any run of missed deadlines (a loaded test machine).
ANY_MISSED = """[safety]
max_consecutive_missed = -1
"""


def start_realtime_run(trial: Path, out: Path, **popen: Any) -> subprocess.Popen[str]:
    """Start ``python -m preisach.trials run TRIAL -o OUT --realtime -q`` (pipes, text)."""
    cmd = [sys.executable, "-m", "preisach.trials", "run", str(trial), "-o", str(out)]
    return subprocess.Popen(
        [*cmd, "--realtime", "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **popen,
    )


def wait_for_rows(proc: subprocess.Popen[str], csv: Path, rows: int) -> int:
    """Wait (60 s at most) until the run has written ``rows`` sample rows to ``csv``.

    Returns the rows seen (at least ``rows``).
    """
    deadline = time.monotonic() + 60
    seen = 0
    while seen < rows and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
        if csv.exists():
            seen = sum(1 for line in csv.read_text().splitlines() if line[:1].isdigit())
    assert seen >= rows, "the trial did not start writing"
    return seen
