"""The path's tip on every drive inside the tolerance, and the knob that brings it within.

The traverse's command is compensated for the described drives (kinds.path.exact), so on
them the tip follows the programmed lines. A real drive inside the description's tolerance
(cnc_msgs_py.machine.Tolerance) responds otherwise: on mill3 a 0.7x gain with a 3x slower
velocity loop overshoots each stop of a G64 P0.02 path by 0.032 mm at 1200 mm/min, where the
described drive stays within 0.2 um. So the plan also runs its command through the corners
of the tolerance (motion.compensation.tolerance_drives), the k-th corner of every joint
together as bench/program_corners.py and the thread's tolerance check pair them, all in one
drive model, and measures the worst tip against the programmed lines.

Where that tip leaves TOLERANCE_SHARE of the chord tolerance, the stretches are planned
again on less of the axes' jerk (``jerk_share``): the overshoot grows with how abruptly the
command stops, and on the oracle program (test/gcode_oracle/path_tolerance_g64.ngc) a
tenth of the jerk takes the worst corner from 0.032 to 0.021 mm for 3 % more path time,
where the lower feed that holds P would cost some 70 %; the acceleration and the corner
speeds are left alone (less of them costs time on the arcs and gains nothing more). Only
below MIN_JERK_SHARE is the feed lowered. A closed tolerance trusts the description:
nothing is checked.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Protocol, TypeVar

import numpy as np

from cnc_msgs_py.machine import Drive, Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.compensation import tolerance_drives

from .polyline import distance_to_polyline

TOLERANCE_SHARE = 0.9  # of the chord tolerance the worst drive inside the tolerance may use
MIN_JERK_SHARE = 0.01  # least share of the jerk tried; below it the feed is lowered
JERK_SLOPE = 0.25  # d log(deviation) / d log(jerk share) assumed before two tries measure it
SLOPE_RANGE = (0.1, 1.0)  # the measured slope clipped to this, so that a flat step cannot run away
STEP_RANGE = (0.05, 0.7)  # factor on the jerk share per try
JERK_TRIES = 6  # plans at most to find the share of the jerk (soften)
REFINED = 0.8  # of the target: a share whose worst tip uses less is refined upwards, if tries are left
AIM = 0.9  # of the target: where a share between two tries is aimed
BETWEEN_RANGE = (0.2, 0.8)  # of the way from the held share to the missed one, in log share
BRACKET_RATIO = 1.25  # missed / held shares this close: the held one is taken
NO_GAIN = 0.9  # a softer try whose worst tip is above this share of the one before gains nothing
COLUMNS_AT_ONCE = 24  # drive columns simulated together: (samples, columns) arrays stay ~20 MB on a long path


class ToleranceCorners:
    """The drives inside the tolerance a path's command is checked on: the k-th corner of
    every joint together, for each k (a joint with fewer corners repeats them, one whose
    tolerance is closed stays as described); none where every tolerance is closed."""

    def __init__(self, machine: Machine, joints: list[str], period: float):
        # the described drives are exact's own check; a joint whose tolerance is closed stays one
        each = [tolerance_drives(machine, j)[1:] or [machine.drives[j]] for j in joints]
        count = max(len(c) for c in each) if any(len(tolerance_drives(machine, j)) > 1 for j in joints) else 0
        self.machine, self.joints, self.period = machine, joints, period
        # A delay every joint shares only shifts the tip in time (from rest, on the same
        # command): a corner that differs from one already taken by that alone is left out.
        seen: set[tuple[Drive, ...]] = set()
        self.columns: list[tuple[str, Drive]] = []
        for k in range(count):
            drives = [c[k % len(c)] for c in each]
            common = min(d.delay for d in drives)
            key = tuple(replace(d, delay=d.delay - common) for d in drives)
            if key not in seen:
                seen.add(key)
                self.columns += list(zip(joints, drives))

    def __bool__(self) -> bool:
        return bool(self.columns)

    def deviation(self, kin: Kinematics, command: np.ndarray, points: np.ndarray, tips: np.ndarray,
                  distances: np.ndarray) -> float:
        """The largest distance (m) of any corner's predicted tip from the programmed lines,
        on the command (3, n, joints) from rest at its first sample; ``tips`` and
        ``distances`` are the described drives' (n, 3) and (n,). A corner's tip is no
        farther from the lines than the described tip plus the distance between the two, so
        only the samples where that bound passes the worst found so far are measured."""
        width = len(self.joints)
        per_run = max(1, COLUMNS_AT_ONCE // width) * width
        worst = 0.0
        for lo in range(0, len(self.columns), per_run):
            columns = self.columns[lo:lo + per_run]
            model = DriveModel.columns(self.machine, self.period, columns)
            source = np.tile(np.arange(width), len(columns) // width)
            model.reset(command[0, 0][source])
            feedback = model.run_shared(*command, source)[0]
            for k in range(0, len(columns), width):
                corner, _ = kin.fk_many({j: feedback[:, k + i] for i, j in enumerate(self.joints)})
                near = distances + np.linalg.norm(corner - tips, axis=1) > worst
                if near.any():
                    worst = max(worst, float(distance_to_polyline(corner[near], points).max()))
        return worst


class Tried(Protocol):
    """A traverse planned on a share of the jerk, with its worst predicted tip (m)."""

    jerk_share: float
    corner_deviation: float


T = TypeVar("T", bound=Tried)


def soften(attempt: Callable[[float], T], first: T, target: float) -> T:
    """The traverse on the largest share of the jerk found whose worst tip holds ``target``,
    from ``first`` (which misses it); ``attempt`` plans one on a share. Shares go down by
    next_jerk_share until one holds, then between the two closest that miss and hold
    (between) until the one that holds uses REFINED of the target or they are within
    BRACKET_RATIO; JERK_TRIES plans at most. If none holds, down to MIN_JERK_SHARE or until
    a softer try gains less than NO_GAIN on the one before (the miss is not the stops': an
    arc's centripetal acceleration), the caller lowers the feed from the last that missed,
    or from ``first`` where the softening gained less than that in all: it would cost time
    for nothing."""
    missed, held = first, None
    tries = [(first.jerk_share, first.corner_deviation)]
    for _ in range(JERK_TRIES):
        if held is None:
            if missed.jerk_share <= MIN_JERK_SHARE:
                break
            share = next_jerk_share(tries, target)
        else:
            share = between(missed, held, target)
        done = attempt(share)
        tries.append((share, done.corner_deviation))
        if done.corner_deviation <= target:
            held = done
        else:
            gain = done.corner_deviation < NO_GAIN * missed.corner_deviation
            missed = done
            if held is None and not gain:
                return missed if missed.corner_deviation < NO_GAIN * first.corner_deviation else first
        if held is not None and (held.corner_deviation >= REFINED * target
                                 or missed.jerk_share < BRACKET_RATIO * held.jerk_share):
            break
    return missed if held is None else held


def between(missed: Tried, held: Tried, target: float) -> float:
    """The share between one that missed and one that held the target (held's is smaller):
    where the worst tip is AIM of the target, interpolated in log-log, kept BETWEEN_RANGE
    of the way (in log share) from held's to missed's so that each try narrows them."""
    lo, hi = math.log(held.jerk_share), math.log(missed.jerk_share)
    d_lo, d_hi = math.log(max(held.corner_deviation, 1e-12)), math.log(missed.corner_deviation)
    way = (math.log(AIM * target) - d_lo) / (d_hi - d_lo) if d_hi > d_lo else 0.5
    return math.exp(lo + float(np.clip(way, *BETWEEN_RANGE)) * (hi - lo))


def next_jerk_share(tries: list[tuple[float, float]], target: float) -> float:
    """The share of the jerk to try next, from the tries so far at this feed
    ((share, worst corner deviation) in order): a secant step in log-log towards ``target``
    (JERK_SLOPE until two tries differ), within STEP_RANGE, not below MIN_JERK_SHARE."""
    share, deviation = tries[-1]
    slope = JERK_SLOPE
    if len(tries) > 1 and tries[-2][0] != share and tries[-2][1] > deviation > 0.0:
        slope = float(np.clip(math.log(tries[-2][1] / deviation) / math.log(tries[-2][0] / share), *SLOPE_RANGE))
    step = math.exp(math.log(target / deviation) / slope)
    return max(MIN_JERK_SHARE, share * float(np.clip(step, *STEP_RANGE)))
