"""No drive inside the tolerance trips its following error alarm: the planner caps rapids
by the most lagging one (motion/derating.py) and checks the plan on it (plan_check.py)."""
from __future__ import annotations

import dataclasses

import numpy as np

from cnc_msgs_py.gcode.document import load_job_file
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import exactly_as_described, load_machine
from cnc_msgs_py.plant import lagging_corner
from cnc_planner.planning import plan_job
from cnc_servo_bridge.drive import DriveModel

from support import ROOT

PERIOD = 1e-3


def long_rapid() -> object:
    doc = load_job_file(ROOT / "config" / "jobs" / "move_mill3.yaml")
    doc["move"] = [{"rapid": {"x": -400.0}}, {"rapid": {"x": 400.0}}]
    return parse_job(doc)


def plan_on(machine):
    return plan_job(long_rapid(), machine, machine.home_joints)


def worst_error(plan, machine, drives) -> float:
    """The largest X following error of ``drives`` running the plan."""
    t = np.arange(int(plan.duration / PERIOD) + 1) * PERIOD
    p, v, a = plan.sample(t, ("x",))
    model = DriveModel(machine, PERIOD, ("x",), drives=drives)
    model.reset(p[0])
    return float(np.max(np.abs(model.run(p, v, a)[2])))


def test_a_tight_alarm_limit_slows_the_rapid_until_the_lagging_drive_keeps_inside_it():
    mill = load_machine("mill3")
    tight = dataclasses.replace(mill, drives={**mill.drives, "x": dataclasses.replace(
        mill.drives["x"], following_error_limit=0.002)})
    roomy, slowed = plan_on(mill), plan_on(tight)
    assert slowed.duration > roomy.duration + 0.1  # 0.8 m/s would lag 2.7 mm on the lagging drive
    corner = {"x": lagging_corner(tight.drives["x"])}
    assert worst_error(slowed, tight, corner) < 0.002
    assert worst_error(roomy, mill, {"x": lagging_corner(mill.drives["x"])}) < mill.drives["x"].following_error_limit
    # trusting the description to the last digit, the tight limit costs nothing
    assert plan_on(exactly_as_described(tight)).duration == roomy.duration
