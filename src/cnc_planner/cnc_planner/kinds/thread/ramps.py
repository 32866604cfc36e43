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
_UNKNOWN = object()  # a query Ramps has not been asked (None: one ruckig found no move for)


class Ramps:
    """Jerk-limited single-axis moves between states at the ramps' share of the jerk limit,
    on one reused ruckig instance and input per axis (building them costs more than the
    calculation). Answers are kept by their exact query: the searches for every candidate
    join ask for the same moves (z onto the face, from the same stop) again and again."""

    def __init__(self, machine: Machine) -> None:
        self._ruckig = Ruckig(1)
        self._inputs: dict[str, InputParameter] = {}
        for joint in JOINTS:
            limits = axis_limits(machine.axis(joint))
            inp = self._inputs[joint] = InputParameter(1)
            inp.max_velocity, inp.max_acceleration = [limits.velocity], [limits.acceleration]
            inp.max_jerk = [RAMP_JERK_SHARE * limits.jerk]
        self._known: dict[tuple, Trajectory | None] = {}

    def limits(self, joint: str) -> np.ndarray:
        """The ramps' |velocity|, |acceleration| and |jerk| limits of ``joint``."""
        inp = self._inputs[joint]
        return np.array([inp.max_velocity[0], inp.max_acceleration[0], inp.max_jerk[0]])

    def reach(self, joint: str, start: Sequence[float], target: Sequence[float],
              duration: float | None = None) -> Trajectory | None:
        """The move of ``joint`` from state start to state target (p, v, a), lasting at
        least ``duration`` if given, or None if ruckig finds none."""
        key = (joint, *start, *target, duration)
        move = self._known.get(key, _UNKNOWN)
        if move is not _UNKNOWN:
            return move
        inp = self._inputs[joint]
        p, v, a = start
        inp.current_position, inp.current_velocity, inp.current_acceleration = [p], [v], [a]
        p, v, a = target
        inp.target_position, inp.target_velocity, inp.target_acceleration = [p], [v], [a]
        inp.minimum_duration = duration
        try:
            move = calculate(inp, self._ruckig)
        except (MotionError, RuckigError):
            move = None
        self._known[key] = move
        return move


def z_to_speed(machine: Machine, state: Sequence[float], speed: float) -> Trajectory:
    """Time-optimal z move from state (p, v, a) to a constant speed: from rest up to the
    helix's lead speed, or off the helix down to rest."""
    z = machine.axis("z")
    p, v, a = state
    return velocity_trajectory([p], [v], [a], [speed], [z.max_velocity], [z.max_acceleration],
                               [RAMP_JERK_SHARE * z.max_jerk])
