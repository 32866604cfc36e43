"""The ``path`` job: tool tip points (and tool axes) in program coordinates at a feed.

The kinematic chain samples the programmed lines into axis-space waypoints that keep
the tip within the chord tolerance (Kinematics.sample_path). Here they become motion:

1. a rapid (ruckig, every joint time-synchronised) from where the machine stands to
   the first pose, and the wait until the drive model's tip has settled there;
2. the traverse: the joints move linearly between waypoints as functions of one path
   parameter ``s``, the cumulative segment time at the feed (ds/dt = 1 is the feed,
   or the slowest axis's max_velocity on segments where that binds). ``s`` follows a
   jerk-limited ruckig profile from rest to rest. On segment k every joint moves as
   q = q_k + m_k (s - s_k) with slope m_k = dq / ds, so its velocity is m_k s', its
   acceleration m_k s'' and its jerk m_k s''': the limits of ``s`` are the joints'
   own limits divided by their largest slope.

Where the slope changes at a waypoint the joint velocity steps by |dm| s' within one
interpolation period. Those steps get at most CORNER_SHARE of each axis's
acceleration (the rest is left for s''), which caps the speed of ``s``. Waypoints
whose steps would slow the traverse below the feed are exact stops unless merging
the stretches around them into one slower stretch is quicker (ruckig decides): a
corner of a polyline stops, C turning on the spot in small steps runs through slower.
The traverse is one ruckig profile per stretch between stops; a path without corners,
such as a tilting 5-axis line, is a single profile. The whole traverse is then
compensated against the drive model and slowed where the predicted tip would still leave
the chord tolerance (kinds.path.exact): the tip is exact on feedback, not only on command.
"""
from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError

from .exact import CHORD_SHARE, exact_traverse
from cnc_planner.kinematics import Kinematics, SampledPath
from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import Limits, RuckigMove, point_to_point
from cnc_planner.motion.settle import settle_time
from cnc_planner.motion.timeline import Piece


INTERPOLATION_PERIOD = 1e-3  # s between setpoints (config/planner.yaml): velocity steps happen over it
CORNER_SHARE = 0.5  # of an axis's max_acceleration that the velocity steps at waypoints may take
SETTLE_SHARE = 0.1  # of the chord tolerance: the tip on feedback this close to the first pose before the path
SETTLE_FLOOR = 5e-7  # m: but no closer than this: the encoders' counts keep the drives dithering about as much


