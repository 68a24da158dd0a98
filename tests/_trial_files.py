"""Trial-file text the trial tests share: a trial on the virtual SS15 rig, steps to follow."""

from __future__ import annotations

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

#: A ``[safety]`` section that tolerates any run of missed deadlines (a loaded test machine).
ANY_MISSED = """[safety]
max_consecutive_missed = -1
"""
