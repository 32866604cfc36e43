"""The thread section of report.json: passes, chips, depth and helix on feedback and on
commands, in the thread block's program coordinates, and its verdict on feedback: depth
short or over, the tool off its flank line and, for a vibrated thread, chips too long
(cnc_analysis.threads.thread_failures holds the limits)."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import to_mm

from cnc_analysis.recording import Run
from cnc_analysis.threads import CHIP_LIMIT_REVS, FLANK_TOLERANCE, SHORT_LIMIT, analyze_thread, thread_failures
from cnc_analysis.verdict import OVERCUT_LIMIT, verdict

from cnc_planner.kinematics import Kinematics


def thread_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """Passes, chips, depth and helix accuracy of a thread, on feedback and on commands,
    judged in program coordinates (the thread block's), whatever the setup and tool length."""
    thread = json.loads(run.goals[-1])["thread"]
    kin = Kinematics(machine, job.setup, job.tool)

    def judge(t: np.ndarray, positions: np.ndarray) -> dict:
        radius, z = kin.tip_radius_z(positions[:, run.column("x")], positions[:, run.column("z")])
        return analyze_thread(t, radius, z, positions[:, run.column(SPINDLE)], thread)

    vibrated = job.vibration is not None
    try:
        feedback = judge(run.feedback_t[window], run.feedback[window])
    except ValueError as err:  # no synchronised pass on feedback: no thread was cut
        return {"error": str(err), "verdict": verdict(criterion(vibrated), [f"on feedback: {err}"], "")}
    feedback["verdict"] = verdict(criterion(vibrated), thread_failures(feedback, vibrated), (
        f"depth within {feedback['depth_error_mm']:.4f} mm (overcut {feedback['overcut_mm']:.4f} mm), "
        f"on the flank within {feedback['helix_residual_mm']:.4f} mm"
        + (f", longest chip {feedback['max_chip_revs']:.2f} rev" if vibrated else "") + " on feedback"))
    inside = run.command_t >= run.feedback_t[window][0]
    try:
        commanded = judge(run.command_t[inside], run.command[inside])
    except ValueError as err:
        # A drive without feed-forward is commanded well ahead of the groove it cuts: its
        # commands need not trace a helix at all. The feedback is what is judged.
        return {**feedback, "commanded": {"error": str(err)}}
    return {**feedback, "commanded": {k: commanded[k] for k in ("max_chip_revs", "helix_residual_mm", "depth_error_mm")}}


def criterion(vibrated: bool) -> str:
    """What the thread's verdict holds its feedback to."""
    return (f"on feedback: no deeper than the depth by more than {to_mm(OVERCUT_LIMIT):g} mm, no shallower by "
            f"more than {to_mm(SHORT_LIMIT):g} mm; the tool within "
            f"{to_mm(FLANK_TOLERANCE):g} mm of its flank line (helix residual)"
            + (f"; every cutting pass's chip within {CHIP_LIMIT_REVS:g} revolution" if vibrated else ""))
