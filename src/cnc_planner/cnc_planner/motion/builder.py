"""Build a Plan move by move, in axis coordinates (SI), within one machine's limits."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_planner.motion.moves import LinearMove, RuckigMove, axis_limits, point_to_point, velocity_change
from cnc_planner.motion.timeline import Event, JointTimeline, Piece, Plan


class PlanBuilder:
    """Appends jerk-limited moves to per-joint timelines and records phase events.

    Moves start, by default, when every axis has finished its previous piece (a program
    runs its moves in sequence); pass ``start`` to overlap a move with the motion of
    other axes on purpose, as overlapped drilling does.
    """

    def __init__(self, machine: Machine, start_position: dict[str, float] | None = None,
                 spindle_speed: float = 0.0, events: bool = True):
        """``spindle_speed``: the spindle already turns at this speed (rad/s), as when a
        long job is planned segment by segment. ``events``: False for a scratch plan of a
        timing search, whose events nobody reads (a drill cycle marks ~15 per hole)."""
        self.machine = machine
        self.record_events = events
        start_position = start_position or {}
        self.timelines = {j: JointTimeline(start_position.get(j, 0.0), spindle_speed if j == SPINDLE else 0.0)
                          for j in machine.joint_names}
        self.events: list[Event] = []
        self.spindle_ready = 0.0  # feed moves wait until the spindle is at speed

    def position(self, joint: str) -> float:
        return self.timelines[joint].end_position

    def end_time(self, joints: list[str] | tuple[str, ...] | None = None) -> float:
        joints = joints or [j for j in self.machine.joint_names if j != SPINDLE]
        return max(self.timelines[j].end_time for j in joints)

    def free_from(self, joints: list[str] | tuple[str, ...]) -> float:
        """When a move of ``joints`` may start: every axis done with its previous piece,
        and these joints settled (a feed's carried settling overlaps only other joints)."""
        return max([self.end_time()] + [self.timelines[j].settled_time for j in joints])

    def event(self, time: float, name: str, **data: object) -> None:
        if self.record_events:
            self.events.append(Event(time, name, data))

    def _add(self, joints: list[str], start: float, move, ends: list[float], velocities=None) -> float:
        for dof, joint in enumerate(joints):
            velocity = 0.0 if velocities is None else velocities[dof]
            self.timelines[joint].add(Piece(start, move.duration, move.sampler(dof)), ends[dof], velocity)
        return start + move.duration

    def moving(self, target: dict[str, float]) -> list[str]:
        """The joints a rapid to ``target`` moves."""
        return [j for j in target if abs(target[j] - self.position(j)) > 1e-12]

    def rapid(self, target: dict[str, float], start: float | None = None) -> float:
        """Time-optimal positioning of the named axes (rest to rest); returns the end time."""
        joints = self.moving(target)
        begin = self.free_from(joints) if start is None else start
        if not joints:
            return begin
        move = point_to_point(
            [self.position(j) for j in joints],
            [target[j] for j in joints],
            [axis_limits(self.machine.axes[j]) for j in joints],
        )
        return self._add(joints, begin, move, [target[j] for j in joints])

    def rapid_move(self, target: dict[str, float]) -> RuckigMove | None:
        """The ruckig move a rapid to ``target`` would take (for timing decisions)."""
        joints = [j for j in target if abs(target[j] - self.position(j)) > 1e-12]
        if not joints:
            return None
        return point_to_point(
            [self.position(j) for j in joints],
            [target[j] for j in joints],
            [axis_limits(self.machine.axes[j]) for j in joints],
        )

    def linear(self, target: dict[str, float], feed: float, start: float | None = None) -> float:
        """Straight move at ``feed`` (m/s along the path); returns the end time."""
        joints = list(target)
        p0 = np.array([self.position(j) for j in joints])
        p1 = np.array([target[j] for j in joints])
        begin = max(self.free_from(joints), self.spindle_ready) if start is None else start
        if np.linalg.norm(p1 - p0) <= 1e-12:
            return begin
        move = LinearMove(p0, p1, [axis_limits(self.machine.axes[j]) for j in joints], feed)
        return self._add(joints, begin, move, list(p1))

    def spindle(self, speed: float, start: float | None = None) -> float:
        """Ramp the spindle to ``speed`` (rad/s, signed); returns when it is reached."""
        timeline = self.timelines[SPINDLE]
        begin = timeline.end_time if start is None else start
        if abs(timeline.end_velocity - speed) < 1e-12:
            return begin
        p0 = timeline.position_at(begin)
        move = velocity_change([p0], [timeline.end_velocity], [0.0], [speed],
                               [axis_limits(self.machine.axes[SPINDLE])])
        end_position = float(move.trajectory.at_time(move.duration)[0][0])
        timeline.add(Piece(begin, move.duration, move.sampler(0)), end_position, speed)
        self.spindle_ready = begin + move.duration
        return self.spindle_ready

    def spindle_after(self, speed: float) -> float:
        """Change the spindle's speed once the axes' moves so far are done (S between a
        program's operations, a new rpm at constant surface speed): ``spindle`` alone ramps
        from the spindle's last change, which may lie inside moves planned at the old speed."""
        return self.spindle(speed, start=max(self.end_time(), self.timelines[SPINDLE].end_time))

    def build(self, stop_spindle: bool = True) -> Plan:
        """The finished plan; the spindle is stopped at the end if still turning, unless
        another segment of the same job follows. Corrections still carried (a vibrated
        feed's settling) hold their joints until they have settled."""
        for timeline in self.timelines.values():
            timeline.flush()
        if stop_spindle and SPINDLE in self.timelines and abs(self.timelines[SPINDLE].end_velocity) > 0.0:
            self.spindle(0.0, start=max(self.end_time(), self.timelines[SPINDLE].end_time))
        self.events.sort(key=lambda e: e.time)
        return Plan(self.machine.joint_names, self.timelines, self.events)
