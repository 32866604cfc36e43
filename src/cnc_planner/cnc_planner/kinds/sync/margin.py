"""Passes and taps that hold their lock on every drive inside the tolerance.

A pass's axes are not compensated: during its ramp onto the lead (and a tap's through the
spindle's reversal) each drive lags its command by its own dynamics, and what the lock sees
is the difference between the axis's lag and the spindle's through the lead. On the
described drives that stays a few um, but a drive inside the stated tolerance (lower gain,
slower velocity loop, less feed-forward) lags more while it accelerates, and the first
samples at which its feedback runs at the lead can still be tens of um off the lock that
it settles onto. That error scales with the acceleration: a ramp ``ease`` times longer
(acceleration / ease, jerk / ease^2) leaves about 1/ease of it.

So each pass and tap is planned on a scratch builder first (the spindle already at speed,
the axes at rest where the real one starts), its command run through the drive model on
the described drives and on every corner of their tolerance (the k-th corner of every
joint together, the pairing bench/program_corners.py judges), and its lock measured on
that predicted feedback: the spread of (progress along the move - lead x spindle angle /
2 pi) wherever the feedback runs within BAND of its lead, a wider band than a measurement
calls locked, so that no sample a judge would count is left out. The smallest ease of
EASES whose worst drive keeps that spread within LOCK_SHARE of the lock tolerance is
planned. All passes of one thread (lead, direction of their first move, spindle speed)
share one ease, the largest any of them needs: the ramp onto the lead sets where a pass
lies in its groove, and passes with unlike ramps would land apart.

The same prediction says how long after its last ramp every such drive takes to stand
within SETTLED of where the pass (or tap) ends; the axes hold there that long, so that the
next move starts from a tool that has arrived.

The spindle is simulated as its deviation from steady rotation (the drive model's linear
part: a constant speed leaves a constant lag, which moves no offset), so that the scratch
plan need not run it up first.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.compensation import corner_plants

TWO_PI = 2.0 * math.pi
# m: the thread's flank tolerance the lock must hold, as the judge (cnc_analysis.spindle_sync,
# which planning does not load) holds it; test_sync_tolerance_corners keeps the two equal
LOCK_TOLERANCE = 0.02e-3
LOCK_SHARE = 0.85  # of the lock tolerance the worst predicted drive may use
EASES = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0)  # ramp stretch factors tried, in order
BAND = 0.05  # progress within this share of one lead per revolution counts as running at the lead
WINDOW = 2  # servo periods either side over which the progress per revolution is taken
SETTLED = 2e-6  # m: a drive this close to where the pass ends stands there
TAIL = 0.5  # s of prediction past the pass's end in which every drive must arrive


@dataclass(frozen=True)
class Margin:
    """What a pass or tap needs: its ease and how long the axes hold after it (s)."""

    ease: float
    hold: float


def _predict(machine: Machine, builder: PlanBuilder, end: float, joints: list[str],
             speed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scratch plan's feedback on every plant: times (n,), the axes (plants, n, axes) and
    the spindle angle (plants, n), from rest (the spindle turning steadily at ``speed``) at
    the plan's start until TAIL after ``end``."""
    described = machine.nominal or machine
    plan = builder.build(stop_spindle=False)
    t = np.arange(math.ceil((end + TAIL) / SERVO_PERIOD) + 1) * SERVO_PERIOD
    order = [*joints, SPINDLE]
    p, v, a = plan.sample(t, tuple(order))
    p[:, -1] -= p[0, -1] + speed * t  # the spindle as its deviation from steady rotation
    v[:, -1] -= speed
    plants = corner_plants(described, order)
    model = DriveModel.columns(described, SERVO_PERIOD, [(j, plant[j]) for plant in plants for j in order])
    fb, _ = model.simulate(*(np.tile(x, (1, len(plants))) for x in (p, v, a)))
    fb = fb.reshape(len(t), len(plants), len(order)).transpose(1, 0, 2)
    return t, fb[:, :, :-1], fb[:, :, -1] + speed * t


