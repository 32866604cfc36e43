"""max_jerk binds the axis's motion, its feedback: every example job's plan, run through the
described drives, keeps each axis's feedback jerk (cnc_msgs_py.jerk) within max_jerk."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_msgs_py.gcode.document import load_job_file
from cnc_msgs_py.jerk import windowed_jerk
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_planner.motion.derating import feedback_jerk_factor
from cnc_planner.planning import plan_job
from cnc_planner.prediction import simulated_feedback

from support import ROOT

PERIOD = 1e-3
JOBS = ["move_mill3", "drill_row", "turn_stepped", "lathe_feed_vibration", "path_5ax_tilt", "path_5ax_table_table"]
# A tool path's joints curve through the inverse kinematics: their reference jerk may pass
# the stretch's bound by a little (at most 1 % on these jobs).
PATH_CURVATURE = 0.02


@pytest.mark.parametrize("name", JOBS)
def test_feedback_jerk_stays_within_the_limit(name):
    job = parse_job(load_job_file(ROOT / "config" / "jobs" / f"{name}.yaml"))
    machine = load_machine(job.machine)
    plan = plan_job(job, machine, machine.home_joints)
    _, feedback = simulated_feedback(plan, machine, PERIOD)
    for i, joint in enumerate(plan.joints):
        if joint == SPINDLE:
            continue
        peak = float(np.max(np.abs(windowed_jerk(feedback[:, i], PERIOD))))
        assert peak <= machine.axes[joint].max_jerk * (1 + PATH_CURVATURE), (joint, peak)


def test_the_jerk_factor_is_the_drives_own():
    """A drive that answers a jerk step without overshoot needs no margin; the shipped
    mill's needs about 12 %."""
    mill = load_machine("mill3")
    assert feedback_jerk_factor(mill, "x") == pytest.approx(1.122, abs=0.005)
    assert 1.0 <= feedback_jerk_factor(load_machine("mill3_soft"), "x") < 1.01