def plan_path(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Rapid to the first pose, then traverse the sampled path (see the module doc).

    Raises:
        KinematicsError: a pose is unreachable (``path.points[i]`` and the axis named).
        JobError: a block this kind cannot take.
    """
    p = job.path
    if job.vibration is not None:
        raise JobError("vibration", "not supported on path jobs")
    joints = list(kin.joints)
    if SPINDLE in joints and job.spindle_rpm > 0:
        raise JobError("spindle_rpm", f"a path on layout {machine.layout} positions the spindle as its "
                                      "C axis: leave spindle_rpm out (0)")
    previous = {j: builder.position(j) for j in joints}
    points = np.asarray(p.points, float)
    tool_axes = None if p.tool_axis is None else np.asarray(p.tool_axis, float)

    def sample(feed: float) -> SampledPath:
        return kin.sample_path(points, tool_axes, feed, CHORD_SHARE * p.chord_tolerance, previous, field="path")

    path = sample(p.feed)
    if job.spindle_rpm > 0:
        builder.spindle(job.spindle_rpm)
    arrived = builder.rapid({j: float(path.joints[j][0]) for j in joints})
    # the compensation starts from drives at rest on the first pose: wait until the tip is there
    arrived += settle_time(builder, kin, arrived, max(SETTLE_SHARE * p.chord_tolerance, SETTLE_FLOOR), SERVO_PERIOD)
    start = SERVO_PERIOD * math.ceil(max(arrived, builder.spindle_ready) / SERVO_PERIOD - 1e-9)
    exact = exact_traverse(kin, machine, joints, points, p.chord_tolerance, p.feed, start, SERVO_PERIOD, sample,
                           lambda sampled, share: traverse_sections(sampled, joints, machine, share=share))
    t = start + exact.lead
    builder.event(t, "path_start", points=len(p.points), waypoints=exact.waypoints, stops=exact.stops,
                  feed=p.feed, planned_feed=exact.feed, chord_tolerance=p.chord_tolerance,
                  predicted_tip_deviation=exact.deviation, corner_tip_deviation=exact.corner_deviation,
                  jerk_share=exact.jerk_share, speed_share=exact.speed_share,
                  softened_stretches=exact.softened)
    for dof, joint in enumerate(joints):
        builder.timelines[joint].add(Piece(start, exact.duration, exact.sampler(dof)), float(path.joints[joint][-1]))
    builder.event(t + exact.motion, "path_end", chord_tolerance=p.chord_tolerance, duration=exact.motion)


class Traverse:
    """One stretch of the path from rest to rest: joints piecewise linear in ``s``,
    ``s`` a 1-DOF ruckig profile (from knots[0] to knots[-1])."""

    def __init__(self, knots: np.ndarray, q: np.ndarray, limits: Limits) -> None:
        self.knots = knots
        self.q = q
        self.slopes = np.diff(q, axis=0) / np.diff(knots)[:, None]
        self.limits = limits
        self.profile: RuckigMove = point_to_point([float(knots[0])], [float(knots[-1])], [limits])
        self._cache: tuple[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None

    @property
    def duration(self) -> float:
        return self.profile.duration

    def sample_all(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations (len(t), joints) at local times t."""
        key = (len(t), float(t[0]), float(t[-1])) if len(t) else (0, 0.0, 0.0)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        s, ds, dds = (x[:, 0] for x in self.profile.sample_all(t))
        k = np.clip(np.searchsorted(self.knots, s, side="right") - 1, 0, len(self.slopes) - 1)
        m = self.slopes[k]
        out = (self.q[k] + m * (s - self.knots[k])[:, None], m * ds[:, None], m * dds[:, None])
        self._cache = (key, out)
        return out

    def softened(self, jerk_share: float, speed_share: float = 1.0) -> Traverse:
        """The stretch on a share of its jerk and of its speed: a softer start and stop and
        slower turns, which a drive unlike its description overshoots less (kinds.path.corners)."""
        return Traverse(self.knots, self.q, replace(self.limits, velocity=self.limits.velocity * speed_share,
                                                    jerk=self.limits.jerk * jerk_share))

    def sampler(self, dof: int):
        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            p, v, a = self.sample_all(t)
            return p[:, dof], v[:, dof], a[:, dof]
        return sample


def traverse_sections(path: SampledPath, joints: list[str], machine: Machine,
                      period: float = INTERPOLATION_PERIOD, share: float = 1.0) -> list[Traverse]:
    """Split the sampled path at its exact stops and give each stretch limits for ``s``
    that keep every joint within its velocity, acceleration and jerk on every segment,
    the velocity steps at the waypoints included (over one interpolation ``period``).

    Every waypoint whose velocity steps would slow the traverse below the feed starts
    as a stop; then, from the start, neighbouring stretches are merged (the stop between
    them dropped, the merged stretch running at the lower speed) wherever ruckig says
    that is quicker: an isolated corner stays a stop, a run of small steps (C turning
    on the spot, a finely sampled curve at a high feed) becomes one slower stretch.
    ``share`` of each axis's velocity, acceleration and jerk is the stretches' to use:
    the rest is room for the drive compensation (kinds.path.exact).
    """
    q = np.stack([path.joints[j] for j in joints], axis=1)
    durations = np.asarray(path.durations, float)
    # Segments without any motion take no time (a repeated pose): drop their end knot.
    q = q[np.concatenate(([True], durations > 0.0))]
    knots = np.concatenate(([0.0], np.cumsum(durations[durations > 0.0])))
    if len(knots) < 2:
        return []
    axes = [machine.axes[j] for j in joints]
    v_max = share * np.array([a.max_velocity for a in axes])
    a_max = share * np.array([a.max_acceleration for a in axes])
    j_max = share * np.array([a.max_jerk for a in axes])
    slopes = np.abs(np.diff(q, axis=0) / np.diff(knots)[:, None])
    steps = np.abs(np.diff(np.diff(q, axis=0) / np.diff(knots)[:, None], axis=0))  # at s' = 1, inner knots
    with np.errstate(divide="ignore"):
        corner_speed = np.min(np.where(steps > 0, CORNER_SHARE * a_max * period / steps, np.inf), axis=1)

    def limits(slope: np.ndarray, step: np.ndarray, corner: float) -> Limits:
        moving = slope > 0
        speed = min(1.0, float(np.min(v_max[moving] / slope[moving])), corner)
        accel = (a_max - step * speed / period)[moving] / slope[moving]
        return Limits(speed, float(np.min(accel)), float(np.min(j_max[moving] / slope[moving])))

    def duration(lo: int, hi: int, lim: Limits) -> float:
        return point_to_point([float(knots[lo])], [float(knots[hi])], [lim]).duration

    bounds = np.concatenate(([0], np.flatnonzero(corner_speed < 1.0) + 1, [len(knots) - 1]))
    zero = np.zeros(len(joints))
    merged = []  # (lo, hi, max slope, max inner step, min inner corner speed, limits, duration)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        slope, step, corner = slopes[lo:hi].max(axis=0), zero, np.inf
        if hi - lo > 1:
            step, corner = steps[lo:hi - 1].max(axis=0), float(corner_speed[lo:hi - 1].min())
        lim = limits(slope, step, corner)
        section = (lo, hi, slope, step, corner, lim, duration(lo, hi, lim))
        if merged:
            plo, _, pslope, pstep, pcorner, _, ptime = merged[-1]
            jslope = np.maximum(pslope, slope)
            jstep = np.maximum(np.maximum(pstep, step), steps[lo - 1])
            jcorner = min(pcorner, corner, float(corner_speed[lo - 1]))
            jlim = limits(jslope, jstep, jcorner)
            jtime = duration(plo, hi, jlim)
            if jtime < ptime + section[-1]:
                merged[-1] = (plo, hi, jslope, jstep, jcorner, jlim, jtime)
                continue
        merged.append(section)
    return [Traverse(knots[lo:hi + 1], q[lo:hi + 1], lim) for lo, hi, *_, lim, _ in merged]
