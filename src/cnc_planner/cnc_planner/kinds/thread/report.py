"""The thread section of report.json: passes, chips, depth and helix on feedback and on
commands, in the thread block's program coordinates."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_analysis.recording import Run
from cnc_analysis.threads import analyze_thread

from cnc_planner.kinematics import Kinematics


def thread_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """Passes, chips, depth and helix accuracy of a thread, on feedback and on commands,
    judged in program coordinates (the thread block's), whatever the setup and tool length."""
    thread = json.loads(run.goals[-1])["thread"]
    kin = Kinematics(machine, job.setup, job.tool)

    def judge(t: np.ndarray, positions: np.ndarray) -> dict:
        radius, z = kin.tip_radius_z(positions[:, run.column("x")], positions[:, run.column("z")])
        return analyze_thread(t, radius, z, positions[:, run.column(SPINDLE)], thread)

    feedback = judge(run.feedback_t[window], run.feedback[window])
    inside = run.command_t >= run.feedback_t[window][0]
    try:
        commanded = judge(run.command_t[inside], run.command[inside])
    except ValueError as err:
        # A drive without feed-forward is commanded well ahead of the groove it cuts: its
        # commands need not trace a helix at all. The feedback is what is judged.
        return {**feedback, "commanded": {"error": str(err)}}
    return {**feedback, "commanded": {k: commanded[k] for k in ("max_chip_revs", "helix_residual_mm", "depth_error_mm")}}
