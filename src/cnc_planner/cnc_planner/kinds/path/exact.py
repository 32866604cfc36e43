"""The path's traverse made exact on feedback: every joint's command pre-compensated
against the drive model, and the feed lowered where that still cannot hold the tolerance.

A drive lags its command (velocity-loop lag, position-loop error); on a 5-axis path the
rotary axes' lag swings the tip off the programmed line by far more than the chord
tolerance, since the lever from the rotary axis to the tip multiplies it. So the whole
traverse (every stretch and the stops between them) is sampled on the servo grid, at
rest for LEAD_S before it and COMPENSATION_TAIL after, and one correction per joint is
learned against the drive model (motion.compensation.learned_command), as drilling and
threading do for their linear axes. The commanded tip then leads the line and the
feedback follows it.

The prediction is the contract: the drive model's feedback to the compensated command,
through forward kinematics, must keep the tip within the chord tolerance of the
programmed lines. Where it does not (a slow drive, a lever too long, a coarse encoder),
the feed is lowered by SLOWDOWN and the traverse planned again, down to MIN_FEED_SHARE of
the job's feed; below that the job is refused, naming what the tip would miss by.
The same command must also hold on every drive inside the description's tolerance
(kinds.path.corners): where the worst of them leaves TOLERANCE_SHARE of it about a
stretch, that stretch is planned again on less of its jerk or, where that does not help,
slower; where that still does not do, the whole traverse at a lower feed (the square
root of target over miss: a stop's miss goes with the speed, an arc's with its square).

The compensated command must stay within the axes' limits as described (the bridge's):
where it does not (the traverse uses an axis's full velocity or acceleration, the
correction adds to it), the plain command is taken if its predicted tip holds the
tolerance (stiff drives need no correction); else the stretches are planned again slower
and on HEADROOM of the limits they use, step by step.
The plan check (motion.plan_check, through motion.derating) then holds the whole plan to
the bridge's contract, lowering the machine's limits if it must.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm, to_mm_per_min
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinematics import Kinematics, SampledPath
from cnc_planner.motion.compensation import COMPENSATION_TAIL, compensation_band, learned_command

from .corners import NEAR_SHARE, TOLERANCE_SHARE, ToleranceCorners, soften
from .polyline import distance_to_polyline

LEAD_S = 0.1  # s at rest before the traverse: the compensated command leads the motion by up to this
SLOWDOWN = 0.7  # feed factor per try where the predicted tip misses the tolerance
MIN_FEED_SHARE = 0.05  # of the job's feed: slower than this, the job is refused
CHORD_SHARE = 0.8  # of the chord tolerance the waypoints may use; the rest is the drives' residual
HEADROOM = 0.9  # factor on the share of the limits the stretches use, per try where the command breaks them
MAX_TRIES = 12  # feed and headroom steps together
MAX_TRAVERSE_S = 600.0  # s: a path the drives follow only slower than this is refused


@dataclass(frozen=True)
class ExactTraverse:
    """The compensated traverse: commands on the servo grid from ``start`` (at rest at the
    first pose), the tip moving from ``start + lead`` for ``motion`` seconds, the command
    settled by ``duration``; ``feed`` the feed it runs at (m/s) and ``deviation`` the
    predicted feedback tip's largest distance from the programmed lines (m) on the described
    drives."""

    start: float
    lead: float
    motion: float
    period: float
    command: np.ndarray  # (3, n, joints): positions, velocities, accelerations
    feed: float
    deviation: float
    stops: int
    waypoints: int
    corner_deviation: float  # m: the same on the worst drive, described or inside the tolerance (kinds.path.corners)
    stretch_deviations: np.ndarray  # m: that about each stretch between stops (ToleranceCorners.by_stretch)
    jerk_shares: np.ndarray  # of its jerk each stretch was planned on
    speed_shares: np.ndarray  # of its speed (the feed, or the axes' speed where that binds) each stretch runs at
    excess: float  # how far the compensated command went beyond the axes' limits (ratio; the plain one is taken above 1)

    @property
    def jerk_share(self) -> float:
        """The least share of the jerk a stretch runs on."""
        return float(self.jerk_shares.min(initial=1.0))

    @property
    def softened(self) -> int:
        """How many stretches run on less than their jerk or their speed."""
        return int(np.count_nonzero((self.jerk_shares < 1.0) | (self.speed_shares < 1.0)))

    @property
    def speed_share(self) -> float:
        """The least share of its speed a stretch runs at."""
        return float(self.speed_shares.min(initial=1.0))

    @property
    def duration(self) -> float:
        return (self.command.shape[1] - 1) * self.period

    def sampler(self, dof: int):
        grid = np.arange(self.command.shape[1]) * self.period

        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return tuple(np.interp(t, grid, x[:, dof]) for x in self.command)  # type: ignore[return-value]
        return sample


def exact_traverse(kin: Kinematics, machine: Machine, joints: list[str], points: np.ndarray,
                   tolerance: float, feed: float, start: float, period: float,
                   sample: Callable[[float], SampledPath],
                   sections: Callable[[SampledPath, float], list]) -> ExactTraverse:
    """The traverse from ``start`` (the axes at rest on the first pose) compensated against
    the drive model, at the job's ``feed`` or, where the predicted tip misses the
    ``tolerance``, at the highest feed tried (by SLOWDOWN) that holds it; the stretches
    about which a drive inside the tolerance misses TOLERANCE_SHARE of it on less of
    their jerk (kinds.path.corners).

    ``sample`` gives the waypoints at a feed, ``sections`` the stretches of waypoints on a
    share of the limits (kinds.path.planning.traverse_sections).

    Raises:
        JobError: ``path.feed``: no feed down to MIN_FEED_SHARE of the job's holds the
            tolerance on the drive model and its tolerance's corners (the miss named), or
            no headroom keeps the compensated command within the limits.
    """
    drive = DriveModel(machine, period, tuple(joints))
    band = min((compensation_band(DriveModel(machine, period, (j,)), machine.drive_axes[j].max_acceleration)
                for j in joints), key=lambda b: b[1])
    # the limits the bridge holds the command to: the machine as described, not as derated
    v_max = np.array([machine.drive_axes[j].max_velocity for j in joints])
    a_max = np.array([machine.drive_axes[j].max_acceleration for j in joints])
    corners = ToleranceCorners(machine, joints, period)
    target = TOLERANCE_SHARE * tolerance
    tail = math.ceil(COMPENSATION_TAIL / period)

    def attempt(tried: float, share: float, jerk: np.ndarray | None = None, speed: np.ndarray | None = None
                ) -> ExactTraverse:
        """The traverse at a feed, on a share of the limits and of that a share of the jerk
        and of the speed per stretch (all of them where None), compensated and predicted on
        the described drives and (where they hold) the corners."""
        path = sample(tried)
        stretches = sections(path, share)
        jerks = np.ones(len(stretches)) if jerk is None else jerk
        speeds = np.ones(len(stretches)) if speed is None else speed
        stretches = [s if j == v == 1.0 else s.softened(j, v) for s, j, v in zip(stretches, jerks, speeds)]
        p, v, a, lead, motion = _reference(stretches, path, joints, period)
        if motion > MAX_TRAVERSE_S:
            raise JobError("path.feed", f"the drives follow the path within chord_tolerance {to_mm(tolerance):g} mm "
                                        f"only at {to_mm_per_min(tried):.0f} mm/min or slower: it would take "
                                        f"{motion:.0f} s, more than {MAX_TRAVERSE_S:.0f} s")
        correction = learned_command(drive, p, v, a, lead // 2, len(p) - 1 - tail, period, band)
        command = np.stack((p, v, a))
        command[:, :correction.shape[1]] += correction
        excess = _excess(command, v_max, a_max, period)
        if excess > 1.0:  # the plain command may do (stiff drives); else slower, on less of the limits
            command = np.stack((p, v, a))
        tips, distances = _deviation(kin, drive, command, joints, points)
        deviation = float(distances.max())
        if corners and deviation <= tolerance:
            distances = corners.tip_deviations(kin, command, points, tips, distances, NEAR_SHARE * target)
        by_stretch = corners.by_stretch(distances, [s.duration for s in stretches], lead)
        return ExactTraverse(start, lead * period, motion, period, command, tried, deviation,
                             max(len(stretches) - 1, 0), len(path.param), float(distances.max()), by_stretch,
                             jerks, speeds, excess)

    tried, share, before = feed, 1.0, math.inf
    for _ in range(MAX_TRIES):
        done = attempt(tried, share)
        if corners and done.deviation <= tolerance and done.corner_deviation > target:
            # only a drive inside the tolerance misses: softer stops at this feed (the lambda runs here, now)
            done = soften(lambda jerks, speeds: attempt(tried, share, jerks, speeds), done, target)  # noqa: B023
        deviation, worst, excess = done.deviation, done.corner_deviation, done.excess
        if deviation <= tolerance and worst <= (target if corners else tolerance):
            return done
        if excess > 1.0:
            share *= HEADROOM
            factor = min(SLOWDOWN, 1.0 / math.sqrt(excess))
        elif deviation > tolerance:
            factor = min(SLOWDOWN, tolerance / deviation)
        else:  # a corner misses on the softest stops: slower, the turns in place too (at the axes' speed);
            # an arc's miss goes with the square of the speed, a stop's with the speed: the root of the two
            factor = min(SLOWDOWN, math.sqrt(target / worst))
            share *= factor
        # a correction that does not shrink when slower is the drive's, not the speed's: refuse
        stuck, before = excess > 1.0 and excess > 0.9 * before, excess
        if tried * factor < MIN_FEED_SHARE * feed or stuck:
            why = (f"the compensated command would break the axes' limits ({excess:.3g} x)" if excess > 1.0
                   else f"the tip would miss by {to_mm(worst) * 1000:.1f} um on the drive model"
                   + ("" if deviation > tolerance else " at a corner of its tolerance"))
            raise JobError("path.feed", f"the drives cannot keep the tip within chord_tolerance "
                                        f"{to_mm(tolerance):g} mm even at {to_mm_per_min(tried):.0f} mm/min: {why}")
        tried *= factor
    raise JobError("path.feed", f"no feed down to {to_mm_per_min(tried):.0f} mm/min keeps the tip within "
                                f"chord_tolerance {to_mm(tolerance):g} mm on the drive model and the corners of "
                                f"its tolerance")


def _deviation(kin: Kinematics, drive: DriveModel, command: np.ndarray, joints: list[str],
               points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The drive model's tips (n, 3) and their distances (m) from the programmed lines."""
    feedback = drive.simulate(*command)[0]
    tips, _ = kin.fk_many({j: feedback[:, i] for i, j in enumerate(joints)})
    return tips, distance_to_polyline(tips, points)


