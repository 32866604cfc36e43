"""A job's plan as consecutive segments on one time axis, planned ahead of the stream.

The first segment is planned when the job arrives (a bad job is rejected then); a
worker thread plans the rest while the job runs, staying up to AHEAD_S of machine time
ahead of what has been streamed, and segments already streamed are released. So a job
of any length costs the memory of a few segments, and the executive never waits for
planning unless the planner falls behind the machine (then ``sample`` waits for it,
which in simulation only costs wall time; the chunks are the same either way).

A segment that cannot be planned ends the job where the planned part ends, with the
axes at rest there: ``error`` says why, and the executive reports the job aborted.
"""
from __future__ import annotations

import math
import threading
from collections import deque
from typing import Iterator

import numpy as np

from cnc_msgs_py.schema import JobError

from cnc_planner.planning import INTERNAL
from cnc_planner.motion.timeline import Event, Plan

AHEAD_S = 20.0  # s of machine time planned beyond what has been streamed


class JobPlan:
    """Segments (each a Plan from rest to rest) laid end to end on the servo grid.

    Args:
        segments: the job's segments in order (segments.plan_segments); the first is
            planned here, so its JobError propagates to the caller.
        count: how many segments ``segments`` yields (for the expected duration).
        period: the interpolation period (s): every segment starts on its grid.
    """

    @classmethod
    def of(cls, plan: Plan, period: float) -> JobPlan:
        """A plan made whole, as one segment."""
        return cls(iter([plan]), 1, period)

    def __init__(self, segments: Iterator[Plan], count: int, period: float, ahead: float = AHEAD_S):
        first = next(segments)
        self.joints = first.joints
        self.error = ""
        self._source = segments
        self._count = count
        self._period = period
        self._ahead = ahead
        self._segments: deque[tuple[float, Plan]] = deque([(0.0, first)])
        self._events: deque[Event] = deque(first.events)
        self._start_position = first.start_position()
        self._planned = 1
        self._end = first.duration
        self._streamed = 0.0
        self._wanted = 0.0  # plan time someone waits for
        self._complete = count == 1
        self._closed = False
        self._changed = threading.Condition()
        self._worker: threading.Thread | None = None
        self._busy = False  # the worker is planning a segment now

    # --- what the executive reads -----------------------------------------------------------

    @property
    def complete(self) -> bool:
        """Every segment is planned (or planning stopped at an error)."""
        return self._complete

    @property
    def duration(self) -> float:
        """Plan time where the planned part ends: the job's duration once complete."""
        return self._end

    @property
    def expected_duration(self) -> float:
        """The duration, extrapolated from the segments planned so far until complete."""
        if self._complete:
            return self._end
        return self._end * self._count / self._planned

    @property
    def planning(self) -> bool:
        """A later segment is being planned now (on the worker, sharing the GIL)."""
        return self._busy

    @property
    def segments_held(self) -> int:
        """Segments in memory: the one being streamed and those planned ahead of it."""
        return len(self._segments)

    def start_position(self) -> dict[str, float]:
        return self._start_position

    def final_position(self) -> dict[str, float] | None:
        """Where the job leaves the axes, or None while that is not planned yet."""
        if not self._complete:
            return None
        return self._segments[-1][1].final_position()

    def sample(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Setpoints at sorted plan times ``ts`` (waits for planning to get there)."""
        self.wait_until(float(ts[-1]) if len(ts) else 0.0)
        with self._changed:
            segments = list(self._segments)
        starts = np.array([offset for offset, _ in segments])
        which = np.maximum(np.searchsorted(starts, ts, side="right") - 1, 0)
        out = [np.empty((len(ts), len(self.joints))) for _ in range(3)]
        for k in np.unique(which):
            offset, plan = segments[k]
            mask = which == k
            for q, part in zip(out, plan.sample(ts[mask] - offset)):
                q[mask] = part
        return out[0], out[1], out[2]

    def first_event(self, name: str) -> Event | None:
        """The first event named ``name`` not popped yet, in the segments planned so far."""
        with self._changed:
            return next((e for e in self._events if e.name == name), None)

    def pop_events(self, until: float) -> list[Event]:
        """Events up to plan time ``until`` (job time), each returned once, in order."""
        out = []
        with self._changed:
            while self._events and self._events[0].time <= until:
                out.append(self._events.popleft())
        return out

    # --- planning ahead ---------------------------------------------------------------------

    def wait_until(self, t: float) -> None:
        """Block until the plan reaches plan time ``t`` or is complete."""
        self._start_worker()
        with self._changed:
            self._wanted = max(self._wanted, t)
            self._changed.notify_all()
            self._changed.wait_for(lambda: self._complete or self._end >= t)

    def streamed(self, t: float) -> None:
        """The stream has served up to plan time ``t``: release what lies before it, plan on."""
        with self._changed:
            self._streamed = t
            while len(self._segments) > 1 and self._segments[1][0] <= t:
                self._segments.popleft()
            self._changed.notify_all()

    def close(self) -> None:
        """Plan no further (the job is stopped or replaced)."""
        with self._changed:
            self._closed = True
            self._changed.notify_all()

    def _start_worker(self) -> None:
        if self._worker is None and not self._complete:
            self._worker = threading.Thread(target=self._plan_ahead, name="cnc_planner lookahead", daemon=True)
            self._worker.start()

    def _plan_ahead(self) -> None:
        while True:
            with self._changed:
                self._changed.wait_for(lambda: self._closed or self._end < max(self._streamed + self._ahead,
                                                                               self._wanted))
                if self._closed:
                    return
                self._busy = True
            try:
                plan = next(self._source)
            except StopIteration:
                plan, error = None, ""
            except JobError as err:
                plan, error = None, str(err)
            except Exception as err:  # noqa: BLE001 (a planner bug ends the job, never the node)
                plan, error = None, f"{INTERNAL} ({type(err).__name__}: {(str(err).splitlines() or [''])[0][:120]})"
            with self._changed:
                self._busy = False
                if plan is None:
                    self.error, self._complete = error, True
                else:
                    offset = math.ceil(self._end / self._period - 1e-9) * self._period
                    self._segments.append((offset, plan))
                    self._events.extend(Event(offset + e.time, e.name, e.data) for e in plan.events)
                    self._planned += 1
                    self._end = offset + plan.duration
                    self._complete = self._planned == self._count
                self._changed.notify_all()
                if self._complete:
                    return
