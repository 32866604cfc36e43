"""Program pauses (M0, M1): where a program holds, what streams while it does, and the
rest of it planned again from where the machine stands once it is resumed.

A program's plan (kinds.program.mark_hold) marks each hold point with a HOLD event between
two operations, once every joint has settled there: offline (cnc-plan, prediction) a hold is
that zero-length mark. Over topics the executive cuts the stream at the mark and goes on
with a HoldStream: every axis where the operation before left it, the spindle turning on as
it was (LinuxCNC's PROGRAM_STOP leaves the spindle and coolant alone; a program stops the
spindle with M5 before M0), setpoints every period, a controlled state and not silence, so
the drives keep their position and a cancel stops from there like any stop. A resume
(job_resume) releases the hold ``planning_lookahead`` (2 s) after it arrives, its setpoints
sent at once, so that the drives hold on while the rest of the program is planned from
the hold's state there (the spindle's angle moved on
while it turned) and numbered as in the whole program: operation and hold indices,
events stamped from the resume.

Plain Python: the executive holds the state, the node only wires job_resume to it.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace
from typing import Iterator

import numpy as np

from cnc_msgs_py.gcode.translate import Operations
from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import NS

from cnc_planner.kinds.program import HOLD, OPERATION
from cnc_planner.motion.timeline import Event, JointTimeline, Plan
from cnc_planner.segments import plan_segments
from cnc_planner.streaming import SetpointStream

RESUME = "resume"  # job_events: the rest of a held program starts here (line, code of the hold)


def held_reason(job_id: str, event: dict) -> str:
    """What a held status says: where, and how to resume."""
    return (f"held at line {event['line']} ({event['code']}): resume by publishing '{job_id}' on job_resume "
            f"(cnc-submit --resume {job_id}), or cancel it")


class HoldStream(SetpointStream):
    """A held program's setpoints from ``start_ns``: the axes at ``position``, the spindle
    turning on at ``spindle_speed`` (rad/s), until released (or stopped: a cancel)."""

    def __init__(self, joints: tuple[str, ...], position: dict[str, float], spindle_speed: float,
                 start_ns: int, period_ns: int, chunk_points: int) -> None:
        timelines = {j: JointTimeline(position[j], spindle_speed if j == SPINDLE else 0.0) for j in joints}
        super().__init__(Plan(joints, timelines, []), start_ns, period_ns, chunk_points)
        self.rest_at_end = False

    @property
    def last_index(self) -> int | None:
        return self._stop_index  # open until released or stopped

    def _bound(self) -> int:
        return max(self.next_index, self._stop_index or 0)

    def release(self, t_ns: int) -> int:
        """End the hold at the grid instant at or after ``t_ns`` (never before a point already
        served); returns the time of its last point."""
        index = max(self.next_index - 1, int(np.ceil((t_ns - self.start_ns) / self.period_ns)))
        self._stop_index = index
        return self.start_ns + index * self.period_ns


def state_after(stream: SetpointStream) -> tuple[dict[str, float], float, int]:
    """Where a stream that ends moving on as it was (cut or released) leaves the joints one
    period after its last point: (positions, spindle speed, that instant in ns). Axes are at
    rest there; the spindle coasts on at its speed."""
    end_ns = stream.end_ns + stream.period_ns
    p, v, _ = stream.plan.sample(np.array([stream.plan_time(stream.end_ns)]))
    joints = stream.plan.joints
    speed = float(v[0][joints.index(SPINDLE)]) if SPINDLE in joints else 0.0
    position = {j: float(p[0][k]) for k, j in enumerate(joints)}
    if SPINDLE in position:
        position[SPINDLE] += speed * stream.period_ns / NS
    return position, speed, end_ns


def hold_after(stream: SetpointStream, chunk_points: int) -> HoldStream:
    """The hold that continues a stream cut at its hold mark, contiguous on the grid."""
    position, speed, start_ns = state_after(stream)
    return HoldStream(stream.plan.joints, position, speed, start_ns, stream.period_ns, chunk_points)


def rest_of(job: SimpleNamespace, operations: Operations, event: dict) -> SimpleNamespace:
    """The program job from hold point ``event`` (a HOLD mark's data) on: its operations from
    the one after the hold, and the holds after this one."""
    before, index = event["before"], event["hold"]
    rest = Operations(operations[before:], [replace(h, before=h.before - before) for h in operations.holds[index + 1:]])
    program = SimpleNamespace(**{**vars(job.program), "operations": rest, "start_from_machine": False})
    return SimpleNamespace(**{**vars(job), "program": program})


def resumed_segments(job: SimpleNamespace, operations: Operations, event: dict, machine: Machine,
                     start: dict[str, float], spindle_speed: float) -> Iterator[Plan]:
    """The rest of a held program, planned from ``start`` with the spindle at ``spindle_speed``,
    its marks numbered as in the whole program; a RESUME mark at its start, no job_start."""
    before, index = event["before"], event["hold"]
    for k, plan in enumerate(plan_segments(rest_of(job, operations, event), machine, start, spindle_speed)):
        events = [_renumbered(e, before, index + 1) for e in plan.events if e.name != "job_start"]
        if k == 0:
            events.insert(0, Event(0.0, RESUME, {"line": event["line"], "code": event["code"]}))
        plan.events = events
        yield plan


def _renumbered(event: Event, operations: int, holds: int) -> Event:
    if event.name == OPERATION:
        return Event(event.time, event.name, {**event.data, "index": event.data["index"] + operations})
    if event.name == HOLD:
        return Event(event.time, event.name, {**event.data, "hold": event.data["hold"] + holds,
                                              "before": event.data["before"] + operations})
    return event
