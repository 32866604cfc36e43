"""The planner's executive: job queue, one job streaming at a time, cancel and faults.

ROS-free: the node feeds it documents, cancel requests, feedback and the time, and
publishes what it returns (statuses, events, setpoint chunks). Jobs are validated
when they arrive and their first segment planned, so a bad job is rejected before
anything moves; long jobs plan the rest while they run (lookahead.JobPlan).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.job import decode_job, job_id_of, parse_job
from cnc_msgs_py.machine import Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.status import Status
from cnc_msgs_py.units import NS
from cnc_servo_bridge.drive import warm_up

from cnc_planner import holding
from cnc_planner.kinds import progress_count
from cnc_planner.kinds.program import HOLD, operations_at
from cnc_planner.lookahead import JobPlan
from cnc_planner.segments import plan_segments, segment_count
from cnc_planner.settings import Settings
from cnc_planner.streaming import Chunk, SetpointStream
from cnc_planner.motion.timeline import Event

START_MATCH = 1e-6  # m: a plan made from another position than the axes hold is redone
REST_SPEED = 1e-4  # m/s or rad/s: feedback this slow counts as standing still (a settled
# position loop dithers by an encoder count, a few um/s)


@dataclass
class Output:
    statuses: list[Status] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    chunks: list[Chunk] = field(default_factory=list)


@dataclass
class _Job:
    job_id: str
    job: SimpleNamespace
    plan: JobPlan
    stream: SetpointStream | None = None
    passing: deque[Event] = field(default_factory=deque)  # published, not yet passed by the feedback
    counts: dict[str, int] = field(default_factory=dict)  # events passed, by name
    count: dict = field(default_factory=dict)  # what a machinist counts (kinds.progress_count)
    phase: str = ""  # the latest event passed
    progress: float = 0.0  # reported so far: never goes back as the duration estimate moves
    next_status_ns: int = 0
    final: str = ""  # the state to report once the stop has run out (canceled/aborted)
    reason: str = ""
    # a program's hold points (M0/M1, cnc_planner.holding): the HOLD mark the stream is cut at
    # (``cut``), then the one it holds at (``held``); the program's plan time run before the
    # stream (``done_s``) and before ``plan`` begins (``plan_from_s``), when the first stream
    # started, and where the program began
    cut: dict | None = None
    held: dict | None = None
    resuming: bool = False  # a resume came: the next tick plans the rest
    done_s: float = 0.0
    plan_from_s: float = 0.0
    first_start_ns: int | None = None
    origin: dict[str, float] = field(default_factory=dict)


class Executive:
    def __init__(self, machine: Machine, settings: Settings | None = None):
        warm_up()  # the drive model's kernel, before the first goal is planned against it
        self.machine = machine
        self.settings = settings or Settings()
        self.queue: deque[_Job] = deque()
        self.active: _Job | None = None
        self.seen_ids: set[str] = set()
        self.position: dict[str, float] | None = None  # where the next plan starts
        self.bridge_alarm: str | None = None  # the bridge's latest report: "" healthy, else its
        # alarm; None until it is heard. No job starts on a bridge not known healthy: a planner
        # (re)started beside a bridge with a latched alarm would have its setpoints refused.
        self.cancel_early: deque[str] = deque(maxlen=100)  # canceled while being prepared

    def _expected_start(self) -> dict[str, float] | None:
        """Where the next job will start, if known (else it is planned again at its start)."""
        last = self.queue[-1] if self.queue else self.active
        return last.plan.final_position() if last is not None else self.position

    def _plan(self, job: SimpleNamespace, start: dict[str, float] | None) -> JobPlan:
        return JobPlan(plan_segments(job, self.machine, start), segment_count(job), self.settings.period_ns / NS)

    def submit(self, text: str) -> Status:
        """A job_goal message: accepted (queued) or rejected with the field and reason."""
        return self.admit(self.prepare(text))

    def prepare(self, text: str) -> _Job | Status:
        """The slow half of submit, safe on another thread than the executive's: the job
        validated and its first segment planned, or its rejection."""
        doc = None
        try:
            doc = decode_job(text)
            job = parse_job(doc)
            self._check_new(job.job_id)
            return _Job(job.job_id, job, self._plan(job, self._expected_start()), count=progress_count(job))
        except JobError as err:
            return Status(job_id_of(doc), "rejected", reason=str(err))

    def admit(self, prepared: _Job | Status) -> Status:
        """The other half: queue a prepared job (in the order goals arrived)."""
        if isinstance(prepared, Status):
            return prepared
        if prepared.job_id in self.cancel_early:
            self.cancel_early.remove(prepared.job_id)
            self.seen_ids.add(prepared.job_id)
            prepared.plan.close()
            return Status(prepared.job_id, "canceled", reason="canceled before it started")
        try:
            self._check_new(prepared.job_id)  # two goals with one id may be prepared at once
        except JobError as err:
            prepared.plan.close()
            return Status(prepared.job_id, "rejected", reason=str(err))
        self.seen_ids.add(prepared.job_id)
        self.queue.append(prepared)
        return Status(prepared.job_id, "accepted", duration_s=prepared.plan.expected_duration, count=prepared.count)

    def _check_new(self, job_id: str) -> None:
        if job_id in self.seen_ids:
            raise JobError("job_id", f"'{job_id}' was already used in this planner's lifetime")

    def cancel(self, job_id: str, now_ns: int, preparing: bool = False) -> list[Status]:
        """Cancel a queued job at once, or stop the running one (jerk-limited).

        ``preparing``: goals are still being prepared, and the job may be one of them:
        it is then canceled as it is admitted."""
        if preparing and job_id not in self.seen_ids:
            self.cancel_early.append(job_id)
        for queued in list(self.queue):
            if queued.job_id == job_id:
                self.queue.remove(queued)
                queued.plan.close()
                return [Status(job_id, "canceled", reason="canceled before it started")]
        if self.active is not None and self.active.job_id == job_id and not self.active.final:
            self._stop(now_ns, "canceled", "canceled by request")
        return []

    def abort(self, reason: str, now_ns: int, stop: bool = True, raised_ns: int | None = None) -> list[Status]:
        """Abort the running job: stop it, or just end it when the bridge has stopped the
        axes itself or is gone. A fault ``raised_ns`` before the job's first setpoint
        belongs to what ran before and is ignored."""
        if self.active is None or self.active.final:
            return []
        stream = self.active.stream
        if raised_ns is not None and (stream is None or raised_ns < stream.start_ns):
            return []
        if stop:
            self._stop(now_ns, "aborted", reason)
            return []
        job, self.active = self.active, None
        job.plan.close()
        self.position = None  # unknown until feedback returns
        return [Status(job.job_id, "aborted", reason=reason)]

    def _stop(self, now_ns: int, final: str, reason: str) -> None:
        job = self.active
        job.final, job.reason = final, reason
        if job.stream is not None:
            # Right after the last setpoint sent: the bridge cannot have passed it (it waits
            # for setpoints rather than run dry), so the stop is never refused as late.
            job.stream.stop_from(max(job.stream.served_until_ns + self.settings.period_ns, job.stream.start_ns),
                                 self.machine)

    def feedback(self, positions: dict[str, float], velocities: dict[str, float] | None = None) -> str:
        """Joint states from the bridge. Plans start from the last commanded position;
        only when that is unknown (start-up, or the bridge stopped on its own) do they
        start from the feedback, once the axes stand still (velocities, if given).

        Returns why the message was ignored ("" if taken): one that lacks a joint of this
        machine is another machine's (a second bridge in the namespace), never where ours stand."""
        if missing := [j for j in self.machine.joint_names if j not in positions]:
            return f"joint_states without joint '{missing[0]}' ignored (another machine's bridge?)"
        standing = velocities is None or all(abs(v) < REST_SPEED for v in velocities.values())
        if self.position is None and self.active is None and standing:
            self.position = {j: positions[j] for j in self.machine.joint_names}
        return ""

    @property
    def heard_bridge(self) -> bool:
        """Whether a job could start now: where the axes stand and the bridge's state are known."""
        return self.position is not None and self.bridge_alarm is not None

    def bridge_report(self, alarm: str) -> None:
        """The bridge's latest diagnostic: ``alarm`` is "" when it reports no error."""
        self.bridge_alarm = alarm

    def tick(self, now_ns: int, planning: bool = False, clock_ns: int = 0) -> Output:
        """Advance to ``now`` (the latest feedback's time): start the next job, stream ahead,
        report progress and ends.

        ``planning``: goals are being planned beside the stream, which then runs further
        ahead, as it does while its own job's next segment is planned. ``clock_ns``: the
        bridge's clock as this process reads it now (real time: the wall). Feedback reaches
        the planner late under CPU load (chunks came up to 140 ms late on a loaded 2-CPU
        host), so setpoints are kept ahead of that clock when it is ahead of the feedback;
        progress and the job's end stay on the feedback."""
        out = Output()
        if self.active is None and self.queue and self.position is not None and self.bridge_alarm == "":
            self._start(now_ns, out)
        job = self.active
        if job is None or job.stream is None:
            return out
        if job.resuming:
            self._plan_rest(job, now_ns)
        stream = job.stream
        planning = planning or job.plan.planning
        ahead = self.settings.planning_lookahead_ns if planning else self.settings.lookahead_ns
        # The first chunk goes out at once, start_delay ahead: held back until the lookahead
        # reached it, it waited that long on an idle bridge's wall-paced clock and then came
        # with less than min_lead, so it was always re-timed (a job started ~0.9 s late).
        while not stream.done and (stream.next_index == 0 or stream.served_until_ns < max(now_ns, clock_ns) + ahead):
            chunk = stream.next_chunk()
            out.chunks.append(chunk)
            self._events_until(job, chunk.end_ns, out)
            if stream.done and job.cut is not None and not stream.stopping:
                stream = self._hold(job)  # served up to its hold point: the hold follows on the grid
        if now_ns >= job.next_status_ns and now_ns < stream.end_ns:  # until the job ends, not until all is served
            out.statuses.append(self._running(job, now_ns))
            job.next_status_ns = now_ns + self.settings.status_period_ns
        elif job.held is not None and not stream.stopping and now_ns >= max(job.next_status_ns, stream.start_ns):
            status = self._running(job, now_ns)  # the feedback has reached the hold
            status.state, status.phase, status.reason = "held", HOLD, holding.held_reason(job.job_id, job.held)
            out.statuses.append(status)
            job.next_status_ns = now_ns + self.settings.status_period_ns
        if stream.done and now_ns >= stream.end_ns:
            self._events_until(job, stream.end_ns, out)
            self.position = dict(zip(stream.plan.joints, out_last_position(stream)))
            if not job.final and job.plan.error:  # a later segment could not be planned
                job.final, job.reason = "aborted", f"stopped where planning did: {job.plan.error}"
            state = job.final or "succeeded"
            out.statuses.append(Status(job.job_id, state, reason=job.reason, progress=1.0,
                                       elapsed_s=(stream.end_ns - job.first_start_ns) / NS,
                                       duration_s=job.plan_from_s + job.plan.duration,
                                       cycle_time_s=(stream.end_ns - job.first_start_ns) / NS))
            self.active = None
        return out

    def retime(self, out: Output, bridge_now_ns: int) -> None:
        """Just before ``out`` is published, with the bridge's clock as it stands now: if it
        holds the running job's first chunk and that would arrive with less than min_lead,
        the job starts later instead (chunks and events shifted on the grid, start_delay
        after now). Later chunks continue a stream the bridge has, so they are never moved."""
        job = self.active
        if job is None or job.stream is None or not out.chunks or out.chunks[0].stamp_ns != job.first_start_ns:
            return  # (a held program's later streams continue the first on the grid: never moved)
        if out.chunks[0].stamp_ns - bridge_now_ns >= self.settings.min_lead_ns:
            return
        period = self.settings.period_ns
        shift = -(-(bridge_now_ns + self.settings.start_delay_ns) // period) * period - job.stream.start_ns
        job.stream.start_ns += shift
        job.first_start_ns += shift
        for chunk in out.chunks:
            chunk.stamp_ns += shift
        for event in out.events:
            if event["job_id"] == job.job_id:
                event["stamp_ns"] += shift

    def _start(self, now_ns: int, out: Output) -> None:
        """Start the next job on the grid, from where the axes really stand.

        If they stand elsewhere than the job was planned from (after a cancel or an abort),
        it is planned again first and starts on the next tick, with a fresh ``now``.
        """
        job = self.queue[0]
        planned_from = job.plan.start_position()
        if any(abs(planned_from[j] - self.position[j]) > START_MATCH for j in self.machine.linear_axes):
            job.plan.close()
            try:
                job.plan = self._plan(job.job, self.position)
            except JobError as err:
                self.queue.popleft()
                out.statuses.append(Status(job.job_id, "aborted", reason=f"cannot start from here: {err}"))
            return
        self.queue.popleft()
        period = self.settings.period_ns
        start = -(-(now_ns + self.settings.start_delay_ns) // period) * period
        job.stream = SetpointStream(job.plan, start, period, self.settings.chunk_points)
        job.first_start_ns, job.origin = start, planned_from
        self._cut(job)
        job.next_status_ns = now_ns
        self.active = job

    def _cut(self, job: _Job) -> None:
        """Cut the job's stream at its plan's first hold point (M0/M1), if it has one."""
        job.cut = job.plan.first_event(HOLD)
        if job.cut is not None:
            job.stream.cut_at(job.cut.time)

    def _hold(self, job: _Job) -> SetpointStream:
        """The stream served up to its hold point: hold there (cnc_planner.holding)."""
        job.done_s += job.cut.time
        job.held, job.cut = dict(job.cut.data), None
        job.stream = holding.hold_after(job.stream, self.settings.chunk_points)
        return job.stream

    def resume(self, job_id: str, now_ns: int) -> tuple[Output, str]:
        """A job_resume: the hold ends ``planning_lookahead`` after now, its setpoints up to
        there returned at once, so that the bridge holds on while the next tick plans the rest
        from the hold's state there (a program's rest took 1.8 s to plan: tort.ngc); or, with
        nothing changed, why it cannot (one line)."""
        job = self.active
        if job is None or job.job_id != job_id or job.held is None or job.final or job.resuming:
            return Output(), f"cannot resume '{job_id}': {self._not_held(job_id)}"
        stream, period = job.stream, self.settings.period_ns
        ahead = max(self.settings.start_delay_ns, self.settings.planning_lookahead_ns)
        stream.release(-(-(now_ns + ahead) // period) * period - period)
        out = Output()
        while not stream.done:
            out.chunks.append(stream.next_chunk())
        job.resuming = True
        return out, ""

    def _plan_rest(self, job: _Job, now_ns: int) -> None:
        """The rest of a resumed program, from where its released hold leaves the machine."""
        job.resuming = False
        position, speed, start_ns = holding.state_after(job.stream)
        operations = operations_at(job.job, self.machine, job.origin)
        try:
            plan = JobPlan(holding.resumed_segments(job.job, operations, job.held, self.machine, position, speed),
                           segment_count(job.job), self.settings.period_ns / NS)
        except JobError as err:  # (it planned whole when it was accepted)
            self._stop(now_ns, "aborted", f"the program after its hold at line {job.held['line']}: {err}")
            return
        job.plan.close()
        job.plan, job.held, job.plan_from_s = plan, None, job.done_s
        job.stream = SetpointStream(plan, start_ns, self.settings.period_ns, self.settings.chunk_points)
        self._cut(job)
        job.next_status_ns = now_ns

    def _not_held(self, job_id: str) -> str:
        job = self.active
        if job is not None and job.job_id == job_id:
            return "it is stopping" if job.final else "it is resuming" if job.resuming else "it is running, not held"
        if any(queued.job_id == job_id for queued in self.queue):
            return "it is queued, not held"
        return "it has ended" if job_id in self.seen_ids else "no such job in this planner"

    def _running(self, job: _Job, now_ns: int) -> Status:
        # held: the hold's stream follows the part before it, which the feedback may not have passed yet
        elapsed = job.done_s + (min(0.0, job.stream.plan_time(now_ns)) if job.held is not None
                                else max(0.0, job.stream.plan_time(now_ns)))
        while job.passing and job.passing[0].time <= elapsed:
            event = job.passing.popleft()
            job.counts[event.name] = job.counts.get(event.name, 0) + 1
            job.phase = event.name
        duration = job.plan_from_s + job.plan.expected_duration
        job.progress = max(job.progress, min(1.0, elapsed / max(duration, 1e-9)))
        return Status(job.job_id, "running", progress=job.progress,
                      phase=job.phase, elapsed_s=elapsed, duration_s=duration, detail=dict(job.counts),
                      count=job.count)

    def _events_until(self, job: _Job, t_ns: int, out: Output) -> None:
        """Publish the job's events up to ``t_ns`` (none once it is stopping, none past a hold
        point the stream is cut at: the rest is planned again on resume)."""
        if job.held is not None:
            return
        for event in job.plan.pop_events(job.stream.plan_time(t_ns)):
            if not job.stream.stopping:
                out.events.append(event_doc(job.job_id, job.stream.start_ns, event))
                job.passing.append(Event(job.done_s + event.time, event.name, event.data))
            if event is job.cut:
                break


def out_last_position(stream: SetpointStream) -> np.ndarray:
    p, _, _ = stream.plan.sample(np.array([stream.plan_time(stream.end_ns)]))
    return p[0]


def event_doc(job_id: str, start_ns: int, event: Event) -> dict:
    """An event as published on job_events: stamped in ROS time from the job's start."""
    return {"job_id": job_id, "name": event.name, "stamp_ns": int(start_ns + round(event.time * NS)),
            "plan_time_s": event.time, **event.data}
