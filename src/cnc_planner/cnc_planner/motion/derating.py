"""Plans inside the bridge's limits on any machine a user describes.

The planner pre-compensates its commands with the drive model (drilling X/Y, threads,
vibration), so a command is the motion plus a correction that leads it. Where the motion
uses an axis's full acceleration and the drive needs a strong correction (a high jerk
limit, low feed-forward, a slow velocity loop), the sum breaks the limits the bridge
enforces. And a drive without feed-forward follows a fast move with a following error
that can trip its alarm limit.

So motion is planned on a derated copy of the machine, the drives still clamping at the
described limits (Machine.nominal): rapids capped where the steady following error,
((1 - velocity_ff) * v + (1 - accel_ff) * velocity_lag * a) / kp + delay * v, would use more
than a share of the alarm limit on the described drive or on the most lagging drive inside
its tolerance, and acceleration and jerk lowered step by step until the plan
passes plan_check: the bridge's own setpoint rules and the drive model's alarms. The
first step is the machine as described: a machine that needs no headroom loses nothing.
Jerk goes first, as it costs the least time and drives the correction's spikes.

``max_jerk`` binds the axis's motion, i.e. its feedback (measured as cnc_msgs_py.jerk
measures it), not only the command: a drive answers a step in jerk with an overshoot of
its own (5-10 % on the shipped drives), and a jerk-limited move reverses its jerk, so
every step plans each axis at max_jerk over the described drive's jerk gain
(feedback_jerk_factor). The compensated command may exceed max_jerk, within the velocity
and acceleration headroom the bridge checks.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from cnc_msgs_py.jerk import windowed_jerk
from cnc_msgs_py.machine import SPINDLE, Axis, Drive, Machine
from cnc_msgs_py.plant import lagging_corner
from cnc_msgs_py.schema import JobError
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion import SERVO_PERIOD, collector  # the grid the feedback's jerk is measured on
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


LAGGING_SHARE = 1.5  # the most lagging drive inside the tolerance may use this much more of the
# alarm limit than the described one (0.9 of it at the first step)


def feedback_jerk_factor(machine: Machine, joint: str) -> float:
    """How far above a jerk-limited command's jerk the drive's feedback goes, at most: the
    feedback's jerk is the command's filtered by the drive (its linear part; counts too fine
    to matter), so it stays within J times the filter's L1 norm, the total variation of its
    answer to a step in jerk (about 2k - 1 for a peak of k: 1.11 to 1.19 on the shipped drives)."""
    return _jerk_factor(machine.drives[joint], machine.drive_axes[joint])


@functools.lru_cache(maxsize=64)
def _jerk_factor(drive: Drive, axis: Axis) -> float:
    drive = replace(drive, resolution=1e-15, friction=0.0, backlash=0.0)
    alone = Machine(name="jerk", layout="mill3", axes={axis.name: axis}, drives={axis.name: drive})
    t = np.arange(round(1.0 / SERVO_PERIOD)) * SERVO_PERIOD
    jerk = 1e-3  # small: no clamp of the drive binds
    p, v, a = (np.concatenate([np.zeros(t.size), x]) for x in (jerk * t**3 / 6, jerk * t**2 / 2, jerk * t))
    feedback = DriveModel(alone, SERVO_PERIOD).simulate(p[:, None], v[:, None], a[:, None])[0][:, 0]
    step_response = windowed_jerk(feedback, SERVO_PERIOD) / jerk
    return max(1.0, float(np.sum(np.abs(np.diff(step_response)))))


def derated(machine: Machine, step: Headroom) -> Machine:
    """The machine the planner plans motion on at one derating step."""
    axes = {}
    for name, axis in machine.axes.items():
        drive = machine.drives[name]
        # The spindle's commands are never compensated: it only needs the error cap.
        share, cap = (1.0, float("inf")) if name == SPINDLE else (step.acceleration_share, step.jerk_cap)
        velocity, acceleration = axis.max_velocity, axis.max_acceleration * share
        # Steady error within its share of the alarm limit, 70 % of it for velocity and 30 % for
        # acceleration, on the described drive and, with a larger share, on the one inside the
        # tolerance that lags most: no plant inside it trips the alarm on a rapid.
        for lagging, error_share in ((drive, step.error_share),
                                     (lagging_corner(drive), LAGGING_SHARE * step.error_share)):
            budget = error_share * drive.following_error_limit
            per_velocity, per_acceleration = lagging.steady_error(1.0, 0.0), lagging.steady_error(0.0, 1.0)
            if per_velocity > 0.0:
                velocity = min(velocity, 0.7 * budget / per_velocity)
            if per_acceleration > 0.0:
                acceleration = min(acceleration, 0.3 * budget / per_acceleration)
        axes[name] = replace(axis, max_velocity=velocity, max_acceleration=acceleration,
                             max_jerk=min(axis.max_jerk / feedback_jerk_factor(machine.nominal or machine, name), cap))
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