def _excess(command: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, period: float) -> float:
    """How far the command's velocity and acceleration go beyond the limits, as sampled and by
    finite differences of its positions (as the bridge streams them): the largest ratio."""
    p, v, a = command
    fd_v = np.abs(np.diff(p, axis=0)) / period
    fd_a = np.abs(np.diff(p, 2, axis=0)) / period**2
    return float(max(np.max(np.abs(v) / v_max), np.max(fd_v / v_max),
                     np.max(np.abs(a) / a_max), np.max(fd_a / a_max)))


def _reference(stretches: list, path: SampledPath, joints: list[str], period: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, float]:
    """The plain traverse on the servo grid: at rest on the first pose for LEAD_S, the
    stretches one after the other, at rest on the last pose for COMPENSATION_TAIL.
    Returns positions, velocities, accelerations (n, joints), the lead (samples) and the
    motion's duration (s)."""
    lead = math.ceil(LEAD_S / period)
    motion = sum(s.duration for s in stretches)
    n = lead + math.ceil(motion / period - 1e-9) + math.ceil(COMPENSATION_TAIL / period) + 1
    t = (np.arange(n) - lead) * period
    first = np.array([path.joints[j][0] for j in joints])
    last = np.array([path.joints[j][-1] for j in joints])
    p = np.where((t < 0)[:, None], first, last)
    v, a = np.zeros_like(p), np.zeros_like(p)
    t0 = 0.0
    for stretch in stretches:  # t is sorted: its instants in [t0, t0 + duration) are a range
        lo, hi = np.searchsorted(t, [t0, t0 + stretch.duration], side="left").tolist()
        if hi > lo:
            p[lo:hi], v[lo:hi], a[lo:hi] = stretch.sample_all(t[lo:hi] - t0)
        t0 += stretch.duration
    return p, v, a, lead, motion