def _at_lead(theta: np.ndarray, u: np.ndarray, lead: float) -> np.ndarray:
    """Where u advances within BAND of one lead per revolution of theta (either way round),
    over WINDOW samples either side (the first and last WINDOW samples, at rest, never)."""
    span = 2 * WINDOW
    du, dtheta = u[span:] - u[:-span], theta[span:] - theta[:-span]
    near = np.abs(du * TWO_PI - lead * dtheta) < BAND * lead * np.abs(dtheta)
    return np.concatenate((np.zeros(WINDOW, bool), near & (dtheta != 0.0), np.zeros(WINDOW, bool)))


def _hold(t: np.ndarray, axes: np.ndarray, end: float, where: np.ndarray) -> float:
    """How long after ``end`` the last plant stands within SETTLED of ``where`` for good."""
    away = np.flatnonzero(np.any(np.linalg.norm(axes - where, axis=2) > SETTLED, axis=0))
    return max(0.0, float(t[away[-1]]) + SERVO_PERIOD - end) if away.size else 0.0


def pass_error(axes: np.ndarray, theta: np.ndarray, start: np.ndarray,
               points: list[np.ndarray], leads: list[float]) -> float:
    """The largest spread of any move's lock offset (m) over the plants' predicted feedback."""
    worst = 0.0
    here = start
    for point, lead in zip(points, leads):
        length = float(np.linalg.norm(point - here))
        direction = (point - here) / length
        for fb, th in zip(axes, theta):
            u = (fb - here) @ direction
            locked = _at_lead(th, u, lead) & (u > 0.0) & (u < length)
            if locked.sum() >= 2:
                worst = max(worst, float(np.ptp(u[locked] - lead * th[locked] / TWO_PI)))
        here = point
    return worst


def tap_error(axes: np.ndarray, theta: np.ndarray, start: np.ndarray, bottom: np.ndarray, lead: float) -> float:
    """The largest spread of the tap's lock offset (m), from the first sample at its lead going
    in to the last coming out, over the plants' predicted feedback."""
    direction = (bottom - start) / np.linalg.norm(bottom - start)
    worst = 0.0
    for fb, th in zip(axes, theta):
        u = (fb - start) @ direction
        at = np.flatnonzero(_at_lead(th, u, lead) & (u > 0.0))
        if at.size >= 2:
            part = slice(int(at[0]), int(at[-1]) + 1)
            worst = max(worst, float(np.ptp(u[part] - lead * th[part] / TWO_PI)))
    return worst


def find_margin(machine: Machine, joints: list[str], start: np.ndarray, speed: float, first: float,
                plan: Callable[[PlanBuilder, float], tuple[float, float]],
                error: Callable[[np.ndarray, np.ndarray], float], ends_at: np.ndarray,
                field: str) -> Margin:
    """The smallest ease from ``first`` on (EASES) at which ``plan`` (builder, ease -> index and
    end time), run from rest at ``start`` with the spindle at ``speed``, keeps ``error`` (on
    the predicted feedback: axes, spindle angle) within LOCK_SHARE of the lock
    tolerance on every plant, and the hold after it for the axes to stand at ``ends_at``.

    Raises:
        JobError: no ease holds the lock (named by ``field``), or the ramps that would do
            not fit a move (named by the move).
    """
    found, tried = 0.0, first
    for ease in (e for e in EASES if e >= first):
        builder = PlanBuilder(machine, dict(zip(joints, start.tolist())), spindle_speed=speed, events=False)
        try:
            _, end = plan(builder, ease)
        except JobError as err:
            if ease == tried:
                raise  # the move's own refusal, at the ramps it starts from
            raise JobError(err.field, f"no ramp holds the lock on every drive inside the tolerance: the worst "
                                      f"strays {to_mm(found):.4f} mm at {tried:g} times the shortest ramp, and "
                                      f"longer ones do not fit ({err.reason})") from err
        t, axes, theta = _predict(machine, builder, end, joints, speed)
        found, tried = error(axes, theta), ease
        if found <= LOCK_SHARE * LOCK_TOLERANCE:
            return Margin(ease, _hold(t, axes, end, ends_at))
    raise JobError(field, f"no ramp holds the lock on every drive inside the tolerance: the worst strays "
                          f"{to_mm(found):.4f} mm at {EASES[-1]:g} times the ramp; narrow drive.<axis>.tolerance "
                          "or identify the drives (cnc-identify)")
