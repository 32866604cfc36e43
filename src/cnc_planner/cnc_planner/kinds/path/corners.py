"""The path's tip on every drive inside the tolerance, and the knob that brings it within.

The traverse's command is compensated for the described drives (kinds.path.exact), so on
them the tip follows the programmed lines. A real drive inside the description's tolerance
(cnc_msgs_py.machine.Tolerance) responds otherwise: on mill3 a 0.7x gain with a 3x slower
velocity loop overshoots each stop of a G64 P0.02 path by 0.032 mm at 1200 mm/min, where the
described drive stays within 0.2 um. So the plan also runs its command through the corners
of the tolerance (motion.compensation.tolerance_drives), the k-th corner of every joint
together as bench/program_corners.py and the thread's tolerance check pair them, all in one
drive model, and measures the worst tip against the programmed lines.

Where that tip leaves TOLERANCE_SHARE of the chord tolerance about a stretch (the motion
between two exact stops; a stop's overshoot shows as the next one starts), that stretch is
planned again on less of its jerk (soften): the overshoot grows with how abruptly the
command stops, and on the oracle program (test/gcode_oracle/path_tolerance_g64.ngc) a
tenth of the jerk takes the worst corner from 0.032 to 0.021 mm for 3 % more path time,
where the lower feed that holds P would cost some 70 %; the acceleration and the corner
speeds are left alone (less of them costs time on the arcs and gains nothing more). Each
stretch is softened only as far as its own stops need. Where the jerk does not help (an
arc's centripetal acceleration, a 5-axis tool axis turning), that stretch alone runs
slower; only where a stretch still misses after JERK_TRIES plans does the caller lower
the feed of the whole path. A closed tolerance trusts the description: nothing is checked.
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
MIN_JERK_SHARE = 0.01  # least share of the jerk tried; a stretch that still misses there runs slower
JERK_SLOPE = 0.4  # d log(deviation) / d log(jerk share) assumed before two tries measure it
SLOPE_RANGE = (0.1, 1.0)  # the measured slope clipped to this, so that a flat step cannot run away
STEP_RANGE = (0.05, 0.7)  # factor on the jerk share per try
JERK_TRIES = 8  # plans at most to find each stretch's share of the jerk and of the speed (soften)
SPEED_STEP = (0.5, 0.9)  # factor on a stretch's speed per try where the jerk does not help
MIN_SLOPE = 0.05  # d log(deviation) / d log(jerk share) below this: softening that stretch gains nothing
REFINED = 0.8  # of the target: a stretch that holds with less tries a larger share, if tries are left
AIM = 0.9  # of the target: where a share between two tries is aimed
BETWEEN_RANGE = (0.2, 0.8)  # of the way from the held share to the missed one, in log share
BRACKET_RATIO = 1.25  # a missed share within this factor of a held one: the held one is taken
NEAR_SHARE = 0.5  # of the target: corner tips bound below this are not measured exactly
SETTLE_TIMES = 3.0  # of the slowest corner's settling time: how far about a stretch its misses are its own
NO_GAIN = 0.9  # a stretch whose softening took its worst tip to no less than this share of the first is undone
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
        self.settle = SETTLE_TIMES * max(1.0 / d.kp + d.velocity_lag + d.delay
                                         for j in joints for d in tolerance_drives(machine, j))
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

    def tip_deviations(self, kin: Kinematics, command: np.ndarray, points: np.ndarray, tips: np.ndarray,
                       distances: np.ndarray, floor: float) -> np.ndarray:
        """Per sample of the command (3, n, joints), from rest at its first: the largest
        distance (m) of any corner's predicted tip from the programmed lines, exact wherever
        it is above ``floor`` (at most ``floor`` elsewhere); ``tips`` and ``distances`` are
        the described drives' (n, 3) and (n,). A corner's tip is no farther from the lines
        than the described tip plus the distance between the two, so only the samples where
        that bound passes ``floor`` are measured."""
        width = len(self.joints)
        per_run = max(1, COLUMNS_AT_ONCE // width) * width
        worst = distances.copy()
        for lo in range(0, len(self.columns), per_run):
            columns = self.columns[lo:lo + per_run]
            model = DriveModel.columns(self.machine, self.period, columns)
            source = np.tile(np.arange(width), len(columns) // width)
            model.reset(command[0, 0][source])
            feedback = model.run_shared(*command, source)[0]
            for k in range(0, len(columns), width):
                corner, _ = kin.fk_many({j: feedback[:, k + i] for i, j in enumerate(self.joints)})
                bound = distances + np.linalg.norm(corner - tips, axis=1)
                near = bound > floor
                np.maximum(worst, np.where(near, 0.0, bound), out=worst)
                if near.any():
                    worst[near] = np.maximum(worst[near], distance_to_polyline(corner[near], points))
        return worst

    def by_stretch(self, worst: np.ndarray, durations: list[float], lead: int) -> np.ndarray:
        """The largest of ``worst`` (per servo sample, the motion starting at sample ``lead``)
        about each stretch of the given durations: from SETTLE_TIMES the slowest corner's
        settling time before it starts to as long after it stops (a stop's overshoot shows
        as the next stretch starts; the first and last stretches take the rest before and
        after the motion too)."""
        if not durations:
            return np.zeros(0)
        t = (np.arange(len(worst)) - lead) * self.period
        edges = np.concatenate(([0.0], np.cumsum(durations)))
        lo = np.searchsorted(t, edges[:-1] - self.settle)
        hi = np.searchsorted(t, edges[1:] + self.settle, side="right")
        lo[0], hi[-1] = 0, len(worst)
        return np.array([worst[a:b].max(initial=0.0) for a, b in zip(lo, hi)])


class Tried(Protocol):
    """A traverse planned on a share of the jerk and of the speed per stretch, with its worst
    predicted tip per stretch (m)."""

    jerk_shares: np.ndarray
    speed_shares: np.ndarray
    stretch_deviations: np.ndarray


T = TypeVar("T", bound=Tried)


def soften(attempt: Callable[[np.ndarray, np.ndarray], T], first: T, target: float) -> T:
    """The traverse with each stretch whose worst tip misses ``target`` on less of its jerk,
    from ``first``; ``attempt`` plans one on given shares of the jerk and of the speed per
    stretch. Each stretch on its own tries: one that misses steps down by next_jerk_share;
    one that holds with less than REFINED of the target, below a share that missed by more
    than BRACKET_RATIO, tries between the two (between); one whose softening gained nothing
    (a log-log slope below MIN_SLOPE: its miss is not its stops', the centripetal
    acceleration of an arc or of a 5-axis tool axis turning is) or reached MIN_JERK_SHARE
    steps no more, back at its first share if softening gained less than NO_GAIN in all
    (it would cost time for nothing), and from then on runs slower while it misses (the
    square root of target over miss, within SPEED_STEP, per try: an arc's miss goes with
    the square of the speed, a stop's with the speed) instead of the whole path. JERK_TRIES
    plans at most, the last on every stretch's largest jerk share that held; returns the
    last plan, which the caller slows down as a whole if a stretch still misses."""
    shares = first.jerk_shares.astype(float)
    speeds = first.speed_shares.astype(float)
    n = len(shares)
    missed: list[list[tuple[float, float]]] = [[] for _ in range(n)]  # (share, deviation) that missed
    held: list[tuple[float, float] | None] = [None] * n  # the largest share that held
    settled = np.zeros(n, bool)  # stretches that step no more
    done = first
    for attempt_left in range(JERK_TRIES - 1, -1, -1):
        before = np.concatenate((shares, speeds))
        for k in range(n):
            tip = float(done.stretch_deviations[k])
            if settled[k] or (tip <= target and held[k] is None and not missed[k]):
                if settled[k] and tip > target:  # its jerk is done with: slower
                    speeds[k] *= float(np.clip(math.sqrt(target / tip), *SPEED_STEP))
                continue  # else left alone: it holds on its own
            if tip > target:
                missed[k].append((float(shares[k]), tip))
                if held[k] is None and shares[k] <= MIN_JERK_SHARE:
                    settled[k] = True
                    speeds[k] *= float(np.clip(math.sqrt(target / tip), *SPEED_STEP))
                    continue
            elif held[k] is None or shares[k] > held[k][0]:
                held[k] = (float(shares[k]), tip)
            shares[k] = _next_share(missed[k], held[k], target, bool(attempt_left))
            if held[k] is None and len(missed[k]) > 1 and _slope(missed[k][-2], missed[k][-1]) < MIN_SLOPE:
                settled[k] = True
                if missed[k][-1][1] >= NO_GAIN * missed[k][0][1]:
                    shares[k] = missed[k][0][0]
                else:
                    shares[k] = missed[k][-1][0]
        if np.array_equal(np.concatenate((shares, speeds)), before):
            break
        done = attempt(shares.copy(), speeds.copy())
    return done


def _next_share(missed: list[tuple[float, float]], held: tuple[float, float] | None, target: float,
                refine: bool) -> float:
    """A stretch's next share: down from its misses while none held; between its smallest
    miss and its held share if ``refine`` and that share uses less than REFINED of the target
    and the two are more than BRACKET_RATIO apart; else the held share."""
    if held is None:
        return next_jerk_share(missed, target)
    below = min(missed, default=None)
    if refine and below is not None and held[1] < REFINED * target and below[0] > BRACKET_RATIO * held[0]:
        return between(below, held, target)
    return held[0]


def _slope(a: tuple[float, float], b: tuple[float, float]) -> float:
    """d log(deviation) / d log(share) from try a to try b (shares differ)."""
    return math.log(a[1] / b[1]) / math.log(a[0] / b[0]) if a[0] != b[0] and b[1] > 0.0 else 0.0


def between(missed: tuple[float, float], held: tuple[float, float], target: float) -> float:
    """The share between one that missed and one that held the target, (share, deviation)
    each (held's share smaller): where the worst tip is AIM of the target, interpolated in
    log-log, kept BETWEEN_RANGE of the way (in log share) from held's to missed's so that
    each try narrows them."""
    lo, hi = math.log(held[0]), math.log(missed[0])
    d_lo, d_hi = math.log(max(held[1], 1e-12)), math.log(missed[1])
    way = (math.log(AIM * target) - d_lo) / (d_hi - d_lo) if d_hi > d_lo else 0.5
    return math.exp(lo + float(np.clip(way, *BETWEEN_RANGE)) * (hi - lo))


def next_jerk_share(tries: list[tuple[float, float]], target: float) -> float:
    """The share of the jerk to try next on a stretch, from its tries so far
    ((share, worst corner deviation) in order): a secant step in log-log towards ``target``
    (JERK_SLOPE until two tries differ), within STEP_RANGE, not below MIN_JERK_SHARE."""
    share, deviation = tries[-1]
    slope = JERK_SLOPE
    if len(tries) > 1 and tries[-2][0] != share and tries[-2][1] > deviation > 0.0:
        slope = float(np.clip(math.log(tries[-2][1] / deviation) / math.log(tries[-2][0] / share), *SLOPE_RANGE))
    step = math.exp(math.log(target / deviation) / slope)
    return max(MIN_JERK_SHARE, share * float(np.clip(step, *STEP_RANGE)))
