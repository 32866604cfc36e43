"""A long job cut into segments that are planned one after another (block lookahead).

Planning a 10,000-hole drill job whole takes minutes and memory in proportion (the
drilling timing search runs the drive model over the whole cycle), and a controller
does not need it: like a CNC's block lookahead, the planner only has to stay ahead of
the machine. So a drill job of more than SEGMENT_HOLES holes, or a move program of
more than SEGMENT_MOVES moves, is planned as consecutive segments:

- the whole job is checked first (every hole and move target against the travel,
  through the kinematics), so a bad job is still rejected before anything moves;
- every segment starts with the axes at rest where the previous one left them and the
  spindle turning at the job's speed, and ends at rest with the spindle still turning:
  a drill segment ends above its last hole at R + clearance and holds there until the
  drive model's feedback has settled (the next segment's timing search starts from
  drives at rest); move programs already stop at the end of every move;
- events are numbered over the whole job (hole and move indices), and only the first
  segment carries ``job_start``, only the last ``job_end``.

The price is one exact stop per drill segment instead of the overlapped transition
between its last and the next segment's first hole: about 0.12 s per join on mill3
(test_segments.py bounds it at 0.2 s against the job planned whole).
"""
from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Iterator

from cnc_msgs_py.machine import SPINDLE, Machine

from .builder import PlanBuilder
from .headroom import plan_within_limits
from .drilling import DrillCycle
from .jobs import SERVO_PERIOD, drill_cycle, move_targets, plan_into, settle_time
from .kinematics import Kinematics
from .timeline import Event, Plan

SEGMENT_HOLES = 50  # holes per segment: ~3 s of planning before a goal is accepted
SEGMENT_MOVES = 500  # moves per segment of a move program
SETTLE_SHARE = 0.1  # of the X/Y tolerance: a drill segment ends once the feedback is this close
INDEX_KEYS = ("hole", "move")  # event fields numbered over the whole job


def segment_count(job: SimpleNamespace) -> int:
    """How many segments ``plan_segments`` cuts the job into."""
    if job.kind == "drill":
        return math.ceil(len(job.drill.holes) / SEGMENT_HOLES)
    if job.kind == "move":
        return math.ceil(len(job.move) / SEGMENT_MOVES)
    return 1


def plan_segments(job: SimpleNamespace, machine: Machine,
                  start_position: dict[str, float] | None = None) -> Iterator[Plan]:
    """The job's plan, segment by segment, each starting where the previous one ends.

    The whole job is checked before the first segment is yielded.

    Raises:
        JobError: from the check (before anything is yielded) or from planning a segment.
    """
    start = dict(start_position or {})
    count = segment_count(job)
    kin = Kinematics(machine, job.setup, job.tool)
    whole = _check_whole(job, machine, kin, start) if count > 1 else None
    if whole is not None and job.drill.order == "shortest":
        job = _in_order(job, whole.order)  # the whole job's tour, then cut into segments
    size = SEGMENT_HOLES if job.kind == "drill" else SEGMENT_MOVES
    speed = 0.0
    for k in range(count):
        first, last = k == 0, k == count - 1
        part = _part(job, k * size, (k + 1) * size)

        def segment(planned_on: Machine) -> Plan:
            builder = PlanBuilder(planned_on, start, speed)
            if first:
                builder.event(0.0, "job_start", kind=job.kind)
            if count == 1:
                return plan_into(part, planned_on, builder)
            plan_into(part, planned_on, builder, stop_spindle=False)
            if job.kind == "drill" and not last:
                _hold_until_settled(builder, whole, kin)
            plan = builder.build(stop_spindle=last)
            plan.events = [_renumbered(e, k * size) for e in plan.events]
            return plan

        plan = plan_within_limits(segment, machine, SERVO_PERIOD, job.kind)
        if last:
            plan.events.append(Event(plan.duration, "job_end"))
        speed = plan.timelines[SPINDLE].end_velocity
        start = plan.final_position()
        yield plan


def _check_whole(job: SimpleNamespace, machine: Machine, kin: Kinematics,
                 start: dict[str, float]) -> DrillCycle | None:
    """Every hole or target against the travel; a drill job's cycle, for its tolerances."""
    if job.kind == "drill":
        return drill_cycle(job, machine, kin, (start.get("x", 0.0), start.get("y", 0.0)))
    move_targets(job, machine, kin, start)
    return None


def _part(job: SimpleNamespace, lo: int, hi: int) -> SimpleNamespace:
    """The job with only its holes or moves lo..hi-1."""
    if job.kind == "drill":
        d = job.drill
        return SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{
            **vars(d), "holes": d.holes[lo:hi], "hole_planes": d.hole_planes[lo:hi]})})
    if job.kind == "move":
        return SimpleNamespace(**{**vars(job), "move": job.move[lo:hi]})
    return job


def _in_order(job: SimpleNamespace, order: tuple[int, ...]) -> SimpleNamespace:
    """The drill job with its holes in ``order``, drilled as given."""
    d = job.drill
    return SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{
        **vars(d), "holes": [d.holes[k] for k in order], "hole_planes": [d.hole_planes[k] for k in order],
        "order": "given"})})


def _hold_until_settled(builder: PlanBuilder, cycle: DrillCycle, kin: Kinematics) -> None:
    """Hold every axis at the segment's end until the simulated feedback is at rest."""
    t_end = builder.end_time()
    settle = settle_time(builder, kin, t_end, SETTLE_SHARE * cycle.xy_tolerance, cycle.servo_period)
    for joint in builder.machine.joint_names:
        if joint != SPINDLE and settle > 0.0:
            builder.timelines[joint].add_hold(t_end, settle)


def _renumbered(event: Event, offset: int) -> Event:
    data = {k: v + offset if k in INDEX_KEYS and isinstance(v, int) else v for k, v in event.data.items()}
    return Event(event.time, event.name, data)
