"""The bridge's contract, checked on a plan before its job is accepted.

The bridge refuses a chunk that breaks its setpoint rules (SetpointBuffer.validate: travel,
velocity and acceleration limits, jumps, a start at rest) and raises an alarm when the
drive model's following error passes its limit or an encoder reads outside the travel
(ServoLoop). A job must never find either mid-run: every plan (every segment of a long
job) is sampled on the servo grid as it will be streamed and put through the same
validation and the same drive model here, so a violation refuses the job up front, with
the limit it would break. The following error is checked on the described drives and on
the drives inside their tolerance that lag most (cnc_msgs_py.plant.lagging_corner): no
plant inside it may trip the alarm either.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.plant import lagging_corner
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import NS
from cnc_servo_bridge.drive import DriveModel
from cnc_servo_bridge.setpoints import SetpointBuffer, SetpointError

from cnc_planner.motion.timeline import Plan

BLOCK_S = 30.0  # s of plan sampled at a time: memory stays flat on long segments


def check_plan(plan: Plan, machine: Machine, period: float, field: str) -> None:
    """Refuse a plan the bridge would refuse or alarm on.

    Args:
        plan: the plan (or segment), starting where the axes stand, in its own time.
        machine: the machine description the bridge runs.
        period: the servo period (s): the plan is checked on this grid.
        field: the job field a violation is reported against (the job's kind block).

    Raises:
        JobError: the first violation, named like the bridge would name it.
    """
    n = int(np.ceil(plan.duration / period - 1e-9)) + 1
    block = max(2, int(BLOCK_S / period))
    period_ns = round(period * NS)
    buffer = SetpointBuffer(machine)
    drives = DriveModel(machine, period, plan.joints)
    limit = drives.following_error_limit
    # (model, who it is, what to do): the described drives, and where the tolerance is open
    # the ones inside it that lag most
    checks = [(drives, "the drive", "")]
    corners = {j: lagging_corner(machine.drives[j]) for j in plan.joints}
    if not all(corners[j] == replace(machine.drives[j], noise=0.0) for j in plan.joints):
        checks.append((DriveModel(machine, period, plan.joints, drives=corners), "a drive inside the tolerance",
                       ": raise following_error_limit or narrow the drive's tolerance"))
    now_ns, state = 0, None
    for lo in range(0, n, block):
        k = np.arange(lo, min(n, lo + block))
        p, v, a = plan.sample(k * period)
        if state is None:  # the plan starts where the axes stand, the drives settled there
            for model, _, _ in checks:
                model.reset(p[0])
                model.state.velocity = v[0].copy()
            state = (p[0], v[0])
        try:
            # Each block continues the one before, as the bridge's chunks continue each other.
            buffer.validate(list(plan.joints), k * period_ns, p, v, a, now_ns, state)
        except SetpointError as err:
            raise JobError(field, f"the plan breaks the bridge's setpoint rules: {err}") from err
        runs = [model.run(p, v, a) for model, _, _ in checks]
        for (_, who, advice), (_, _, error) in zip(checks, runs):
            tripped = np.greater(np.abs(error), limit, order="F")  # per joint's column (SetpointBuffer.outside_travel)
            if tripped.any():  # argwhere only then: it scans the whole block even when nothing is wrong
                i, j = np.argwhere(tripped)[0]
                raise JobError(field, f"{plan.joints[j]}: {who} would trip its following error limit "
                                      f"({abs(error[i, j]):.6g} > {limit[j]:.6g}) at {k[i] * period:.3f} s of the plan"
                                      + advice)
        measured = runs[0][0]
        outside = buffer.outside_travel(measured)
        if outside.any():
            i, j = np.argwhere(outside)[0]
            raise JobError(field, f"{plan.joints[j]}: the drive would overshoot its travel "
                                  f"({measured[i, j]:.6f}) at {k[i] * period:.3f} s of the plan")
        now_ns, state = int(k[-1]) * period_ns, (p[-1], v[-1])
