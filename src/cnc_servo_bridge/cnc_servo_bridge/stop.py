"""Jerk-limited velocity changes (ruckig's velocity interface): stops and spindle ramps.

Shared by the bridge (stop on an alarm) and the planner (cancel, spindle speed changes)
so both stop the machine the same way.
"""
from __future__ import annotations

from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory


def velocity_trajectory(
    position: list[float], velocity: list[float], acceleration: list[float],
    target_velocity: list[float], max_velocity: list[float], max_acceleration: list[float],
    max_jerk: list[float],
) -> Trajectory:
    """Time-optimal jerk-limited change to target velocities, ending with zero acceleration.

    Limits are widened to the current state where it already exceeds them (a stop must
    start from wherever the axes are).

    Raises:
        ValueError: ruckig found no trajectory.
    """
    dofs = len(position)
    inp = InputParameter(dofs)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position = list(position)
    inp.current_velocity = list(velocity)
    inp.current_acceleration = list(acceleration)
    inp.target_velocity = list(target_velocity)
    inp.target_acceleration = [0.0] * dofs
    inp.max_velocity = [max(m, abs(v)) for m, v in zip(max_velocity, velocity)]
    inp.max_acceleration = [max(m, abs(a)) for m, a in zip(max_acceleration, acceleration)]
    inp.max_jerk = list(max_jerk)
    trajectory = Trajectory(dofs)
    result = Ruckig(dofs).calculate(inp, trajectory)
    if result not in (Result.Working, Result.Finished):
        raise ValueError(f"ruckig could not plan the velocity change ({result.name})")
    return trajectory
