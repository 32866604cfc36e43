"""Plans inside the bridge's limits on any machine a user describes.

The planner pre-compensates its commands with the drive model (drilling X/Y, threads,
vibration), so a command is the motion plus a correction that leads it. Where the motion
uses an axis's full acceleration and the drive needs a strong correction (a high jerk
limit, low feed-forward, a slow velocity loop), the sum breaks the limits the bridge
enforces. And a drive without feed-forward follows a fast move with a following error
that can trip its alarm limit.

So motion is planned on a derated copy of the machine, the drives still clamping at the
described limits (Machine.nominal): rapids capped where the steady following error,
((1 - velocity_ff) * v + (1 - accel_ff) * velocity_lag * a) / kp, would use more than a
share of the alarm limit, and acceleration and jerk lowered step by step until the plan
passes plan_check: the bridge's own setpoint rules and the drive model's alarms. The
first step is the machine as described: a machine that needs no headroom loses nothing.
Jerk goes first, as it costs the least time and drives the correction's spikes.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError

from cnc_planner.motion import collector
from cnc_planner.motion.plan_check import check_plan
from cnc_planner.motion.timeline import Plan


@dataclass(frozen=True)
class Headroom:
    """One derating step: share of the acceleration limit, cap on the jerk limit, and the
    share of the following error limit the steady error of a move may use."""

    acceleration_share: float
    jerk_cap: float
    error_share: float


STEPS = (
    Headroom(1.0, float("inf"), 0.6),
    Headroom(1.0, 2e4, 0.6),
    Headroom(0.9, 5e3, 0.5),
    Headroom(0.75, 1e3, 0.4),
    Headroom(0.5, 250.0, 0.3),
    Headroom(0.3, 80.0, 0.2),
)


def derated(machine: Machine, step: Headroom) -> Machine:
    """The machine the planner plans motion on at one derating step."""
    axes = {}
    for name, axis in machine.axes.items():
        drive = machine.drives[name]
        budget = step.error_share * drive.following_error_limit * drive.kp
        # The spindle's commands are never compensated: it only needs the error cap.
        share, cap = (1.0, float("inf")) if name == SPINDLE else (step.acceleration_share, step.jerk_cap)
        velocity, acceleration = axis.max_velocity, axis.max_acceleration * share
        if drive.velocity_ff < 1.0:
            velocity = min(velocity, 0.7 * budget / (1.0 - drive.velocity_ff))
        if drive.accel_ff < 1.0:
            acceleration = min(acceleration, 0.3 * budget / ((1.0 - drive.accel_ff) * drive.velocity_lag))
        axes[name] = replace(axis, max_velocity=velocity, max_acceleration=acceleration,
                             max_jerk=min(axis.max_jerk, cap))
    return replace(machine, axes=axes, nominal=machine)


def plan_within_limits(plan: Callable[[Machine], Plan], machine: Machine, period: float,
                       field: str) -> Plan:
    """Plan on the machine derated step by step until the plan meets the bridge's contract.

    Args:
        plan: plans the job (or segment) on the machine it is given.
        machine: the machine as described (the bridge's).
        period: the servo period the plan is checked on (s).
        field: the job field a violation is reported against.

    Raises:
        JobError: the job cannot be planned (as the planner says it, on the least derated
            machine that could not plan it), or no step meets the contract (the last
            violation, which names the limit).
    """
    violation: JobError | None = None
    with collector.paused():
        for step in STEPS:
            candidate = plan(derated(machine, step))
            try:
                check_plan(candidate, machine, period, field)
                return candidate
            except JobError as err:
                violation = err
    assert violation is not None
    raise violation
