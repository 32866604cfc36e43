"""A pass of spindle-synchronised moves (G33): straight moves locked to the spindle's angle.

The pass waits at rest for the spindle's index (its angle a whole number of turns, as
LinuxCNC's G33 waits for the index pulse), then runs its moves without stopping, each
advancing its lead along its path per revolution. Every pass that starts from rest at the
index at one spindle speed follows the same motion against the spindle angle, ramps
included, so the passes of a multi-pass thread land in one groove, shifted only as their
programmed starts are.

The motion is the ideal one (the tool at constant velocity lead * rpm along each move,
every velocity change a step) with each step replaced by a symmetric jerk-limited ramp
centred on it (triangular acceleration): a symmetric ramp leaves the axis on the ideal
line once it is over, so after the first ramp the tool is exactly K per revolution behind
where an instantaneous start would have put it, a lag that is the same on every pass.
The first ramp begins at the index (the ideal start is half a ramp after it); the last
ends at the pass's end point, at rest.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.timeline import Piece, WritingSampler

TWO_PI = 2.0 * math.pi


def ramp_time(change: np.ndarray, acceleration: np.ndarray, jerk: np.ndarray) -> float:
    """The shortest triangular-acceleration ramp that changes every axis's velocity by
    ``change`` (m/s) within its acceleration and jerk: peak acceleration 2|dv|/T, jerk 4|dv|/T^2."""
    dv = np.abs(change)
    return float(np.max(np.maximum(2.0 * dv / acceleration, 2.0 * np.sqrt(dv / jerk))))


def ramp(u: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A unit velocity step at u = 0 smoothed over [-width/2, width/2]: position, velocity,
    acceleration (position 0 before, u after: the ideal step's, once the ramp is over)."""
    s = np.clip(u + width / 2.0, 0.0, width)
    first = s <= width / 2.0
    rest = width - s
    w2 = width * width
    position = np.where(first, 2.0 * s**3 / (3.0 * w2), width / 2.0 - rest + 2.0 * rest**3 / (3.0 * w2))
    velocity = np.where(first, 2.0 * s**2 / w2, 1.0 - 2.0 * rest**2 / w2)
    acceleration = np.where(first, 4.0 * s / w2, 4.0 * rest / w2)
    after = u > width / 2.0
    position = np.where(after, u, position)
    acceleration = np.where((u < -width / 2.0) | after, 0.0, acceleration)
    return position, velocity, acceleration


@dataclass(frozen=True)
class PassMotion:
    """One pass's motion from the index: per axis (rows of ``steps``) the velocity steps at
    the instants ``centres`` (s after the index), each ramped over its ``widths``."""

    start: np.ndarray  # axis positions at rest where the pass begins
    steps: np.ndarray  # (changes, axes): velocity change, m/s
    centres: np.ndarray
    widths: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.centres[-1] + self.widths[-1] / 2.0)

    def state(self, t: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of one axis at times t after the index."""
        p = np.full_like(t, self.start[axis])
        v, a = np.zeros_like(t), np.zeros_like(t)
        for step, centre, width in zip(self.steps[:, axis], self.centres, self.widths):
            if step != 0.0:
                rp, rv, ra = ramp(t - centre, width)
                p, v, a = p + step * rp, v + step * rv, a + step * ra
        return p, v, a


class _Axis(WritingSampler):
    """One axis of a pass as a timeline piece."""

    def __init__(self, sync: PassMotion, axis: int) -> None:
        self.sync, self.axis = sync, axis

    def write(self, t: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        out[0][:], out[1][:], out[2][:] = self.sync.state(t, self.axis)


def pass_motion(machine: Machine, joints: list[str], start: np.ndarray, points: list[np.ndarray],
                leads: list[float], speed: float, fields: list[str], ease: float = 1.0) -> PassMotion:
    """The pass from ``start`` through ``points`` (axis positions, m), each move advancing
    its lead (m along its path per revolution) at spindle ``speed`` (rad/s), every ramp
    ``ease`` times as long as the axes' acceleration and jerk allow (kinds.sync.margin).

    Raises:
        JobError: a move faster than an axis may go, or too short for the ramps into and
            out of it at the axes' acceleration and jerk (named by its field).
    """
    axes = [machine.axes[j] for j in joints]
    top = np.array([a.max_velocity for a in axes])
    acceleration = np.array([a.max_acceleration for a in axes]) / ease
    jerk = np.array([a.max_jerk for a in axes]) / ease**2
    velocities, durations = [np.zeros(len(joints))], []
    here = start
    for point, lead, field in zip(points, leads, fields):
        length = float(np.linalg.norm(point - here))
        if length <= 1e-12:
            raise JobError(field, "moves nowhere: a synchronised move needs a length")
        feed = lead * speed / TWO_PI
        velocity = (point - here) / length * feed
        fast = np.abs(velocity) > top
        if fast.any():
            j = int(np.argmax(fast))
            raise JobError(field, f"{to_mm(feed) * 60:.6g} mm/min (lead x rpm) drives {joints[j]} faster than its "
                                  f"{to_mm(top[j]) * 60:g} mm/min")
        velocities.append(velocity)
        durations.append(length / feed)
        here = point
    velocities.append(np.zeros(len(joints)))
    steps = np.diff(np.array(velocities), axis=0)
    widths = np.array([ramp_time(step, acceleration, jerk) for step in steps])
    centres = widths[0] / 2.0 + np.concatenate(([0.0], np.cumsum(durations)))
    for k, field in enumerate(fields):  # the ramps at either end of a move must not overlap
        if centres[k + 1] - centres[k] < (widths[k] + widths[k + 1]) / 2.0:
            raise JobError(field, "too short to be locked to the spindle: the axes' ramps into and out of it "
                                  f"need {to_mm((widths[k] + widths[k + 1]) / 2.0 * np.linalg.norm(velocities[k + 1])):.3g} mm")
    return PassMotion(np.asarray(start, dtype=float), steps, centres, widths)


def plan_pass(builder: PlanBuilder, joints: list[str], points: list[np.ndarray], leads: list[float],
              fields: list[str], ease: float = 1.0) -> tuple[float, float]:
    """Append a pass of synchronised moves from where the axes stand: at rest until the
    spindle's index once the axes are free and the spindle at its speed, then locked to its
    angle, its ramps ``ease`` times the shortest. Returns (index time, end time)."""
    spindle = builder.timelines[SPINDLE]
    speed = spindle.end_velocity
    start = np.array([builder.position(j) for j in joints])
    sync = pass_motion(builder.machine, joints, start, points, leads, speed, fields, ease)
    ready = max(builder.free_from(joints), builder.spindle_ready, spindle.end_time)
    index = ready + (-spindle.position_at(ready)) % TWO_PI / speed
    for axis, joint in enumerate(joints):
        builder.timelines[joint].add(Piece(index, sync.duration, _Axis(sync, axis)), float(points[-1][axis]))
    return index, index + sync.duration
