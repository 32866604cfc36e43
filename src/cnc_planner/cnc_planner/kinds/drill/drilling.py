"""Drilling cycles on a 3-axis mill: overlapped (S1/S2/S3) and conventional (G81/G99).

Overlapped cycle, per hole i:
  S1  X/Y rapid to the hole (ruckig, axes synchronised);
  S2  Z comes down from the top of its air arc R' through the R plane, where it has
      reached the cutting feed exactly, and feeds to depth;
  S3  Z retracts; as the tip passes R going up, S1 of the next hole starts.
Between two holes Z makes one ruckig move from its retract state at R to (R, -feed), the
air arc R -> R' -> R: R' follows from the motion. The arc lasts the longer of its own
minimum time and the X/Y move plus the servo-lag margins, so Z descends before S1 ends.

The retract law (mode) trades time below R against time in the air:
  1  deep, wide pitch: full acceleration out of the hole, rapid reached before R;
  2  shallow: full acceleration up to R, the speed at R still below rapid;
  3  close pitch: Z reaches R at a chosen lower speed with zero acceleration, so it starts
     decelerating before R (the closer the pitch, the lower the speed, the earlier);
     the short X/Y move then does not wait for a high, long arc.
Auto picks, per hole, the law with the shortest retract + arc time for the next X/Y move.

Servo lag: X/Y feedback settles some tens of ms after its command ends, Z feedback trails
its command. The planner runs the bridge's drive model on its own commands and moves the
Z descent / the next X/Y start by whole servo periods until the feedback never shows the
tip below R with X/Y off the hole; both gaps start at the smallest value that keeps the
commands themselves safe, so the cycle loses only what the feedback demands.

X/Y pre-compensation (compensate_xy, on by default): with kp = 50/s and no acceleration
feed-forward the X/Y feedback settles within the tolerance only 30-50 ms after a rapid's
command ends, and Z has to wait for it. Each S1 command is therefore the ruckig move plus
a correction learned against the drive model (motion.compensation: the exact
inverse of the drive's linear part, refined against DriveModel.simulate), so that the
FEEDBACK follows the ruckig move and is in position when the move ends. The command
leads the move by XY_COMMAND_LEAD servo periods (from rest) and keeps settling
(exponentially, at the position loop's rate, with the drive at rest) for up to ~0.2 s
after it; consecutive corrections simply add (the drive is linear), so a tail may run
into the next hole's S1. S1 starts on the servo grid (its correction is learned on it).
The command stays within the axis velocity and acceleration limits (finite differences,
tested), but where ruckig switches jerk the correction briefly needs more jerk than the
axis limit, as in vibration.py; the motion the feedback follows is the ruckig move. The
command itself arrives at the hole some tens of ms after the feedback does, so only the
feedback, not the command, is safe at R then. compensate_xy=False plans the plain ruckig
commands (then both are safe), for comparison.

Below the X/Y plane (feed_to_depth): each hole may have its own surface, R and bottom
(hole_planes; r_z is then the plane X/Y moves above, the highest R, and Z falls fast from
it to the hole's R); the feed to the bottom is plain, vibrated (chip breaking locked to
the spindle angle, VibrationFeed: Z reaches R at rest) or in pecks (peck.py); a dwell
(G82) may follow. X/Y stands still over the hole throughout. A move between two holes
that passes over a clamp has its own, higher X/Y plane (air_planes): the retract before
it, its air arc and the fall into the next hole run to and from that plane, every other
move stays at r_z.

Bottoms on feedback: the last feed stroke of a hole (plain, or a pecked hole's last peck
after its retract and re-entry) turns where the drive model's feedback turns at the
programmed depth (turning_point); a dwelled hole's last stroke ends at the depth itself,
pre-compensated with the drive model so that its feedback stops there without passing it
and holds it for the dwell (dwell_correction: learned, or where that cannot land, aimed
and then settled onto the depth). Below R no Z acceleration ramp is shorter than
BOTTOM_TURN_PERIODS servo periods, so that no bottom depends on where the servo
instants fall.

Conventional cycle (overlap=False), like G81 with G99: X/Y rapid, Z rapid to R, feed to
depth, rapid up to R + RETURN_CLEARANCE, each move after the previous one ends.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Callable

import numpy as np
from ruckig import ControlInterface, InputParameter

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import Limits, RuckigMove, axis_limits, calculate, point_to_point
from cnc_planner.kinds.drill.peck import Peck, peck_moves
from cnc_planner.motion.plan_check import BLOCK_S
from cnc_planner.motion.timeline import Piece, Plan
from cnc_planner.motion.compensation import COMPENSATION_TAIL, compensation_band, learned_command
from cnc_planner.vibration.waveform import Vibration, VibrationFeed

# Conventional cycle: X/Y travel at R + 1 mm (G99 returns to R; the 1 mm keeps the tip
# above R on feedback too, where Z reads up to ~0.3 mm below its command while braking).
# The overlapped cycle ends at this level as well after its last hole (mode 3).
RETURN_CLEARANCE = 1e-3
SAFETY_ROUNDS = 40      # drive-model rounds before giving up on a safe timing
GENTLE_ROUNDS = 6       # bisection rounds for the gentle air acceleration
MODE3_GRID = 24         # retract speeds tried per level of the mode-3 search
FINE_STEP = 1e-4        # s, sampling of tolerance crossings and of a_z^2
XY = ("x", "y")
XY_LEAD_PERIODS = 8     # rest before an S1 move in its learning reference: room to lead
XY_FIXED_PERIODS = 4    # of which uncorrected: the compensated command leads by the rest
XY_COMMAND_LEAD = XY_LEAD_PERIODS - XY_FIXED_PERIODS + 1  # periods: from its last rest sample
XY_SETTLED_COUNTS = 0.25  # encoder counts: an X/Y correction below this has settled
BOTTOM_ROUNDS = 6  # drive-model rounds placing the Z command's turning point at a hole's bottom
BOTTOM_PHASES = 4  # offsets of a stroke against the servo grid that its turning point is aimed over
BOTTOM_TURN_PERIODS = 5  # servo periods at least that a Z acceleration ramp below R lasts (z_turn)
BOTTOM_STEADY_S = 0.3  # s of steady feed before R in those rounds: the drive settles into it
DWELL_BLEND_S = 0.05  # s: a dwelled hole's stroke correction fades in over this (or half the stroke)
DWELL_PHASES = 8  # offsets against the servo grid a dwelled stroke's correction is learned at
DWELL_TOLERANCE = 1e-6  # m (or an encoder count): the feedback is at a dwell's bottom within this
DWELL_KEPT = 2e-6  # m (or an encoder count): a learned dwell correction landing this close is kept
DWELL_SETTLE_TIME_CONSTANTS = 3.0  # of the drive (1/kp + velocity lag): a settle onto a dwell's bottom
DWELL_SETTLE_ROUNDS = 10  # drive-model rounds aiming a settled dwell's stroke and slowing its settle
XY_ACCELERATION_SHARES = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3)  # of an S1 move's limits,
XY_JERK_SHARES = (1.0, 0.3, 0.1, 0.03, 0.01, 3e-3, 1e-3, 3e-4)  # tried fastest first
XY_HEADROOM_TRIES = 24  # moves tried before the plain (uncompensated) one
XY_VELOCITY_ROUNDS = 3  # lower velocity shares tried when the command overshoots the velocity
XY_HEADROOM_MARGIN = 0.99  # of the limits: the compensated command stays this far inside them
XY_HEADROOM_AIM = 0.98  # a lowered velocity share aims this far inside them


@dataclass(frozen=True)
class DrillCycle:
    """One drilling job in axis coordinates (m, m/s, z up): holes, planes, feed, options.

    mode None lets the planner choose the retract law per hole; 1/2/3 force it.
    xy_tolerance: X/Y must be this close to the hole, on feedback, whenever the tip is
    below R. servo_period: the bridge's period, for the drive model the timing uses.
    compensate_xy: pre-compensate the overlapped cycle's X/Y commands with the drive
    model, so that the X/Y feedback is in position when the ruckig move ends.
    """

    holes: list[tuple[float, float]]
    surface_z: float
    bottom_z: float
    r_z: float
    feed: float
    overlap: bool = True
    mode: int | None = None
    gentle_air_accel: bool = False
    xy_tolerance: float = 1e-5
    servo_period: float = 1e-3
    compensate_xy: bool = True
    vibration: Vibration | None = None
    spindle_speed: float = 0.0
    dwell: float = 0.0
    hole_planes: tuple[tuple[float, float, float], ...] | None = None
    peck: Peck | None = None
    order: tuple[int, ...] | None = None  # the job's index of each hole, in drilling order
    air_planes: tuple[float, ...] | None = None  # per hole: the plane X/Y moves above into it

    def __post_init__(self) -> None:
        if not self.holes:
            raise ValueError("holes: at least one hole is needed")
        if not self.bottom_z < self.surface_z <= self.r_z:
            raise ValueError("planes: need bottom_z < surface_z <= r_z")
        if self.feed <= 0:
            raise ValueError("feed: must be > 0")
        if self.mode not in (None, 1, 2, 3):
            raise ValueError(f"mode: expected None, 1, 2 or 3, got {self.mode!r}")
        if self.xy_tolerance <= 0 or self.servo_period <= 0:
            raise ValueError("xy_tolerance and servo_period must be > 0")
        if self.vibration is not None and not self.spindle_speed > 0:
            raise ValueError("spindle_speed: a vibrated feed needs a turning spindle")
        if self.dwell < 0:
            raise ValueError("dwell: must be >= 0")
        if self.hole_planes is not None:
            if len(self.hole_planes) != len(self.holes):
                raise ValueError("hole_planes: one (surface, R, bottom) per hole")
            if not all(self.bottom_z <= b < s <= r <= self.r_z for s, r, b in self.hole_planes):
                raise ValueError("hole_planes: need bottom_z <= bottom < surface <= R <= r_z per hole")
        if self.air_planes is not None and (len(self.air_planes) != len(self.holes)
                                            or min(self.air_planes) < self.r_z):
            raise ValueError("air_planes: one per hole, none below r_z")

    def planes(self, i: int) -> tuple[float, float, float]:
        """Hole i's surface, its R plane (where the feed starts) and its bottom. r_z is the
        plane X/Y moves above: the highest R, or higher (clearance_z)."""
        return self.hole_planes[i] if self.hole_planes is not None else (self.surface_z, self.r_z, self.bottom_z)

    def air_plane(self, i: int) -> float:
        """The plane X/Y moves above into hole i (i = 0: from the start; i = len(holes):
        after the last hole): r_z, or higher where the move passes over clamps (obstacles)."""
        return self.air_planes[i] if self.air_planes is not None and i < len(self.holes) else self.r_z


def _z_move(lim: Limits, p0: float, v0: float, a0: float, p1: float | None = None,
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


def _z_samples(move: RuckigMove, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity, acceleration of a one-axis move at local times (held at its end)."""
    out = move.sample_all(np.minimum(t, move.duration))
    return out[0][:, 0], out[1][:, 0], out[2][:, 0]


