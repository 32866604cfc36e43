"""S1, the X/Y rapid to each hole: its ruckig move, when its command leaves and re-enters
the position tolerance, and its drive-model correction with the headroom that needs.

X/Y pre-compensation (compensate_xy, on by default): with kp = 50/s and no acceleration
feed-forward the X/Y feedback settles within the tolerance only 30-50 ms after a rapid's
command ends, and Z has to wait for it. Each S1 command is therefore the ruckig move plus
a correction learned against the drive model (motion.compensation: the exact
inverse of the drive's linear part, refined against DriveModel.simulate), so that the
FEEDBACK follows the ruckig move and is in position when the move ends. The command
leads the move by XY_COMMAND_LEAD servo periods (from rest) and keeps settling
(exponentially, at the position loop's rate, with the drive at rest) for up to ~0.2 s
after it; consecutive corrections simply add (the drive is linear), so a tail may run
into the next hole's S1 (xy_command.py). S1 starts on the servo grid (its correction is
learned on it). The command stays within the axis velocity and acceleration limits
(finite differences, tested), but where ruckig switches jerk the correction briefly needs
more jerk than the axis limit, as in vibration; the motion the feedback follows is the
ruckig move. The command itself arrives at the hole some tens of ms after the feedback
does, so only the feedback, not the command, is safe at R then. compensate_xy=False plans
the plain ruckig commands (then both are safe), for comparison.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.drill.cycle import DrillCycle, DrillError
from cnc_planner.motion.compensation import COMPENSATION_TAIL, learned_command
from cnc_planner.motion.moves import Limits, RuckigMove, axis_limits, point_to_point

XY = ("x", "y")
CROSSING_STEP = 1e-4  # s, sampling of a command's tolerance crossings
CROSSING_CHUNK = 256  # instants sampled at a time from either end: the crossings lie near the ends
XY_LEAD_PERIODS = 8     # rest before an S1 move in its learning reference: room to lead
XY_FIXED_PERIODS = 4    # of which uncorrected: the compensated command leads by the rest
XY_COMMAND_LEAD = XY_LEAD_PERIODS - XY_FIXED_PERIODS + 1  # periods: from its last rest sample
XY_SETTLED_COUNTS = 0.25  # encoder counts: an X/Y correction below this has settled
XY_ACCELERATION_SHARES = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3)  # of an S1 move's limits,
XY_JERK_SHARES = (1.0, 0.3, 0.1, 0.03, 0.01, 3e-3, 1e-3, 3e-4)  # tried fastest first
XY_HEADROOM_TRIES = 24  # moves tried before the plain (uncompensated) one
XY_VELOCITY_ROUNDS = 3  # lower velocity shares tried when the command overshoots the velocity
XY_HEADROOM_MARGIN = 0.99  # of the limits: the compensated command stays this far inside them
XY_HEADROOM_AIM = 0.98  # a lowered velocity share aims this far inside them


@dataclass(frozen=True)
class XYMove:
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

    @property
    def correction_samples(self) -> int:
        """Servo samples of its correction (1 for a move planned without one)."""
        return self.correction.shape[1] if self.correction is not None else 1


def s1_moves(machine: Machine, cycle: DrillCycle, start: dict[str, float]) -> list[XYMove]:
    """S1 of every hole from the start, each hole checked against the X/Y travel; in the
    overlapped cycle with compensate_xy each move carries its correction."""
    position = (start["x"], start["y"])
    moves: list[XYMove] = []
    corrections: dict[tuple, tuple] = {}
    crossings: dict[tuple, tuple[float, float]] = {}
    for i, hole in enumerate(cycle.holes):
        for axis, value in zip(XY, hole):
            if not machine.axes[axis].within_travel(value):
                raise DrillError(f"drill.holes[{i}]", f"{axis} = {value} m is outside the travel")
        moved = _moved_axes(position, hole)
        # The drive is linear up to its encoder counts, and a move's shape depends on its
        # displacement only: one correction, and one pair of tolerance crossings, per
        # displacement (a plate of one pitch computes each once, not at every hole).
        key = tuple(round((dict(zip(XY, hole))[j] - dict(zip(XY, position))[j]) * 1e9) for j in moved)
        shares, correction = (1.0, 1.0, 1.0), None
        if moved and cycle.overlap and cycle.compensate_xy:
            if key not in corrections:
                corrections[key] = _headroom(machine, cycle.servo_period, position, hole, cycle.xy_tolerance)
            shares, correction = corrections[key]
        xy = _xy_move(machine, position, hole, cycle.xy_tolerance, shares, crossings.get((key, shares)))
        if xy.move is not None:
            crossings[key, shares] = (xy.leave, xy.arrive)
        moves.append(replace(xy, correction=correction) if correction is not None else xy)
        position = hole
    return moves


def _xy_move(machine: Machine, p0: tuple[float, float], p1: tuple[float, float], tol: float,
            shares: tuple[float, float, float] = (1.0, 1.0, 1.0),
            crossings: tuple[float, float] | None = None) -> XYMove:
    """S1 as the builder's rapid will plan it, with its command's tolerance crossings
    (``crossings``, leave and arrive, if known from a move of the same displacement);
    ``shares`` of the velocity, acceleration and jerk limits leave headroom for the drive
    compensation (_headroom)."""
    target = dict(zip(XY, p1))
    move, joints = _limited(machine, p0, p1, shares)
    if move is None:
        return XYMove(target, None, math.inf, 0.0)
    if crossings is not None:
        return XYMove(target, move, *crossings, tuple(joints))
    ts = np.arange(0.0, move.duration + CROSSING_STEP, CROSSING_STEP)
    start = np.array([dict(zip(XY, p0))[j] for j in joints])
    end = np.array([target[j] for j in joints])
    # Conservative on the sampling grid: leave one step early, arrive one step late. A
    # move shorter than the tolerance (a hole given twice) never leaves it at all.
    left = _outside(move, ts, start, tol, last=False)
    away = _outside(move, ts, end, tol, last=True)
    leave = max(ts[left] - CROSSING_STEP, 0.0) if left is not None else math.inf
    arrive = ts[away] + CROSSING_STEP if away is not None else 0.0
    return XYMove(target, move, leave, arrive, tuple(joints))


def _outside(move: RuckigMove, ts: np.ndarray, point: np.ndarray, tol: float, last: bool) -> int | None:
    """Index of the first instant of ts (the last, with ``last``) at which the move is
    farther than tol from point, or None. Sampled CROSSING_CHUNK instants at a time from
    that end: the same index as sampling all of ts (each instant's sample and distance
    are its own), without sampling the middle of the move."""
    n = len(ts)
    for k in range(0, n, CROSSING_CHUNK):
        lo, hi = (max(n - k - CROSSING_CHUNK, 0), n - k) if last else (k, min(k + CROSSING_CHUNK, n))
        p = move.sample_all(np.minimum(ts[lo:hi], move.duration))[0]
        far = np.nonzero(np.linalg.norm(p - point, axis=1) > tol)[0]
        if len(far):
            return lo + int(far[-1] if last else far[0])
    return None


def _moved_axes(p0: tuple[float, float], p1: tuple[float, float]) -> list[str]:
    """The X/Y axes an S1 move from p0 to p1 moves."""
    return [j for j, a, b in zip(XY, p0, p1) if abs(a - b) > 1e-12]


def _limited(machine: Machine, p0: tuple[float, float], p1: tuple[float, float],
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


def _headroom(machine: Machine, period: float, p0: tuple[float, float],
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
        for shares in sorted(grid, key=lambda shares: _limited(machine, p0, p1, shares)[0].duration)[:XY_HEADROOM_TRIES]:
            candidate = _xy_move(machine, p0, p1, tol, shares)
            correction, (over_v, over_a) = _correction(machine, period, candidate)
            if over_v > XY_HEADROOM_MARGIN:
                velocity *= XY_HEADROOM_AIM / over_v
                break
            if over_a <= XY_HEADROOM_MARGIN:
                return shares, correction
        else:
            break
    return (1.0, 1.0, 1.0), None


def _correction(machine: Machine, period: float, xy: XYMove) -> tuple[np.ndarray, tuple[float, float]]:
    """The drive-model correction (3, k, joints) of one S1 move, from rest, on the servo
    grid: sample 0 (still zero) lies XY_COMMAND_LEAD periods before the move starts; and by
    how much the command (move plus correction) exceeds the velocity and acceleration limits.

    The reference is the ruckig move relative to its start, at rest XY_LEAD_PERIODS
    periods before and COMPENSATION_TAIL s after; learned_command leaves its first
    XY_FIXED_PERIODS samples uncorrected (all but the last dropped here) and cuts the tail where
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
