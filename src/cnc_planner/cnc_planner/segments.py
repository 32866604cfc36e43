"""A long job cut into segments that are planned one after another (block lookahead).

Planning a 10,000-hole drill job whole takes minutes and memory in proportion (the
drilling timing search runs the drive model over the whole cycle), and a controller
does not need it: like a CNC's block lookahead, the planner only has to stay ahead of
the machine. So a job of a kind that can be segmented (``JobKind.segmenting``: a drill job
of more than 50 holes, a move program of more than 500 moves) is planned as consecutive
segments:

- the whole job is checked first (every hole and move target against the travel,
  through the kinematics), so a bad job is still rejected before anything moves;
- every segment starts with the axes at rest where the previous one left them and the
  spindle turning at the job's speed, and ends at rest with the spindle still turning:
  a drill segment ends above its last hole at R + clearance and holds there until the
  drive model's feedback has settled (the kind's ``settle``: the next segment's timing
  search starts from drives at rest); move programs already stop at the end of every move;
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

from cnc_planner.kinds import KINDS
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.derating import plan_within_limits
from cnc_planner.motion.timeline import Event, Plan
from cnc_planner.planning import plan_into


def segment_count(job: SimpleNamespace) -> int:
    """How many segments ``plan_segments`` cuts the job into."""
    cut = KINDS[job.kind].segmenting
    return 1 if cut is None else math.ceil(cut.count(job) / cut.size)


def plan_segments(job: SimpleNamespace, machine: Machine, start_position: dict[str, float] | None = None,
                  spindle_speed: float = 0.0) -> Iterator[Plan]:
    """The job's plan, segment by segment, each starting where the previous one ends; the
    first with the spindle turning at ``spindle_speed`` (rad/s: a held program resumed).

    The whole job is checked before the first segment is yielded.

    Raises:
        JobError: from the check (before anything is yielded) or from planning a segment.
    """
    start = dict(start_position or {})
    count = segment_count(job)
    cut = KINDS[job.kind].segmenting
    kin = Kinematics(machine, job.setup, job.tool)
    whole = None
    if count > 1:
        whole = cut.check_whole(job, machine, kin, start)
        if cut.prepare is not None:
            job = cut.prepare(job, whole)
    speed = spindle_speed
    for k in range(count):
        first, last = k == 0, k == count - 1
        part = job if cut is None else cut.part(job, k * cut.size, (k + 1) * cut.size)

        def segment(planned_on: Machine) -> Plan:
            builder = PlanBuilder(planned_on, start, speed)
            if first:
                builder.event(0.0, "job_start", kind=job.kind)
            if count == 1:
                return plan_into(part, planned_on, builder)
            plan_into(part, planned_on, builder, stop_spindle=False)
            if cut.settle is not None and not last:
                cut.settle(builder, whole, kin)
            plan = builder.build(stop_spindle=last)
            plan.events = [_renumbered(e, cut.index, k * cut.size) for e in plan.events]
            return plan

        plan = plan_within_limits(segment, machine, SERVO_PERIOD, job.kind)
        if last:
            plan.events.append(Event(plan.duration, "job_end"))
        speed = plan.timelines[SPINDLE].end_velocity
        start = plan.final_position()
        yield plan


def _renumbered(event: Event, index: str, offset: int) -> Event:
    """The event with its item number (``index``: hole, move) counted over the whole job."""
    data = {k: v + offset if k == index and isinstance(v, int) else v for k, v in event.data.items()}
    return Event(event.time, event.name, data)
