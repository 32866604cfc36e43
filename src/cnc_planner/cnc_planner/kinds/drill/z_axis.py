"""Z of one drill cycle: its limits in the air and below R, the one-axis ruckig moves made
of them (the plain feed stroke, a peck's moves, the air arc) and how they go into a plan.

Below R every Z acceleration ramp (feed strokes, a peck's retract and re-entry, the exit
from a bottom) lasts at least BOTTOM_TURN_PERIODS servo periods: a shorter one is a pulse
that the drive's feed-forward sees at only a few servo instants, so the feedback's bottom
would depend on where they fall (about 30 um apart on a drawn drive with full
acceleration feed-forward, a 9 ms velocity lag, kp 20/s and jerk 2.8e5 m/s^3). The
shipped mill3 and mill3_soft are below this jerk anyway.
"""
from __future__ import annotations

import numpy as np
from ruckig import ControlInterface, InputParameter

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.drill.cycle import DrillCycle, DrillError
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import Limits, RuckigMove, axis_limits, calculate
from cnc_planner.motion.timeline import Piece

BOTTOM_TURN_PERIODS = 5  # servo periods at least that a Z acceleration ramp below R lasts


def z_move(lim: Limits, p0: float, v0: float, a0: float, p1: float | None = None,
           v1: float = 0.0, a1: float = 0.0, duration: float = 0.0) -> RuckigMove:
    """One-axis ruckig move to a state (p1, v1, a1), or to velocity v1 when p1 is None."""
    inp = InputParameter(1)
    if p1 is None:
        inp.control_interface = ControlInterface.Velocity
    else:
        inp.target_position = [p1]
    inp.current_position = [p0]
    inp.current_velocity = [v0]
    inp.current_acceleration = [a0]
    inp.target_velocity = [v1]
    inp.target_acceleration = [a1]
    inp.max_velocity = [max(lim.velocity, abs(v0))]
    inp.max_acceleration = [max(lim.acceleration, abs(a0))]
    inp.max_jerk = [lim.jerk]
    if duration > 0:
        inp.minimum_duration = duration
    return RuckigMove(calculate(inp))


def z_samples(move: RuckigMove, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity, acceleration of a one-axis move at local times (held at its end)."""
    out = move.sample_all(np.minimum(t, move.duration))
    return out[0][:, 0], out[1][:, 0], out[2][:, 0]


def z_state(move: RuckigMove, t: float) -> tuple[float, float, float]:
    """Position, velocity, acceleration of a one-axis move at local time t."""
    p, v, a = move.trajectory.at_time(t)
    return float(p[0]), float(v[0]), float(a[0])


def crossing(move: RuckigMove, z: float) -> float:
    """When a one-axis move first passes z."""
    t = move.trajectory.get_first_time_at_position(0, z)
    if t is None:
        raise ValueError(f"the Z move never reaches {z} m")
    return float(t)


def add_z(builder: PlanBuilder, start: float, move: RuckigMove, duration: float | None = None) -> float:
    """Append (the first ``duration`` s of) a Z move; returns its end time."""
    duration = move.duration if duration is None else duration
    p, v, _ = z_state(move, duration)
    builder.timelines["z"].add(Piece(start, duration, move.sampler(0)), p, v)
    return start + duration


class ZAxis:
    """The Z limits of one cycle from a start: ``rapid`` in the air, ``turn`` below R (its
    jerk lowered so that no acceleration ramp is shorter than BOTTOM_TURN_PERIODS), the
    cutting feed, the velocity at R going down (``entry``), and the moves made of them."""

    def __init__(self, machine: Machine, cycle: DrillCycle, start_z: float):
        self.rapid = axis_limits(machine.axes["z"])
        turn_jerk = self.rapid.acceleration / (BOTTOM_TURN_PERIODS * cycle.servo_period)
        self.turn = Limits(self.rapid.velocity, self.rapid.acceleration, min(self.rapid.jerk, turn_jerk))
        self.feed = cycle.feed
        self.entry = cycle.entry_velocity
        if cycle.feed > self.rapid.velocity:
            raise DrillError("drill.feed", f"{cycle.feed} m/s exceeds the Z rapid {self.rapid.velocity} m/s")
        for name, lo in (("bottom_z", cycle.bottom_z), ("start z", start_z)):
            if not machine.axes["z"].within_travel(lo):
                raise DrillError("drill", f"{name}: {lo} m is outside the Z travel")
        if start_z < cycle.r_z:
            raise DrillError("drill", "the tool must start above the R plane")
        self._strokes: dict[tuple[float, float], RuckigMove] = {}
        self._arcs: dict[tuple, RuckigMove] = {}

    def stroke(self, top: float, turn: float) -> RuckigMove:
        """The plain feed stroke from a hole's R plane, at feed, to the turning point."""
        if (top, turn) not in self._strokes:
            self._strokes[(top, turn)] = z_move(Limits(self.feed, self.rapid.acceleration, self.turn.jerk),
                                                top, -self.feed, 0.0, turn)
        return self._strokes[(top, turn)]

    def peck_move(self, p0: float, v0: float, a0: float, p1: float, v1: float, speed: float | None) -> RuckigMove:
        """A Z move of a peck sequence (peck.ZMove): at ``speed``, or rapid if None; its
        acceleration ramps as long as at a bottom (``turn``): a slow drive still carries a
        retract's or re-entry's sharp ramps into the last peck."""
        lim = self.turn if speed is None else Limits(speed, self.rapid.acceleration, self.turn.jerk)
        return z_move(lim, p0, v0, a0, p1, v1)

    def arc(self, state: tuple[float, float, float], plane: float, accel: float | None = None,
            duration: float = 0.0) -> RuckigMove:
        """The air move from a state at the X/Y plane (or the start) to ``plane`` at the
        entry velocity (DrillCycle.entry_velocity), at ``accel`` and lasting ``duration`` if given.
        Holes of one pitch and depth ask for the very same arcs (a plate of 10,000 holes for
        39): each is planned once."""
        key = (tuple(state), plane, accel, duration)
        if key not in self._arcs:
            lim = Limits(self.rapid.velocity, accel or self.rapid.acceleration, self.rapid.jerk)
            self._arcs[key] = z_move(lim, *state, plane, self.entry, 0.0, duration)
        return self._arcs[key]