def _state(move: RuckigMove, t: float) -> tuple[float, float, float]:
    p, v, a = move.trajectory.at_time(t)
    return float(p[0]), float(v[0]), float(a[0])


def _crossing(move: RuckigMove, z: float) -> float:
    t = move.trajectory.get_first_time_at_position(0, z)
    if t is None:
        raise ValueError(f"the Z move never reaches {z} m")
    return float(t)


@dataclass(frozen=True)
class _Retract:
    """S3 of one hole up to the R plane: the law (mode), its move and the state at R."""

    mode: int
    move: RuckigMove
    t_r: float
    state: tuple[float, float, float]


# The retract search asks every hole the same questions (the same speeds, the same arcs
# from the same states): each is answered by ruckig once.
@lru_cache(maxsize=4096)
def _slow_exit(z: Limits, bottom_z: float, r_z: float, speed: float) -> _Retract | None:
    move = _z_move(z, bottom_z, 0.0, 0.0, r_z, speed)
    extrema = move.trajectory.position_extrema[0]
    if extrema.min < bottom_z - 1e-9 or extrema.max > r_z + 1e-9:
        return None
    return _Retract(3, move, move.duration, (r_z, speed, 0.0))


@lru_cache(maxsize=4096)
def _arc_time(z: Limits, state: tuple[float, float, float], r_z: float, feed: float) -> float:
    """Duration of the fastest air arc from ``state`` to R at cutting feed (Job.arc)."""
    return _z_move(z, *state, r_z, -feed, 0.0).duration


@dataclass(frozen=True)
class _XYMove:
    """S1 of one hole and when its command leaves / re-enters the position tolerance."""

    target: dict[str, float]
    move: RuckigMove | None
    leave: float
    arrive: float
    joints: tuple[str, ...] = ()
    correction: np.ndarray | None = None  # (3, k, joints) from XY_COMMAND_LEAD periods before

    @property
    def duration(self) -> float:
        return self.move.duration if self.move else 0.0


