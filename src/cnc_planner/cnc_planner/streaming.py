"""Cut a Plan into contiguous setpoint chunks on the interpolation grid, on demand.

Times are integer nanoseconds of ROS time (sim or wall), so chunk stamps stay exact
however long a job runs. A controlled stop replaces the rest of the plan from a given
instant with a ruckig stop from the state the plan has there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.units import NS

from cnc_planner.motion.moves import axis_limits, velocity_change
from cnc_planner.lookahead import JobPlan
from cnc_planner.motion.timeline import JointTimeline, Piece, Plan


@dataclass
class Chunk:
    """Setpoints of consecutive grid instants: stamp of the first, then every period."""

    stamp_ns: int
    period_ns: int
    joints: tuple[str, ...]
    positions: np.ndarray  # (n, joints)
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def end_ns(self) -> int:
        """Time of the last point."""
        return self.stamp_ns + (len(self.positions) - 1) * self.period_ns


class SetpointStream:
    """Serves a job's plan as chunks, starting at absolute time ``start_ns``.

    Every chunk but the job's last is full: when planning has not reached the chunk's
    end yet, serving waits for it (see lookahead.JobPlan).
    """

    def __init__(self, plan: JobPlan | Plan, start_ns: int, period_ns: int, chunk_points: int):
        self.plan = plan if isinstance(plan, JobPlan) else JobPlan.of(plan, period_ns / NS)
        self.start_ns = start_ns
        self.period_ns = period_ns
        self.chunk_points = chunk_points
        self.next_index = 0  # grid index (from start_ns) of the next point to serve
        self._stop_index: int | None = None
        self.stopping = False
        self.rest_at_end = True  # the last point is at rest (not where a held program's stream is cut)

    @property
    def last_index(self) -> int | None:
        """Grid index of the job's last point; None while the plan is still growing."""
        if self._stop_index is not None:
            return self._stop_index
        return self._index(self.plan.duration) if self.plan.complete else None

    @property
    def end_ns(self) -> int:
        """When the job ends (the planned part's end while planning goes on)."""
        last = self.last_index
        return self.start_ns + (self._index(self.plan.duration) if last is None else last) * self.period_ns

    @property
    def served_until_ns(self) -> int:
        """Time of the last point served so far."""
        return self.start_ns + (self.next_index - 1) * self.period_ns

    @property
    def done(self) -> bool:
        last = self.last_index
        return last is not None and self.next_index > last

    def plan_time(self, t_ns: int) -> float:
        return (t_ns - self.start_ns) / NS

    def _index(self, t: float) -> int:
        return int(np.ceil(t * NS / self.period_ns))

    def next_chunk(self) -> Chunk | None:
        if self.done:
            return None
        first = self.next_index
        last = first + self.chunk_points - 1
        self.plan.wait_until(last * self.period_ns / NS)
        if self.last_index is not None:
            last = min(last, self.last_index)
        ts = np.arange(first, last + 1) * (self.period_ns / NS)
        p, v, a = self.plan.sample(ts)
        self.next_index = last + 1
        self.plan.streamed(float(ts[-1]))
        if self.done and self.rest_at_end:  # the last point of a job is at rest
            v[-1] = 0.0
            a[-1] = 0.0
        return Chunk(self.start_ns + first * self.period_ns, self.period_ns, self.plan.joints, p, v, a)

    def cut_at(self, t: float) -> None:
        """End the stream at plan time ``t`` (on the grid), the motion as it is there: a held
        program's stream (cnc_planner.holding) is continued by its hold."""
        self._stop_index = self._index(t)
        self.rest_at_end = False

    def _bound(self) -> int:
        """The last grid index a stop may start at."""
        return self.last_index if self.last_index is not None else self._index(self.plan.duration)

    def stop_from(self, t_ns: int, machine: Machine) -> int:
        """Replace the plan from grid instant ``t_ns`` on by a jerk-limited stop.

        Returns the grid time the stop starts at; the next chunk served starts there, so
        the bridge replaces whatever it had buffered beyond it.
        """
        index = max(0, min(int(np.ceil((t_ns - self.start_ns) / self.period_ns)), self._bound()))
        t = index * self.period_ns / NS
        p, v, a = (x[0] for x in self.plan.sample(np.array([t])))
        self.plan.close()
        joints = self.plan.joints
        stop = velocity_change(list(p), list(v), list(a), [0.0] * len(joints),
                               [axis_limits(machine.axes[j]) for j in joints])
        end = stop.trajectory.at_time(stop.duration)[0]
        timelines = {}
        for dof, joint in enumerate(joints):
            timeline = JointTimeline(float(p[dof]))
            timeline.add(Piece(t, stop.duration, stop.sampler(dof)), float(end[dof]))
            timelines[joint] = timeline
        self.plan = JobPlan.of(Plan(joints, timelines, []), self.period_ns / NS)
        self.next_index = index
        self._stop_index = index + int(np.ceil(stop.duration * NS / self.period_ns))
        self.stopping = True
        self.rest_at_end = True
        return self.start_ns + index * self.period_ns
