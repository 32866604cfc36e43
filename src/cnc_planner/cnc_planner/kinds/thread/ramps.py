"""Jerk-limited moves onto and off the helix, at RAMP_JERK_SHARE of each axis's jerk
limit: the rest is room for the drive-compensated command, which leads each jerk step by
the drive's velocity lag."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from ruckig import InputParameter, Ruckig, RuckigError, Trajectory

from cnc_msgs_py.machine import Machine
from cnc_servo_bridge.stop import velocity_trajectory

from cnc_planner.kinds.thread.spec import JOINTS
from cnc_planner.motion.moves import MotionError, axis_limits, calculate

RAMP_JERK_SHARE = 0.6  # of the axis jerk for ramps onto and off the helix


class Ramps:
    """Jerk-limited single-axis moves between states at the ramps' share of the jerk limit,
    on one reused ruckig instance (building one costs more than its calculation)."""

    def __init__(self, machine: Machine) -> None:
        self._limits = {j: axis_limits(machine.axis(j)) for j in JOINTS}
        self._ruckig = Ruckig(1)

    def reach(self, joint: str, start: np.ndarray, target: np.ndarray,
              duration: float | None = None) -> Trajectory | None:
        """The move of ``joint`` from state start to state target (p, v, a), lasting at
        least ``duration`` if given, or None if ruckig finds none."""
        limits = self._limits[joint]
        inp = InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = ([x] for x in start)
        inp.target_position, inp.target_velocity, inp.target_acceleration = ([x] for x in target)
        inp.max_velocity, inp.max_acceleration = [limits.velocity], [limits.acceleration]
        inp.max_jerk = [RAMP_JERK_SHARE * limits.jerk]
        if duration is not None:
            inp.minimum_duration = duration
        try:
            return calculate(inp, self._ruckig)
        except (MotionError, RuckigError):
            return None


def z_to_speed(machine: Machine, state: Sequence[float], speed: float) -> Trajectory:
    """Time-optimal z move from state (p, v, a) to a constant speed: from rest up to the
    helix's lead speed, or off the helix down to rest."""
    z = machine.axis("z")
    p, v, a = state
    return velocity_trajectory([p], [v], [a], [speed], [z.max_velocity], [z.max_acceleration],
                               [RAMP_JERK_SHARE * z.max_jerk])