class _Job:
    """What every round of the timing search shares: limits, moves, retract choices."""

    def __init__(self, machine: Machine, cycle: DrillCycle, start: dict[str, float]):
        self.machine = machine
        self.cycle = cycle
        self.start = start
        self.z = axis_limits(machine.axes["z"])
        # Below R every Z acceleration ramp (feed strokes, a peck's retract and re-entry,
        # the exit from a bottom) lasts at least BOTTOM_TURN_PERIODS: a shorter one is a
        # pulse that the drive's feed-forward sees at only a few servo instants, so the
        # feedback's bottom would depend on where they fall (about 30 um apart on a drawn
        # drive with full acceleration feed-forward, a 9 ms velocity lag, kp 20/s and
        # jerk 2.8e5 m/s^3). The shipped mill3 and mill3_soft are below this jerk anyway.
        turn_jerk = self.z.acceleration / (BOTTOM_TURN_PERIODS * cycle.servo_period)
        self.z_turn = Limits(self.z.velocity, self.z.acceleration, min(self.z.jerk, turn_jerk))
        if cycle.feed > self.z.velocity:
            raise ValueError(f"feed: {cycle.feed} m/s exceeds the Z rapid {self.z.velocity} m/s")
        for name, lo in (("bottom_z", cycle.bottom_z), ("start z", start["z"])):
            if not machine.axes["z"].within_travel(lo):
                raise ValueError(f"{name}: {lo} m is outside the Z travel")
        if start["z"] < cycle.r_z:
            raise ValueError("the tool must start above the R plane")
        self.n = len(cycle.holes)
        self._exits: dict[tuple[float, float], _Retract] = {}
        self._turns: dict[tuple[float, ...], float] = {}
        self._dwells: dict[tuple[float, ...], tuple[np.ndarray, float]] = {}
        self._approaches: dict[tuple[float, float, float], tuple[float, tuple[RuckigMove, ...]]] = {}
        self._strokes: dict[tuple[float, float], RuckigMove] = {}
        self._vibrated: dict[tuple[float, float], VibrationFeed] = {}
        position = (start["x"], start["y"])
        self.xy: list[_XYMove] = []
        corrections: dict[tuple, np.ndarray] = {}
        for i, hole in enumerate(cycle.holes):
            for axis, value in zip(XY, hole):
                if not machine.axes[axis].within_travel(value):
                    raise ValueError(f"holes[{i}]: {axis} = {value} m is outside the travel")
            moved = _moved_axes(position, hole)
            if moved and cycle.overlap and cycle.compensate_xy:
                # The drive is linear up to its encoder counts: one correction per displacement.
                key = tuple(round((dict(zip(XY, hole))[j] - dict(zip(XY, position))[j]) * 1e9) for j in moved)
                if key not in corrections:
                    corrections[key] = _xy_headroom(machine, cycle.servo_period, position, hole,
                                                    cycle.xy_tolerance)
                shares, correction = corrections[key]
                xy = replace(_xy_move(machine, position, hole, cycle.xy_tolerance, shares), correction=correction)
            else:
                xy = _xy_move(machine, position, hole, cycle.xy_tolerance)
            self.xy.append(xy)
            position = hole

    def turning_point(self, hole: int) -> float:
        """Where the Z command turns at a hole's bottom, the exit starting there: a feed
        stroke (plain, or a pecked hole's last) turns where the drive's feedback turns at
        the programmed depth. A drive with velocity lag overshoots the end of a feed stroke
        (about 16 um on mill3 at 1200 mm/min), one without full feed-forward falls short.
        A dwelled hole's command ends at the bottom itself, pre-compensated so that the
        feedback stops there (dwell_correction); a vibrated one is compensated as a whole."""
        c = self.cycle
        _, _, bottom = c.planes(hole)
        if not c.compensate_xy or c.vibration is not None or c.dwell > 0:
            return bottom
        return self._aimed_turn(*self.final_approach(hole), bottom)

    def final_approach(self, hole: int) -> tuple[float, tuple[RuckigMove, ...]]:
        """Where a hole's last feed stroke starts (feeding) and the Z moves that bring the
        tool there from a steady feed: none for a plain stroke or a single peck (fed from
        R), the previous peck's feed, the last retract and the re-entry for a pecked hole
        (a slow drive is still behind the previous peck when the retract starts)."""
        c = self.cycle
        surface, top, bottom = c.planes(hole)
        if c.peck is None:
            return top, ()
        if (surface, top, bottom) not in self._approaches:
            steps = peck_moves(self._peck_move, c.peck, c.feed, top, -c.feed, surface, bottom)
            lead = tuple(step.move for step in steps[-4:-1]) if len(steps) >= 4 else ()
            self._approaches[(surface, top, bottom)] = (_state(lead[-1], lead[-1].duration)[0] if lead else top, lead)
        return self._approaches[(surface, top, bottom)]

    def _peck_move(self, p0: float, v0: float, a0: float, p1: float, v1: float, speed: float | None) -> RuckigMove:
        """A Z move of a peck sequence (peck.ZMove): at ``speed``, or rapid if None; its
        acceleration ramps as long as at a bottom (z_turn): a slow drive still carries a
        retract's or re-entry's sharp ramps into the last peck."""
        lim = self.z_turn if speed is None else Limits(speed, self.z.acceleration, self.z_turn.jerk)
        return _z_move(lim, p0, v0, a0, p1, v1)

    def _reference(self, start: float, lead_in: tuple[RuckigMove, ...], stroke: RuckigMove,
                   after: RuckigMove | None, tail: int, phase: float) -> tuple[np.ndarray, ...]:
        """The Z command around a hole's last stroke on a servo grid shifted by ``phase``
        periods: BOTTOM_STEADY_S of steady feed into ``start`` (or into the lead-in moves),
        the stroke from time 0, then ``after`` (an exit) or rest, for ``tail``
        periods more. Returns p, v, a and the index of the stroke's first sample."""
        period, feed = self.cycle.servo_period, self.cycle.feed
        lead = sum(m.duration for m in lead_in)
        k = np.arange(-math.ceil(BOTTOM_STEADY_S / period) - math.ceil(lead / period),
                      math.ceil(stroke.duration / period - phase) + tail)
        tau = (phase + k) * period
        p, v, a = start - feed * tau, np.full(len(tau), -feed), np.zeros(len(tau))
        if lead_in:  # at the first move's start velocity (a feed, or rest) before it
            p0, v0, _ = _state(lead_in[0], 0.0)
            p[tau < 0], v[tau < 0] = p0 + v0 * (tau[tau < 0] + lead), v0
            begin = -lead
            for move in lead_in:
                inside = (tau >= begin) & (tau < begin + move.duration)
                p[inside], v[inside], a[inside] = _z_samples(move, tau[inside] - begin)
                begin += move.duration
        inside = tau >= 0
        p[inside], v[inside], a[inside] = _z_samples(stroke, tau[inside])
        beyond = tau >= stroke.duration
        if after is not None:
            p[beyond], v[beyond], a[beyond] = _z_samples(after, tau[beyond] - stroke.duration)
        return p, v, a, int(np.argmax(inside))

    def _aimed_turn(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float) -> float:
        """The turning point of a last stroke from ``start``: the drive model runs the
        approach, the stroke and two exits, and the turning point moves by the error, a few
        rounds (one on mill3; a stiff drive whose bottom feedback rings needs about five, as
        the stroke's shape changes with its end)."""
        c = self.cycle
        key = (start, bottom, *(_state(m, 0.0)[0] for m in lead_in))
        if key not in self._turns:
            period = c.servo_period
            drive = DriveModel(self.machine, period, ("z",))
            steady = math.ceil(BOTTOM_STEADY_S / period)
            turn = bottom
            for _ in range(BOTTOM_ROUNDS):
                stroke = self._stroke(start, turn)
                # The exit law is chosen later, per hole, and a stroke starts anywhere
                # between two servo instants: aim between the extremes of the fastest and
                # the gentlest exit (rest to rest above R) sampled at BOTTOM_PHASES, so
                # that every hole lands close.
                errors = []
                for exit_move, phase in itertools.product(
                        (self.fast_exit(turn, c.r_z).move, _z_move(self.z_turn, turn, 0.0, 0.0, c.r_z + RETURN_CLEARANCE)),
                        np.arange(BOTTOM_PHASES) / BOTTOM_PHASES):
                    p, v, a, k0 = self._reference(start, lead_in, stroke, exit_move,
                                                  math.ceil(exit_move.duration / period) + steady, phase)
                    drive.reset(p[:1])
                    drive.state.velocity[:] = v[0]
                    errors.append(float(np.min(drive.run(p[:, None], v[:, None], a[:, None])[0][k0:, 0]) - bottom))
                error = 0.5 * (min(errors) + max(errors))
                if abs(error) < 0.5 * float(drive.resolution[0]):
                    break
                turn -= error
                if not self.machine.axes["z"].within_travel(turn):
                    raise ValueError(f"bottom_z: the drive needs a command at {turn} m, outside the Z travel")
            self._turns[key] = turn
        return self._turns[key]

    def dwell_correction(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                         phase: float) -> tuple[np.ndarray, float]:
        """The drive-model correction (3, k) of a dwelled hole's last stroke and its dwell,
        at the servo instants from the stroke's start (the first ``phase`` periods after
        it; a stiff drive's bottom depends on where they fall), and how long after the
        stroke's end the feedback arrives (s): the command (stroke to the bottom plus
        correction) makes the feedback stop at the bottom and hold it. Learned first
        (_learned_dwell, the fastest); where its feedback still misses the bottom by
        more than DWELL_KEPT (a drive far behind after a fast re-entry, ringing or without
        acceleration headroom), the stroke is aimed and settled instead (_settled_dwell),
        and whichever lands closer is kept."""
        key = (start, bottom, phase, *(_state(m, 0.0)[0] for m in lead_in))
        if key not in self._dwells:
            learned = self._learned_dwell(start, lead_in, bottom, phase)
            if abs(learned[2]) > max(DWELL_KEPT, self.machine.drives["z"].resolution):
                learned = min(learned, self._settled_dwell(start, lead_in, bottom, phase), key=lambda c: abs(c[2]))
            self._dwells[key] = learned[:2]
        return self._dwells[key]

    def _learned_dwell(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                       phase: float) -> tuple[np.ndarray, float, float]:
        """dwell_correction learned against the drive model, and its feedback's deepest
        point past the bottom (m, negative = deeper). The correction makes the feedback
        follow the stroke to rest at the bottom and hold there, where a plain stroke's
        feedback would overshoot it and come back (velocity lag) or creep in late
        (no full feed-forward). It fades in over the first DWELL_BLEND_S of
        the stroke (the drive arrives lagging from the moves before it; longer, into the
        dwell, where the command would break the Z limits otherwise) and out over the
        dwell's last DWELL_BLEND_S (what is left there chases encoder counts); where the
        drive cannot catch up by the stroke's end (a slow drive after a fast re-entry), the
        command rests at the bottom until the feedback is there, and the dwell counts from
        then: it is held on feedback."""
        c = self.cycle
        period = c.servo_period
        stroke = self._stroke(start, bottom)
        drive = DriveModel(self.machine, period, ("z",))
        band = compensation_band(drive, self.machine.axes["z"].max_acceleration)  # a coarse encoder's counts
        late = 0
        blends = [min(DWELL_BLEND_S, 0.5 * stroke.duration)] + [DWELL_BLEND_S * 2 ** k for k in range(4)]
        for _ in range(2):  # learn, then learn again with the rest the feedback needs
            p, v, a, k0 = self._reference(start, lead_in, stroke, None, math.ceil(c.dwell / period) + late, phase)
            tau = (phase + np.arange(len(p)) - k0) * period
            fade = min(DWELL_BLEND_S, 0.5 * c.dwell)
            for blend in blends:  # a drive far behind needs a longer fade-in within the limits
                share = np.clip(np.minimum(tau / blend, (tau[-1] - tau) / fade), 0.0, 1.0)
                weight = np.sin(0.5 * math.pi * share) ** 2
                kept = learned_command(drive, p[:, None], v[:, None], a[:, None], 0, len(p) - k0 - 1, period, band,
                                       weight=weight, keep_from=k0)
                command = np.zeros((3, len(p)))
                command[:, k0:k0 + kept.shape[1]] = kept[:, :, 0]
                if (np.max(np.abs(v + command[1])) <= self.z.velocity
                        and np.max(np.abs(a + command[2])) <= self.z.acceleration):
                    break
            feedback = drive.simulate(*(x[:, None] + dx[:, None] for x, dx in zip((p, v, a), command)))[0][:, 0]
            arrival = self._arrival(feedback, k0 + math.ceil(stroke.duration / period - phase), bottom)
            if arrival <= late:
                break
            late = arrival
        return kept[:, :, 0], late * period, float(np.min(feedback[k0:]) - bottom)

    def _settled_dwell(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                       phase: float) -> tuple[np.ndarray, float, float]:
        """dwell_correction without learning, as (correction, arrival, deepest point past
        the bottom): the stroke turns where the drive model's feedback reaches the bottom
        and no deeper (aimed like a plain stroke's turning point), then the command
        settles onto the bottom in a smooth rest-to-rest move over
        DWELL_SETTLE_TIME_CONSTANTS of the drive (slower while the settle itself would
        pass the bottom), where the feedback comes to rest for the dwell. The command
        stays within the plain Z limits: it holds where a learned correction has no room
        (a drive far behind after a fast re-entry, or one that rings)."""
        c = self.cycle
        period = c.servo_period
        stroke = self._stroke(start, bottom)
        drive = DriveModel(self.machine, period, ("z",))
        settle_time = DWELL_SETTLE_TIME_CONSTANTS * (1.0 / float(drive.kp[0]) + float(drive.lag[0]))
        aim = 0.5 * max(DWELL_TOLERANCE, float(drive.resolution[0]))
        turn, late, best = bottom, 0, None
        for _ in range(DWELL_SETTLE_ROUNDS):
            aimed = self._stroke(start, turn)
            # jerk alone limits it to the settle time: the smoothest rest-to-rest move
            jerk = min(self.z.jerk, 32.0 * abs(turn - bottom) / settle_time**3) or self.z.jerk
            settle = _z_move(Limits(self.z.velocity, self.z.acceleration, jerk), turn, 0.0, 0.0, bottom,
                             duration=settle_time)
            settled_at = math.ceil((aimed.duration + settle.duration - stroke.duration) / period)
            tail = math.ceil(c.dwell / period) + max(late, settled_at) + math.ceil(settle_time / period)
            p, v, a, k0 = self._reference(start, lead_in, aimed, settle, tail, phase)
            drive.reset(p[:1])
            drive.state.velocity[:] = v[0]
            feedback = drive.run(p[:, None], v[:, None], a[:, None])[0][:, 0]
            late = max(settled_at, self._arrival(feedback, k0 + math.ceil(stroke.duration / period - phase), bottom))
            deepest = k0 + int(np.argmin(feedback[k0:]))
            error = float(feedback[deepest] - bottom)
            if best is None or abs(error) < abs(best[2]):
                plain = np.stack(_z_samples(stroke, (phase + np.arange(len(p) - k0)) * period))
                best = (np.stack((p, v, a))[:, k0:] - plain, late * period, error)
            if abs(error) <= aim:
                break
            if (phase + deepest - k0) * period > aimed.duration + 0.5 * settle.duration:
                settle_time *= 2.0  # the settle itself passes the bottom: slower, the turn stays
                continue
            turn -= error
            if not self.machine.axes["z"].within_travel(turn):
                raise ValueError(f"bottom_z: the drive needs a command at {turn} m, outside the Z travel")
        return best

    def _arrival(self, feedback: np.ndarray, end: int, bottom: float) -> int:
        """Servo periods after sample ``end`` (the stroke's end) from which the feedback
        stays at the bottom within DWELL_TOLERANCE (or an encoder count)."""
        tolerance = max(DWELL_TOLERANCE, self.machine.drives["z"].resolution)
        off = np.nonzero(np.abs(feedback[end:] - bottom) > tolerance)[0]
        return int(off[-1]) + 1 if len(off) else 0

    def _dwelled_stroke(self, builder: PlanBuilder, t: float, hole: int) -> float:
        """A dwelled hole's last stroke and its dwell as one compensated Z command
        (dwell_correction); returns the end of the dwell."""
        c = self.cycle
        bottom = c.planes(hole)[2]
        start, lead_in = self.final_approach(hole)
        stroke = self._stroke(start, bottom)
        # the first servo instant after t, in periods, to 1/DWELL_PHASES
        phase = round((math.ceil(t / c.servo_period - 1e-9) - t / c.servo_period) * DWELL_PHASES) / DWELL_PHASES
        correction, late = self.dwell_correction(start, lead_in, bottom, phase)
        grid = (phase + np.arange(correction.shape[1])) * c.servo_period

        def sample(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return tuple(x + np.interp(tt, grid, dx, right=0.0)  # type: ignore[return-value]
                         for x, dx in zip(_z_samples(stroke, tt), correction))

        arrival = t + stroke.duration + late
        builder.timelines["z"].add(Piece(t, arrival + c.dwell - t, sample), bottom)
        builder.event(arrival, "dwell", hole=hole, seconds=c.dwell)
        return arrival + c.dwell

    def _stroke(self, top: float, turn: float) -> RuckigMove:
        """The plain feed stroke from a hole's R plane, at feed, to the turning point."""
        if (top, turn) not in self._strokes:
            self._strokes[(top, turn)] = _z_move(Limits(self.cycle.feed, self.z.acceleration, self.z_turn.jerk),
                                                 top, -self.cycle.feed, 0.0, turn)
        return self._strokes[(top, turn)]

    def fast_exit(self, bottom: float, plane: float) -> _Retract:
        """Full acceleration out of a hole from ``bottom`` up through the X/Y ``plane``:
        mode 1 if rapid is reached below it, else 2."""
        if (bottom, plane) not in self._exits:
            z = self.z_turn
            run = _z_move(z, bottom, 0.0, 0.0, None, z.velocity)
            if _state(run, run.duration)[0] <= plane:
                move = _z_move(z, bottom, 0.0, 0.0, plane, z.velocity)
                self._exits[(bottom, plane)] = _Retract(1, move, move.duration, (plane, z.velocity, 0.0))
            else:
                t_r = _crossing(run, plane)
                self._exits[(bottom, plane)] = _Retract(2, run, t_r, _state(run, t_r))
        return self._exits[(bottom, plane)]

    def arc(self, state: tuple[float, float, float], plane: float, accel: float | None = None,
            duration: float = 0.0) -> RuckigMove:
        """The air move from a state at the X/Y plane (or the start) to ``plane`` at cutting feed."""
        lim = Limits(self.z.velocity, accel or self.z.acceleration, self.z.jerk)
        return _z_move(lim, *state, plane, self.entry_velocity, 0.0, duration)

    @property
    def entry_velocity(self) -> float:
        """Z velocity at R going down: the cutting feed, or rest where a vibrated feed starts
        (its waveform ramps up from rest, locked to the spindle angle)."""
        return 0.0 if self.cycle.vibration is not None else -self.cycle.feed

    def vibrated_stroke(self, builder: PlanBuilder, t_down: float, hole: int) -> float:
        """S2 below R with the chip-breaking vibration: Z from rest at the hole's R to rest
        at its bottom, the waveform locked to the spindle angle and its command
        pre-compensated with the drive model (VibrationFeed); returns its end time. Strokes
        are cached by length and start angle, since the timing search replans the cycle."""
        c = self.cycle
        _, top, bottom = c.planes(hole)
        angle = builder.timelines[SPINDLE].position_at(t_down)
        key = (round(top - bottom, 12), round(math.fmod(angle, 2 * math.pi), 9))
        if key not in self._vibrated:
            z = self.machine.axes["z"]
            self._vibrated[key] = VibrationFeed(
                top - bottom, c.feed * 2 * math.pi / c.spindle_speed, c.vibration, c.spindle_speed, z,
                start_angle=angle, servo_period=c.servo_period,
                drive_model_factory=lambda: DriveModel(self.machine, c.servo_period, ("z",)))
        move = self._vibrated[key]

        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            progress, v, a = move.sample(t)
            return top - progress, -v, -a

        builder.timelines["z"].add(Piece(t_down, move.duration, sample), bottom)
        builder.event(t_down, "vibration_feed", start=[top], direction=[-1.0], joints=["z"],
                      length=top - bottom, feed_per_rev=c.feed * 2 * math.pi / c.spindle_speed,
                      field="drill", hole=hole)
        builder.event(t_down + move.duration, "vibration_end", hole=hole)
        return t_down + move.duration

    def _pecks(self, builder: PlanBuilder, t: float, hole: int, v0: float, last: bool = True) -> float:
        """The peck sequence of a hole from its R (moving at v0) to rest at its bottom, its
        last feed turning at the turning point; without that feed if not ``last`` (a
        dwelled hole's, compensated with its dwell)."""
        c = self.cycle
        surface, top, bottom = c.planes(hole)
        steps = peck_moves(self._peck_move, c.peck, c.feed, top, v0, surface, bottom, self.turning_point(hole))
        for k, step in enumerate(steps):
            if step.kind == "feed" and step.peck > 0:
                builder.event(t, "peck", hole=hole, peck=step.peck, previous_bottom=step.bottom)
            elif step.kind == "reentry":
                builder.event(t, "reentry", hole=hole, peck=step.peck, previous_bottom=step.bottom)
            if last or k < len(steps) - 1:
                t = _add_z(builder, t, step.move)
        return t

    def feed_to_depth(self, builder: PlanBuilder, t_down: float, hole: int, overlapped: bool,
                      plane: float) -> float:
        """S2 below the X/Y plane (Z at ``plane``): fast down to the hole's own R if it lies lower, the feed
        (plain, vibrated or in pecks) to the bottom, then the dwell (G82); returns when Z
        leaves the bottom. ``overlapped``: Z arrives at the plane moving (the air arc).
        In the overlapped cycle a dwelled hole's last stroke and dwell are one compensated
        command (dwell_correction); the conventional cycle holds its plain command."""
        c = self.cycle
        _, top, bottom = c.planes(hole)
        v = self.entry_velocity if overlapped else 0.0
        t = t_down
        if top < plane - 1e-12:
            t = _add_z(builder, t, _z_move(self.z, plane, v, 0.0, top, v))
        compensated_dwell = c.dwell > 0 and overlapped and c.compensate_xy and c.vibration is None
        if c.vibration is not None:
            end = self.vibrated_stroke(builder, t, hole)
        elif compensated_dwell:
            if c.peck is not None:
                t = self._pecks(builder, t, hole, v, last=False)
            return self._dwelled_stroke(builder, t, hole)
        elif c.peck is not None:
            end = self._pecks(builder, t, hole, v)
        elif overlapped:
            end = _add_z(builder, t, self._stroke(top, self.turning_point(hole)))
        else:
            end = builder.linear({"z": self.turning_point(hole)}, c.feed, start=t)
        if c.dwell > 0:
            builder.timelines["z"].add_hold(end, c.dwell)
            builder.event(end, "dwell", hole=hole, seconds=c.dwell)
        return end + c.dwell

    def _slow_exit(self, speed: float, bottom: float, plane: float) -> _Retract | None:
        """Mode 3: reach the X/Y plane at ``speed`` with zero acceleration, or None if that needs an overshoot."""
        return _slow_exit(self.z_turn, bottom, plane, float(speed))

    def cost(self, retract: _Retract, air_needed: float) -> float:
        """Time from the bottom to R at feed over the next hole: retract plus air arc."""
        return retract.t_r + max(_arc_time(self.z, retract.state, retract.state[0], self.cycle.feed), air_needed)

    def _best_slow_exit(self, air_needed: float, bottom: float, plane: float) -> _Retract:
        top = self.fast_exit(bottom, plane).state[1]
        speeds = np.linspace(0.0, top, MODE3_GRID + 1)[:-1]
        for _ in range(2):
            found = [r for r in (self._slow_exit(v, bottom, plane) for v in speeds) if r is not None]
            costs = [self.cost(r, air_needed) for r in found]
            best = found[int(np.argmin(costs))]
            step = speeds[1] - speeds[0]
            speeds = np.linspace(max(best.state[1] - step, 0.0), min(best.state[1] + step, top), MODE3_GRID)
        return best

    def retract(self, air_needed: float, hole: int) -> _Retract:
        """The retract law for a hole followed by an air arc of at least ``air_needed``."""
        forced = self.cycle.mode
        bottom = self.turning_point(hole)
        plane = self.cycle.air_plane(hole + 1)
        fast = self.fast_exit(bottom, plane)
        if forced in (1, 2):
            if fast.mode != forced:
                reason = ("too shallow to reach rapid below R" if forced == 1
                          else "deep enough to reach rapid below R (mode 1)")
                raise ValueError(f"mode: {forced} is impossible here, the hole is {reason}")
            return fast
        slow = self._best_slow_exit(air_needed, bottom, plane)
        if forced == 3 or self.cost(slow, air_needed) < self.cost(fast, air_needed) - 1e-6:
            return slow
        return fast

    def last_retract(self) -> tuple[int, RuckigMove, float, RuckigMove | None]:
        """S3 of the last hole to rest above R: (mode, move, time at R, stop move or None).

        Modes 1/2 keep their exit law and brake above R; mode 3 (and auto) takes the
        time-optimal rest-to-rest move to R + RETURN_CLEARANCE, braking before R.
        """
        c = self.cycle
        if c.mode in (1, 2):
            fast = self.retract(0.0, self.n - 1)
            stop = _z_move(self.z, *fast.state, None, 0.0)
            return fast.mode, fast.move, fast.t_r, stop
        move = _z_move(self.z_turn, self.turning_point(self.n - 1), 0.0, 0.0, c.r_z + RETURN_CLEARANCE)
        return 3, move, _crossing(move, c.r_z), None


def _xy_move(machine: Machine, p0: tuple[float, float], p1: tuple[float, float], tol: float,
             shares: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> _XYMove:
    """S1 as the builder's rapid will plan it, with its command's tolerance crossings;
    ``shares`` of the velocity, acceleration and jerk limits leave headroom for the drive
    compensation (_xy_headroom)."""
    target = dict(zip(XY, p1))
    move, joints = _xy_limited(machine, p0, p1, shares)
    if move is None:
        return _XYMove(target, None, math.inf, 0.0)
    ts = np.arange(0.0, move.duration + FINE_STEP, FINE_STEP)
    p = move.sample_all(np.minimum(ts, move.duration))[0]
    start = np.array([dict(zip(XY, p0))[j] for j in joints])
    end = np.array([target[j] for j in joints])
    # Conservative on the sampling grid: leave one step early, arrive one step late. A
    # move shorter than the tolerance (a hole given twice) never leaves it at all.
    left = np.nonzero(np.linalg.norm(p - start, axis=1) > tol)[0]
    away = np.nonzero(np.linalg.norm(p - end, axis=1) > tol)[0]
    leave = max(ts[left[0]] - FINE_STEP, 0.0) if len(left) else math.inf
    arrive = ts[away[-1]] + FINE_STEP if len(away) else 0.0
    return _XYMove(target, move, leave, arrive, tuple(joints))


def _moved_axes(p0: tuple[float, float], p1: tuple[float, float]) -> list[str]:
    """The X/Y axes an S1 move from p0 to p1 moves."""
    return [j for j, a, b in zip(XY, p0, p1) if abs(a - b) > 1e-12]


def _xy_limited(machine: Machine, p0: tuple[float, float], p1: tuple[float, float],
                shares: tuple[float, float, float]) -> tuple[RuckigMove | None, list[str]]:
    """The ruckig move of S1 at shares of the velocity, acceleration and jerk limits, and
    the axes it moves (None and [] for no move)."""
    joints = _moved_axes(p0, p1)
    if not joints:
        return None, []
    limits = [axis_limits(machine.axes[j]) for j in joints]
    limits = [Limits(lim.velocity * shares[0], lim.acceleration * shares[1], lim.jerk * shares[2]) for lim in limits]
    start, target = dict(zip(XY, p0)), dict(zip(XY, p1))
    return point_to_point([start[j] for j in joints], [target[j] for j in joints], limits), joints


def _xy_headroom(machine: Machine, period: float, p0: tuple[float, float],
                 p1: tuple[float, float], tol: float) -> tuple[tuple[float, float, float], np.ndarray | None]:
    """Shares of the velocity, acceleration and jerk limits for one S1 move, and its
    correction, such that the compensated command stays within the axis limits: the
    fastest move of a grid of acceleration and jerk shares whose command fits. The
    correction leads the motion by the drive's lag, so it adds about lag x jerk to the
    acceleration: a lower jerk usually buys the headroom for less time than a lower
    acceleration. A command over the velocity limit lowers the velocity share and the
    grid is tried again. If nothing fits, the plain move (no correction, within the
    limits by construction): the timing search then waits for the feedback."""
    velocity = 1.0
    for _ in range(XY_VELOCITY_ROUNDS):
        grid = [(velocity, a, j) for a in XY_ACCELERATION_SHARES for j in XY_JERK_SHARES]
        for shares in sorted(grid, key=lambda shares: _xy_limited(machine, p0, p1, shares)[0].duration)[:XY_HEADROOM_TRIES]:
            candidate = _xy_move(machine, p0, p1, tol, shares)
            correction, (over_v, over_a) = _xy_correction(machine, period, candidate)
            if over_v > XY_HEADROOM_MARGIN:
                velocity *= XY_HEADROOM_AIM / over_v
                break
            if over_a <= XY_HEADROOM_MARGIN:
                return shares, correction
        else:
            break
    return (1.0, 1.0, 1.0), None


def _xy_correction(machine: Machine, period: float, xy: _XYMove) -> tuple[np.ndarray, tuple[float, float]]:
    """The drive-model correction (3, k, joints) of one S1 move, from rest, on the servo
    grid: sample 0 (still zero) lies XY_COMMAND_LEAD periods before the move starts.

    The reference is the ruckig move relative to its start, at rest XY_LEAD_PERIODS
    periods before and COMPENSATION_TAIL s after; learn_correction leaves its first
    XY_FIXED_PERIODS samples uncorrected (all but the last dropped here) and `settled` cuts the tail where
    the correction stays below XY_SETTLED_COUNTS encoder counts.
    """
    drive = DriveModel(machine, period, xy.joints)
    steps = math.ceil(xy.duration / period - 1e-9)
    n = XY_LEAD_PERIODS + steps + math.ceil(COMPENSATION_TAIL / period) + 1
    t = (np.arange(n) - XY_LEAD_PERIODS) * period
    p, v, a = xy.move.sample_all(np.clip(t, 0.0, xy.duration))
    p = p - p[0]
    moving = (t >= 0.0) & (t < xy.duration)
    v, a = v * moving[:, None], a * moving[:, None]
    tolerance = XY_SETTLED_COUNTS * float(np.min(drive.resolution))
    kept = learned_command(drive, p, v, a, XY_FIXED_PERIODS, XY_COMMAND_LEAD + steps, period, tolerance=tolerance,
                           keep_from=XY_FIXED_PERIODS - 1)
    # The command (motion plus correction) against the limits, by how much it exceeds them.
    k = min(kept.shape[1], n - XY_FIXED_PERIODS + 1)
    limits = [machine.axes[j] for j in xy.joints]
    over = tuple(float(np.max(np.abs(ref[XY_FIXED_PERIODS - 1:][:k] + kept[q, :k]) / [getattr(ax, name) for ax in limits]))
                 for q, ref, name in ((1, v, "max_velocity"), (2, a, "max_acceleration")))
    return kept, over


def _length(xy: _XYMove) -> int:
    """Servo samples of an S1 move's correction (1 for a move planned without one)."""
    return xy.correction.shape[1] if xy.correction is not None else 1


class _XYCommand:
    """The compensated X/Y commands of one overlapped cycle, as one timeline piece per axis:
    the ruckig moves (holding at each hole in between) plus every move's correction,
    added where they overlap (a correction's tail may reach into the next S1)."""

    def __init__(self, start: dict[str, float], period: float):
        self.start = {j: start[j] for j in XY}
        self.period = period
        self.entries: list[tuple[float, _XYMove, float]] = []  # (move start, move, correction start)
        self._cache: tuple[tuple, dict] | None = None
        self._reach: np.ndarray | None = None
        self._held_after: list[dict[str, float]] = [dict(self.start)]  # _held's, per entry

    def add(self, t_s1: float, xy: _XYMove) -> None:
        lead = XY_COMMAND_LEAD * self.period if xy.correction is not None else 0.0
        self.entries.append((t_s1, xy, t_s1 - lead))

    @property
    def begin(self) -> float:
        return min(c for _, _, c in self.entries)

    @property
    def end(self) -> float:
        return max(max(t + xy.duration, c + (_length(xy) - 1) * self.period) for t, xy, c in self.entries)

    def sample(self, ts: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Commands at sorted instants ts. Only the entries that reach into [ts[0], ts[-1]]
        are evaluated, each on its own index range, so a chunk costs the same at any hole.

        A move sets its axes from its start on (its samples, then its target held), so
        a later move of an axis overrides everything an earlier one did from the later
        one's start: each entry writes and corrects only up to there.
        """
        key = (len(ts), float(ts[0]), float(ts[-1])) if len(ts) else (0, 0.0, 0.0)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        first = self._first_entry(ts[0]) if len(ts) else len(self.entries)
        held = self._held(first)
        out = {j: [np.full_like(ts, held[j]), np.zeros_like(ts), np.zeros_like(ts)] for j in XY}
        window = []
        for t_s1, xy, c0 in self.entries[first:]:
            if len(ts) == 0 or min(t_s1, c0) > ts[-1]:
                break
            window.append((xy, c0, t_s1, *np.searchsorted(ts, [t_s1, t_s1 + xy.duration], side="left")))
        overridden = {j: len(ts) for j in XY}  # where the next move of each axis starts
        until = []
        for xy, _, _, lo, _ in reversed(window):
            until.append({j: overridden[j] for j in xy.joints})
            overridden.update({j: lo for j in xy.joints})
        until.reverse()
        for (xy, _, t_s1, lo, hi), stop in zip(window, until):
            pva = xy.move.sample_all(ts[lo:hi] - t_s1) if hi > lo else None
            for dof, j in enumerate(xy.joints):
                out[j][0][hi:stop[j]] = xy.target[j]
                end = min(hi, stop[j])
                for q in range(3):
                    if pva is not None and end > lo:
                        out[j][q][lo:end] = pva[q][: end - lo, dof]
        for (xy, c0, _, _, _), stop in zip(window, until):
            if xy.correction is None:  # a move planned without one (_xy_headroom)
                continue
            k = xy.correction.shape[1]
            lo = np.searchsorted(ts, c0, side="left")
            hi = np.searchsorted(ts, c0 + (k - 1) * self.period, side="right")
            grid = np.arange(k) * self.period
            for dof, j in enumerate(xy.joints):
                end = min(hi, stop[j])
                for q in range(3):
                    if end > lo:
                        out[j][q][lo:end] += np.interp(ts[lo:end] - c0, grid, xy.correction[q, :, dof])
        self._cache = (key, out)
        return out

    def _held(self, first: int) -> dict[str, float]:
        """Where the axes stand after the first ``first`` entries' moves (kept per entry:
        a long cycle is sampled block by block)."""
        while len(self._held_after) <= len(self.entries):
            xy = self.entries[len(self._held_after) - 1][1]
            self._held_after.append({**self._held_after[-1], **{j: xy.target[j] for j in xy.joints}})
        return self._held_after[first]

    def _first_entry(self, t: float) -> int:
        """Index of the first entry whose move or correction may still act at time t."""
        if self._reach is None or len(self._reach) != len(self.entries):
            # Latest instant each entry or an earlier one acts on (a running maximum).
            ends = [max(t_s1 + xy.duration, c + (_length(xy) - 1) * self.period)
                    for t_s1, xy, c in self.entries]
            self._reach = np.maximum.accumulate(ends) if ends else np.zeros(0)
        return int(np.searchsorted(self._reach, t, side="left"))

    def write(self, builder: PlanBuilder) -> None:
        """Add the commands to the builder: one piece per X/Y axis over the whole cycle."""
        if not self.entries:
            return
        begin, end = self.begin, self.end
        final = dict(self.start)
        for _, xy, _ in self.entries:
            final.update(xy.target)
        for j in XY:
            def sample(t: np.ndarray, j: str = j) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return tuple(self.sample(t + begin)[j])  # type: ignore[return-value]

            builder.timelines[j].add(Piece(begin, end - begin, sample), final[j])


def _add_z(builder: PlanBuilder, start: float, move: RuckigMove, duration: float | None = None) -> float:
    """Append (the first ``duration`` s of) a Z move; returns its end time."""
    duration = move.duration if duration is None else duration
    p, v, _ = _state(move, duration)
    builder.timelines["z"].add(Piece(start, duration, move.sampler(0)), p, v)
    return start + duration


def _air_energy(move: RuckigMove) -> float:
    """Integral of a_z^2 dt over an air move: the heat/power proxy of the gentle variant."""
    a = move.sample_all(np.arange(0.0, move.duration, FINE_STEP))[2][:, 0]
    return float(np.sum(a * a) * FINE_STEP)


# A cycle written into a builder for given gaps (e_down, e_up) and air accelerations.
Emit = Callable[[PlanBuilder, float, np.ndarray, np.ndarray, np.ndarray, bool], list[dict]]


def _emit_overlapped(job: _Job, retracts: list[_Retract]) -> Emit:
    """Overlapped cycle: e_down[i] = Z at R after the X/Y command ends, e_up[i] = X/Y start
    after Z passed R up from hole i-1; accel[i] = Z acceleration limit of hole i's air move."""
    c = job.cycle
    approach_min = _z_move(job.z, job.start["z"], 0.0, 0.0, c.air_plane(0), job.entry_velocity)
    arc_min = [approach_min.duration] + [job.arc(r.state, r.state[0]).duration for r in retracts[:-1]]
    last_mode, last_move, last_t_r, stop = job.last_retract()

    def emit(builder: PlanBuilder, t0: float, e_down: np.ndarray, e_up: np.ndarray,
             accel: np.ndarray, energy: bool) -> list[dict]:
        u = t0  # when Z last passed R going up (the cycle start for the first hole)
        infos = []
        period = c.servo_period
        command = _XYCommand(job.start, period) if c.compensate_xy else None
        lead = XY_COMMAND_LEAD * period
        for i, xy in enumerate(job.xy):
            last = i == job.n - 1
            mode = last_mode if last else retracts[i].mode
            t_s1 = t0 if i == 0 else u + e_up[i]
            if command is None:
                xy_end = builder.rapid(xy.target, start=t_s1)
            else:
                # On the servo grid, where the correction was learned; the first command
                # starts no earlier than the cycle.
                t_s1 = (math.ceil(t0 / period - 1e-9) * period + lead if i == 0
                        else round(t_s1 / period) * period)
                xy_end = t_s1 + xy.duration
                if xy.move:
                    command.add(t_s1, xy)
            builder.event(t_s1, "S1", hole=i, mode=mode)
            air_time = max(arc_min[i], t_s1 + xy.duration + e_down[i] - u)
            if i == 0:
                gentle = accel[0] < job.z.acceleration
                t_air = t0 if gentle else t0 + air_time - arc_min[0]
                air = (_z_move(Limits(job.z.velocity, accel[0], job.z.jerk), job.start["z"], 0.0, 0.0,
                               c.air_plane(0), job.entry_velocity, 0.0, t0 + air_time - t_air) if gentle
                       else approach_min)
            else:
                t_air = u
                air = job.arc(retracts[i - 1].state, c.air_plane(i), accel[i], air_time)
            t_down = _add_z(builder, t_air, air)
            apex = air.trajectory.position_extrema[0]
            builder.event(t_air + apex.t_max, "S2", hole=i, mode=mode)
            builder.event(t_down, "R_down", hole=i, mode=mode)
            t_s3 = job.feed_to_depth(builder, t_down, i, True, c.air_plane(i))
            builder.event(t_s3, "S3", hole=i, mode=mode)
            if last:
                u = t_s3 + last_t_r
                end = _add_z(builder, t_s3, last_move, last_t_r if stop else None)
                if stop:
                    _add_z(builder, end, stop)
            else:
                u = _add_z(builder, t_s3, retracts[i].move, retracts[i].t_r)
            builder.event(u, "R_up", hole=i, mode=mode)
            info = {"hole": i, "x": xy.target["x"], "y": xy.target["y"], "mode": mode,
                    "s1": float(t_s1), "s1_end": float(xy_end), "s2": float(t_air + apex.t_max),
                    "r_down": float(t_down),
                    "s3": float(t_s3), "r_up": float(u), "apex_z": float(apex.max),
                    "air_time": float(t_down - t_air), "air_accel": float(accel[i])}
            if energy:
                info["air_energy"] = _air_energy(air)
            infos.append(info)
        if command is not None:
            command.write(builder)
        return infos

    return emit


def _emit_conventional(job: _Job) -> Emit:
    """Sequential G81/G99 cycle: e_up[i] = dwell before the X/Y move, e_down[i] = dwell
    between the X/Y move's end and the rapid down to R."""
    c = job.cycle

    def emit(builder: PlanBuilder, t0: float, e_down: np.ndarray, e_up: np.ndarray,
             accel: np.ndarray, energy: bool) -> list[dict]:
        infos = []
        for i, xy in enumerate(job.xy):
            t_s1 = max(builder.end_time(), t0) + e_up[i]
            xy_end = builder.rapid(xy.target, start=t_s1)
            builder.event(t_s1, "S1", hole=i, mode=None)
            t_s2 = xy_end + e_down[i]
            t_down = builder.rapid({"z": c.r_z}, start=t_s2)
            builder.event(t_s2, "S2", hole=i, mode=None)
            builder.event(t_down, "R_down", hole=i, mode=None)
            t_s3 = job.feed_to_depth(builder, t_down, i, False, c.r_z)
            builder.event(t_s3, "S3", hole=i, mode=None)
            clearance = c.air_plane(i + 1) + RETURN_CLEARANCE  # X/Y moves on at this level
            up = builder.rapid_move({"z": clearance})
            t_up = t_s3 + _crossing(up, c.r_z)
            builder.rapid({"z": clearance}, start=t_s3)
            builder.event(t_up, "R_up", hole=i, mode=None)
            infos.append({"hole": i, "x": xy.target["x"], "y": xy.target["y"], "mode": None,
                          "s1": float(t_s1), "s1_end": float(xy_end), "s2": float(t_s2), "r_down": float(t_down),
                          "s3": float(t_s3), "r_up": float(t_up)})
        return infos

    return emit


def _feedback(machine: Machine, plan: Plan, ts: np.ndarray, period: float) -> np.ndarray:
    """X/Y/Z feedback (len(ts), 3) of the drives from rest at the plan's position at ts[0],
    the plan sampled and simulated BLOCK_S at a time (the same values as in one piece,
    without the whole cycle's setpoints in memory)."""
    drives = DriveModel(machine, period, ("x", "y", "z"))
    feedback = np.empty((len(ts), 3))
    block = max(2, int(BLOCK_S / period))
    for lo in range(0, len(ts), block):
        p, v, a = plan.sample(ts[lo:lo + block], ("x", "y", "z"))
        if lo == 0:
            drives.reset(p[0])
        feedback[lo:lo + block] = drives.run(p, v, a)[0]
    return feedback


def _lag_margins(job: _Job, plan: Plan, infos: list[dict], t0: float) -> tuple[np.ndarray, np.ndarray]:
    """Per hole, in servo periods, from the drive model's feedback: how late X/Y settles
    after the tip went below the plane of the move into the hole (down) and how early X/Y
    leaves before the tip is back above the plane of the move out of it (up). Positive =
    unsafe by that many samples, negative = slack."""
    c = job.cycle
    period = c.servo_period
    k0 = math.floor(t0 / period + 1e-9)
    ts = (k0 + np.arange(math.ceil((plan.duration - t0) / period) + 50)) * period
    feedback = _feedback(job.machine, plan, ts, period)
    z = feedback[:, 2]
    starts = np.searchsorted(ts, [info["s1"] for info in infos] + [ts[-1] + 1.0, ts[-1] + 1.0])
    down = np.zeros(job.n)
    up = np.zeros(job.n)
    ku = 0
    for i, info in enumerate(infos):
        # S1 may start a few periods before the previous hole's tip is out: skip that.
        # X/Y moves into the hole above one plane and out of it above the next's.
        lo, hi = max(starts[i], ku), starts[i + 2]
        into, out = c.air_plane(i), c.air_plane(i + 1)
        low = z[lo:hi] < min(into, out)  # one visit below both planes (pecks stay below R)
        if not low.any():
            continue
        kv = lo + int(np.argmax(low))
        kw = hi if low[kv - lo:].all() else kv + int(np.argmin(low[kv - lo:]))
        kb = kv + int(np.argmin(z[kv:kw]))  # the hole's bottom
        kd = lo + int(np.argmax(z[lo:hi] < into))
        ku = kb + int(np.argmin(z[kb:hi] < out))
        ku = hi if z[ku] < out else ku
        # Off-hole samples before the hole's bottom are a late arrival, after it an early exit.
        far = np.hypot(feedback[lo:hi, 0] - info["x"], feedback[lo:hi, 1] - info["y"]) > c.xy_tolerance
        before = np.nonzero(far[: kb - lo])[0]
        after = np.nonzero(far[kb - lo:])[0]
        down[i] = (lo + before[-1] + 1 if len(before) else lo) - kd
        up[i] = ku - (kb + after[0] if len(after) else hi)
    return down, up


def _safe_gaps(job: _Job, emit: Emit, t0: float, e_down: np.ndarray, e_up: np.ndarray,
               floor_down: np.ndarray, floor_up: np.ndarray, rounds: int = SAFETY_ROUNDS
               ) -> tuple[np.ndarray, np.ndarray]:
    """Move each gap by whole servo periods until the feedback is safe with no slack left.

    With rounds=1 it returns after one correction, to learn the lag margins. A gap that
    once had to grow is never shrunk again, so the search cannot oscillate; no gap goes
    below its floor, where the commands themselves stop being safe.
    """
    period = job.cycle.servo_period
    full = np.full(job.n, job.z.acceleration)
    grew_down = np.zeros(job.n, bool)
    grew_up = np.zeros(job.n, bool)
    for _ in range(rounds):
        down, up = _margins(job, emit, t0, e_down, e_up, full)
        up = np.roll(up, 1)  # hole i's exit constrains the start of S1 for hole i+1
        up[0] = 0.0
        grew_down |= down > 0
        grew_up |= up > 0
        new_down = np.where(grew_down & (down <= 0), e_down, np.maximum(e_down + down * period, floor_down))
        new_up = np.where(grew_up & (up <= 0), e_up, np.maximum(e_up + up * period, floor_up))
        if np.all(down <= 0) and np.all(up <= 0) and np.allclose(new_down, e_down) and np.allclose(new_up, e_up):
            return e_down, e_up
        e_down, e_up = new_down, new_up
    if rounds > 1:
        drive = job.machine.drives["z"]
        raise JobError("drill.overlap" if job.cycle.overlap else "drill",
                       f"no timing found in {rounds} drive-model rounds that keeps X/Y on the hole while the "
                       f"tip is below R against the servo lag (z: kp {drive.kp:g}/s, velocity_lag "
                       f"{drive.velocity_lag * 1e3:.3g} ms)" + ("; overlap: off drills conventionally"
                                                                if job.cycle.overlap else ""))
    return e_down, e_up


def _margins(job: _Job, emit: Emit, t0: float, e_down: np.ndarray, e_up: np.ndarray,
             accel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plan the cycle on a scratch builder and measure its lag margins on feedback."""
    builder = PlanBuilder(job.machine, job.start)
    infos = emit(builder, t0, e_down, e_up, accel, False)
    return _lag_margins(job, builder.build(), infos, t0)


def _gentle_accels(job: _Job, emit: Emit, t0: float, e_down: np.ndarray, e_up: np.ndarray,
                   starts: list[tuple[float, float, float]], air_times: list[float]) -> np.ndarray:
    """Lowest Z acceleration per air move that keeps its duration and the feedback safe.

    Time first: bisect the limit until the move's own minimum time just fits the time
    the cycle leaves it. Then safety: gentler braking into R shrinks Z's favourable lag
    there, so holes whose feedback turns unsafe get their limit bisected back up
    (the full limit is the plain cycle, known safe).
    """
    full = job.z.acceleration
    c = job.cycle
    low = np.empty(job.n)
    for i, (state, air_time) in enumerate(zip(starts, air_times)):
        lo, hi = max(abs(state[2]), 0.02 * full), full
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if job.arc(state, c.air_plane(i), mid).duration <= air_time + 1e-9 else (mid, hi)
        low[i] = hi
    safe = np.full(job.n, full)
    test = low
    for _ in range(GENTLE_ROUNDS):
        ok = _margins(job, emit, t0, e_down, e_up, test)[0] <= 0
        safe = np.where(ok, np.minimum(safe, test), safe)
        low = np.where(ok, low, test)
        test = 0.5 * (low + safe)
    # Keep a lower limit only where it really lowers the energy: ruckig stretches a
    # move to a given duration differently under different limits.
    for i, (state, air_time) in enumerate(zip(starts, air_times)):
        plane = c.air_plane(i)
        plain = job.arc(state, plane) if i == 0 else job.arc(state, plane, full, air_time)
        if safe[i] < full and _air_energy(job.arc(state, plane, safe[i], air_time)) >= _air_energy(plain):
            safe[i] = full
    return safe


def plan_drilling(builder: PlanBuilder, cycle: DrillCycle) -> list[dict]:
    """Append the whole drilling cycle to ``builder`` (tool above R, at rest) and return,
    per hole: hole index, x, y, mode, the plan times s1, s1_end, s2 (Z leaves R'),
    r_down, s3 and r_up; for the overlapped cycle also apex_z (R'), air_time, air_accel
    and air_energy (integral of a_z^2 dt over the air move into the hole: the proxy the
    gentle variant lowers).

    The timing search runs the drive model from the cycle's start with the drives at
    rest there, as after any rapid.
    """
    start = {j: builder.position(j) for j in builder.machine.joint_names}
    job = _Job(builder.machine, cycle, start)
    t0 = builder.end_time()
    full = np.full(job.n, job.z.acceleration)
    if not cycle.overlap:
        emit = _emit_conventional(job)
        zeros = np.zeros(job.n)
        e_down, e_up = _safe_gaps(job, emit, t0, zeros, zeros, zeros, zeros)
        return emit(builder, t0, e_down, e_up, full, True)
    # Command-level floors: X/Y may leave the hole only once Z is above R, and must be
    # back inside the tolerance before Z goes below R (in whole servo periods).
    period = cycle.servo_period
    floor_down = np.array([math.ceil((xy.arrive - xy.duration) / period - 1e-9) * period for xy in job.xy])
    floor_up = np.array([0.0] + [-math.floor(xy.leave / period + 1e-9) * period
                                 if xy.move and math.isfinite(xy.leave) else 0.0 for xy in job.xy[1:]])
    xy_time = np.array([xy.duration for xy in job.xy])
    last_bottom = job.turning_point(job.n - 1)

    def retracts(e_down: np.ndarray, e_up: np.ndarray) -> list[_Retract]:
        air_needed = e_up + xy_time + e_down
        laws: dict[tuple[float, float], _Retract] = {}  # holes of one pitch and depth need the same law
        out = []
        for i in range(job.n - 1):
            key = (float(air_needed[i + 1]), job.turning_point(i), cycle.air_plane(i + 1))
            if key not in laws:
                laws[key] = job.retract(key[0], i)
            out.append(laws[key])
        return out + [job.fast_exit(last_bottom, cycle.r_z)]

    # One round at the command floors measures the lag margins; with them the retract
    # laws are chosen once more, then the gaps settle.
    e_down, e_up = _safe_gaps(job, _emit_overlapped(job, retracts(floor_down, floor_up)), t0,
                              floor_down, floor_up, floor_down, floor_up, rounds=1)
    chosen = retracts(e_down, e_up)
    emit = _emit_overlapped(job, chosen)
    e_down, e_up = _safe_gaps(job, emit, t0, e_down, e_up, floor_down, floor_up)
    accel = full
    if cycle.gentle_air_accel:
        infos = emit(PlanBuilder(job.machine, start), t0, e_down, e_up, full, False)
        ups = [t0] + [info["r_up"] for info in infos[:-1]]
        air_times = [info["r_down"] - u for info, u in zip(infos, ups)]
        starts = [(start["z"], 0.0, 0.0)] + [r.state for r in chosen[:-1]]
        accel = _gentle_accels(job, emit, t0, e_down, e_up, starts, air_times)
    return emit(builder, t0, e_down, e_up, accel, True)


def lower_bound_time(machine: Machine, cycle: DrillCycle,
                     start_xy: tuple[float, float] | None = None) -> float:
    """Sum over holes of the X/Y positioning time (from ``start_xy`` for the first hole,
    if given) and the fastest possible time below R: feed from R to depth, then full
    acceleration back to R. X/Y may not move while the tip is below R, so no safe cycle
    is shorter."""
    first = start_xy if start_xy is not None else cycle.holes[0]
    job = _Job(machine, replace(cycle, compensate_xy=False), {"x": first[0], "y": first[1], "z": cycle.r_z})
    # each hole from its own R (a fall from the X/Y plane to a lower one left out) to its bottom
    below = sum(job._stroke(top, bottom).duration + job.fast_exit(bottom, cycle.r_z).t_r
                for _, top, bottom in map(cycle.planes, range(job.n)))
    return sum(xy.duration for xy in job.xy) + below


def plan_cycle(builder: PlanBuilder, cycle: DrillCycle) -> None:
    try:
        plan_drilling(builder, cycle)
    except JobError:
        raise  # names its field already
    except ValueError as err:  # one line: ruckig appends its whole input to its errors
        first = (str(err).splitlines() or [""])[0]
        name, sep, reason = first.partition(": ")
        if sep and re.fullmatch(r"(holes(\[\d+\])?|feed|mode)", name):  # a field of the drill block
            raise JobError(f"drill.{name}", reason) from err
        if sep and name.startswith("vibration"):
            raise JobError(name, reason) from err
        if sep and name == "length":  # a vibrated stroke too short to ramp onto the waveform
            raise JobError("drill.depth", reason) from err
        raise JobError("drill", first) from err
