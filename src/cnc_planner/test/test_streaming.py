"""Setpoint streaming and the planner's executive, driven by a simulated clock (no ROS).

The loop advances ``now`` in 10 ms steps, feeds the executive the last commanded
position (a perfect bridge), and collects what it publishes. Every chunk is also fed
to the bridge's SetpointBuffer, so the stream is checked against the rules the bridge
enforces on joint_trajectory.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.status import Status
from cnc_msgs_py.units import NS
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.executive import Executive, Settings
from cnc_planner.kinds.drill import SEGMENT_HOLES
from cnc_planner.streaming import SetpointStream
from cnc_servo_bridge.setpoints import SetpointBuffer

MILL = load_machine("mill3")
STEP_NS = 10_000_000
MS = 1_000_000
ORIGIN = {"x": 0.0, "y": 0.0, "z": 0.0, SPINDLE: 0.0}


def move_job(job_id: str, moves: list[dict], rpm: float = 0.0, machine: str = "mill3") -> str:
    return json.dumps({"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": machine,
                       "spindle_rpm": rpm, "move": moves})


class Sim:
    """A simulated clock loop around one Executive, with a perfect bridge behind it."""

    def __init__(self, settings: Settings | None = None, now_ns: int = 0, feedback: bool = True):
        self.settings = settings or Settings()
        self.ex = Executive(MILL, self.settings)
        self.ex.bridge_report("")  # the bridge has reported, without an alarm
        self.now = now_ns
        self.bridge = SetpointBuffer(MILL)
        self.position = np.zeros(len(MILL.joint_names))
        self.chunks: list[tuple[int, object, str]] = []  # (tick time, chunk, active job id)
        self.statuses: list[tuple[int, Status]] = []
        self.events: list[dict] = []
        self.active_ids: list[str] = []
        self.started: dict[str, int] = {}  # job id -> the tick that started it
        self.feedback = feedback

    def commanded(self) -> np.ndarray:
        sample = self.bridge.sample(self.now)
        if sample is not None:
            self.position = np.array(sample[0])
        return self.position

    def submit(self, text: str) -> Status:
        status = self.ex.submit(text)
        self.statuses.append((self.now, status))
        return status

    def tick(self) -> None:
        reference = self.commanded()
        if self.feedback:
            self.ex.feedback(dict(zip(MILL.joint_names, reference.tolist())))
        out = self.ex.tick(self.now)
        active = self.ex.active.job_id if self.ex.active is not None else ""
        if active and (not self.active_ids or self.active_ids[-1] != active):
            self.active_ids.append(active)
            self.started.setdefault(active, self.now)
        for chunk in out.chunks:
            times = chunk.stamp_ns + np.arange(len(chunk.positions)) * chunk.period_ns
            points = self.bridge.validate(list(chunk.joints), times, chunk.positions, chunk.velocities,
                                          chunk.accelerations, self.now, (reference, np.zeros_like(reference)))
            self.bridge.insert(points)
            self.chunks.append((self.now, chunk, active))
        self.statuses.extend((self.now, s) for s in out.statuses)
        self.events.extend(out.events)
        self.now += STEP_NS

    def run_until(self, predicate, limit_s: float = 30.0) -> None:
        end = self.now + int(limit_s * NS)
        while not predicate():
            assert self.now < end, "simulation did not reach the expected state"
            self.tick()

    def run_for(self, seconds: float) -> None:
        end = self.now + int(seconds * NS)
        while self.now < end:
            self.tick()

    def final(self, job_id: str) -> Status | None:
        return next((s for _, s in self.statuses if s.job_id == job_id and s.final), None)

    def states(self, job_id: str) -> list[str]:
        return [s.state for _, s in self.statuses if s.job_id == job_id]

    def run_job(self, job_id: str, limit_s: float = 30.0) -> Status:
        self.run_until(lambda: self.final(job_id) is not None, limit_s)
        return self.final(job_id)


def stitched(chunks) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The reference a bridge follows: later chunks replace points from their stamp on."""
    times: list[int] = []
    rows: list[tuple] = []
    for chunk in chunks:
        while times and times[-1] >= chunk.stamp_ns:
            times.pop()
            rows.pop()
        for i in range(len(chunk.positions)):
            times.append(chunk.stamp_ns + i * chunk.period_ns)
            rows.append((chunk.positions[i], chunk.velocities[i], chunk.accelerations[i]))
    return (np.array(times), np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
            np.array([r[2] for r in rows]))


def assert_within_limits(p: np.ndarray, dt: float, rel: float = 1e-6) -> None:
    for k, joint in enumerate(MILL.joint_names):
        axis = MILL.axes[joint]
        assert np.abs(np.diff(p[:, k])).max(initial=0) / dt <= axis.max_velocity * (1 + rel) + 1e-9, joint
        assert np.abs(np.diff(p[:, k], 2)).max(initial=0) / dt**2 <= axis.max_acceleration * (1 + rel) + 1e-6, joint
        assert np.abs(np.diff(p[:, k], 3)).max(initial=0) / dt**3 <= axis.max_jerk * (1 + rel) + 1e-3, joint


DEMO = [{"rapid": {"x": 20, "y": 10, "z": 5}}, {"linear": {"z": -2}, "feed": 600},
        {"linear": {"x": 25, "y": 13}, "feed": 1200}, {"rapid": {"z": 5}}]


# --- SetpointStream on its own --------------------------------------------------------------

def small_plan():
    builder = PlanBuilder(MILL, {"x": 0.0})
    builder.rapid({"x": 0.01})  # about 0.1 s
    return builder.build()


def test_stream_cuts_the_plan_into_contiguous_chunks():
    plan = small_plan()
    stream = SetpointStream(plan, start_ns=7 * MS, period_ns=MS, chunk_points=20)
    chunks = []
    while (chunk := stream.next_chunk()) is not None:
        chunks.append(chunk)
    n = math.ceil(plan.duration * 1000 - 1e-9) + 1  # grid points from 0 up to the first at/after the end
    assert sum(len(c.positions) for c in chunks) == n
    assert [len(c.positions) for c in chunks[:-1]] == [20] * (len(chunks) - 1)
    assert chunks[0].stamp_ns == 7 * MS
    for prev, cur in zip(chunks, chunks[1:]):
        assert cur.stamp_ns == prev.end_ns + MS
    assert stream.done and stream.served_until_ns == chunks[-1].end_ns == stream.end_ns
    # the points are the plan sampled on the grid
    t, p, v, a = stitched(chunks)
    ps, vs, _ = plan.sample((t - 7 * MS) / NS)
    assert np.allclose(p, ps, rtol=0, atol=1e-12)
    assert np.allclose(v[:-1], vs[:-1], rtol=0, atol=1e-9)
    # the last point is at rest, exactly at the target
    assert np.all(v[-1] == 0.0) and np.all(a[-1] == 0.0)
    assert p[-1, 0] == 0.01


def test_stream_stop_from_replaces_the_rest_with_a_stop():
    builder = PlanBuilder(MILL, {"x": 0.0})
    builder.linear({"x": 0.05}, 0.02)  # 2.5 s at 20 mm/s
    plan = builder.build()
    stream = SetpointStream(plan, start_ns=0, period_ns=MS, chunk_points=100)
    served = [stream.next_chunk() for _ in range(10)]  # 1 s served
    begin = stream.stop_from(500 * MS + 1, MILL)  # between grid instants: the next one
    assert begin == 501 * MS and stream.stopping
    rest = []
    while (chunk := stream.next_chunk()) is not None:
        rest.append(chunk)
    assert rest[0].stamp_ns == begin
    t, p, v, _ = stitched(served + rest)
    assert np.all(np.diff(t) == MS)
    assert_within_limits(p, 1e-3)
    after = t >= begin
    speed = np.abs(v[after, 0])
    assert np.all(np.diff(speed) <= 1e-12) and speed[-1] == 0.0
    assert speed[0] == pytest.approx(0.02)
    # from 20 mm/s at a = 0, v < A^2/J = 0.48 m/s: two jerk phases, 2 sqrt(v/J) = 20 ms
    assert (t[-1] - begin) / NS == pytest.approx(2 * math.sqrt(0.02 / 200), abs=1.5e-3)
    assert p[-1, 0] < 0.05


def test_stream_stop_before_the_start_is_a_single_point_at_rest():
    stream = SetpointStream(small_plan(), start_ns=100 * MS, period_ns=MS, chunk_points=100)
    stream.next_chunk()
    assert stream.stop_from(0, MILL) == 100 * MS
    chunk = stream.next_chunk()
    assert len(chunk.positions) == 1 and chunk.stamp_ns == 100 * MS
    assert np.all(chunk.velocities == 0.0) and chunk.positions[0, 0] == 0.0
    assert stream.next_chunk() is None


# --- the executive ------------------------------------------------------------------------

@pytest.mark.parametrize("start_ns", [0, 3_456_789])
def test_chunks_contiguous_on_grid_never_past_bounded_and_end_at_rest(start_ns):
    sim = Sim(now_ns=start_ns)
    assert sim.submit(move_job("demo", DEMO, rpm=2000)).state == "accepted"
    final = sim.run_job("demo")
    assert final.state == "succeeded" and final.progress == 1.0
    settings = sim.settings
    chunks = [c for _, c, _ in sim.chunks]
    assert len(chunks) >= 10
    for now, chunk, _ in sim.chunks:
        assert chunk.stamp_ns % settings.period_ns == 0
        assert chunk.period_ns == settings.period_ns
        assert chunk.stamp_ns >= now, "a chunk never starts in the past"
        ahead = max(now + settings.lookahead_ns, sim.chunks[0][1].stamp_ns)  # the first chunk goes at once
        assert chunk.end_ns <= ahead + settings.chunk_points * settings.period_ns
        assert chunk.joints == MILL.joint_names
    for prev, cur in zip(chunks, chunks[1:]):
        assert cur.stamp_ns == prev.end_ns + settings.period_ns
    assert chunks[0].stamp_ns == -(-(sim.started["demo"] + settings.start_delay_ns) // MS) * MS
    t, p, v, a = stitched(chunks)
    assert_within_limits(p, 1e-3)
    assert np.all(v[-1] == 0.0) and np.all(a[-1] == 0.0)
    assert p[-1, :3] == pytest.approx([0.025, 0.013, 0.005], abs=1e-12)
    assert p[-1, 3] > 0.0  # the spindle turned, and stopped
    assert final.cycle_time_s == pytest.approx((t[-1] - t[0]) / NS)
    assert final.cycle_time_s >= final.duration_s
    assert sim.ex.active is None and not sim.ex.queue


def test_a_last_chunk_of_one_point_is_accepted_by_the_bridge():
    sim = Sim()
    status = sim.submit(move_job("one", [{"linear": {"x": 3}, "feed": 1200}]))
    last_index = math.ceil(status.duration_s * NS / MS)
    sim.settings.chunk_points = last_index  # chunks of last_index points, then one more
    assert sim.run_job("one").state == "succeeded"
    chunks = [c for _, c, _ in sim.chunks]
    assert [len(c.positions) for c in chunks] == [last_index, 1]
    assert np.abs(chunks[0].velocities[-1, 0]) > 0.0  # the point before it still moves


def test_events_are_published_in_order_with_stamps():
    sim = Sim()
    sim.submit(move_job("ev", DEMO))
    sim.run_job("ev")
    moves = [e for e in sim.events if "move" in e]  # the per-move phase marks
    assert [e["name"] for e in moves] == ["rapid", "linear", "linear", "rapid"]
    assert [e["move"] for e in moves] == [0, 1, 2, 3]
    stamps = [e["stamp_ns"] for e in sim.events]
    assert stamps == sorted(stamps) and all(e["job_id"] == "ev" for e in sim.events)
    assert moves[0]["stamp_ns"] == sim.chunks[0][1].stamp_ns
    assert stamps[-1] <= sim.chunks[-1][1].end_ns


def test_progress_statuses_increase_within_0_and_1():
    sim = Sim()
    sim.submit(move_job("long", [{"linear": {"x": 60}, "feed": 1200}]))  # ~3 s
    sim.run_job("long")
    running = [s for _, s in sim.statuses if s.state == "running"]
    assert len(running) >= 4
    progress = [s.progress for s in running]
    assert all(0.0 <= x <= 1.0 for x in progress)
    assert progress[0] == 0.0
    # before the first setpoint (the start delay, longer than a status period) it stays at 0
    waiting = progress.index(next(x for x in progress if x > 0))
    assert 1 <= waiting <= -(-Settings().start_delay_ns // Settings().status_period_ns)
    assert all(b > a for a, b in zip(progress[waiting - 1:], progress[waiting:]))
    assert all(s.duration_s == running[0].duration_s > 2.9 for s in running)
    assert sim.states("long")[0] == "accepted" and sim.states("long")[-1] == "succeeded"
    # updates every status period (0.5 s)
    times = [now for now, s in sim.statuses if s.state == "running"]
    assert all(b - a == sim.settings.status_period_ns for a, b in zip(times, times[1:]))


@pytest.mark.parametrize("document, field", [
    (move_job("bad-feed", [{"linear": {"x": 10}, "feed": -5}]), "move[0].feed"),
    (move_job("bad-key", [{"rapid": {"x": 10, "q": 1}}]), "move[0].rapid.q"),
    (move_job("no-feed", [{"linear": {"x": 10}}]), "move[0].feed"),
    (move_job("travel", [{"rapid": {"x": 10}}, {"rapid": {"y": 400}}]), "move[1].rapid"),
    (move_job("lathe-job", [{"rapid": {"x": 10}}], machine="lathe"), "machine"),
    (move_job("fast", [{"rapid": {"x": 10}}], rpm=20000), "spindle_rpm"),
    (move_job("axis", [{"rapid": {"a": 10}}]), "move[0].rapid.a"),
])
def test_rejected_job_names_the_field_and_never_moves(document, field):
    sim = Sim()
    status = sim.submit(document)
    assert status.state == "rejected" and status.final
    assert status.reason.startswith(f"{field}: "), status.reason
    assert status.job_id == json.loads(document)["job_id"]
    sim.run_for(1.0)
    assert sim.chunks == [] and sim.events == []
    assert [s.state for _, s in sim.statuses] == ["rejected"]


@pytest.mark.parametrize("text", ["{not json", "[]", json.dumps({"job_id": "x"}), ""])
def test_malformed_documents_are_rejected(text):
    sim = Sim()
    status = sim.submit(text)
    assert status.state == "rejected" and status.reason
    sim.run_for(0.2)
    assert sim.chunks == []


def test_duplicate_job_id_rejected_while_queued_and_after():
    sim = Sim()
    assert sim.submit(move_job("same", [{"rapid": {"x": 5}}])).state == "accepted"
    again = sim.submit(move_job("same", [{"rapid": {"x": 6}}]))
    assert again.state == "rejected" and again.reason.startswith("job_id: ") and "already used" in again.reason
    sim.run_until(lambda: "succeeded" in sim.states("same"))
    assert sim.submit(move_job("same", [{"rapid": {"x": 7}}])).state == "rejected"
    sim.run_for(0.5)
    states = sim.states("same")  # "running" once per status period of the start delay
    assert [s for k, s in enumerate(states) if k == 0 or s != states[k - 1]] == \
        ["accepted", "rejected", "running", "succeeded", "rejected"]
    t, p, _, _ = stitched([c for _, c, _ in sim.chunks])
    assert p[-1, 0] == pytest.approx(0.005)  # only the first job ran


def test_jobs_queue_and_run_in_order_one_at_a_time():
    sim = Sim()
    for i, x in enumerate([10, -10, 30]):
        assert sim.submit(move_job(f"q{i}", [{"rapid": {"x": x, "y": i}}])).state == "accepted"
    for i in range(3):
        assert sim.run_job(f"q{i}").state == "succeeded"
    assert sim.active_ids == ["q0", "q1", "q2"]
    finals = [s.job_id for _, s in sim.statuses if s.final]
    assert finals == ["q0", "q1", "q2"]
    # each job's chunks come after the previous job ended, and start where it ended
    by_job = {j: [c for _, c, a in sim.chunks if a == j] for j in ("q0", "q1", "q2")}
    for prev, cur in [("q0", "q1"), ("q1", "q2")]:
        assert by_job[cur][0].stamp_ns > by_job[prev][-1].end_ns
        assert np.array_equal(by_job[cur][0].positions[0], by_job[prev][-1].positions[-1])
        ended = next(now for now, s in sim.statuses if s.job_id == prev and s.final)
        assert all(now >= ended for now, c, a in sim.chunks if a == cur)
        started = [now for now, s in sim.statuses if s.job_id == cur and s.state == "running"]
        assert not started or started[0] >= ended
    assert by_job["q2"][-1].positions[-1][:2] == pytest.approx([0.030, 0.002])


def test_queued_jobs_plan_from_the_previous_jobs_end():
    sim = Sim()
    sim.submit(move_job("first", [{"rapid": {"x": 10}}]))
    second = sim.submit(move_job("second", [{"linear": {"x": 12}, "feed": 600}]))
    # 2 mm at 10 mm/s from the first job's end, not 12 mm from the origin
    assert 0.2 < second.duration_s < 0.3
    sim.run_job("second")


def test_cancel_of_a_queued_job_is_immediate_and_it_never_runs():
    sim = Sim()
    sim.submit(move_job("run", [{"rapid": {"x": 10}}]))
    sim.submit(move_job("drop", [{"rapid": {"x": 20}}]))
    sim.submit(move_job("next", [{"rapid": {"y": 10}}]))
    sim.run_for(0.05)
    statuses = sim.ex.cancel("drop", sim.now)
    assert [(s.job_id, s.state) for s in statuses] == [("drop", "canceled")]
    assert statuses[0].reason
    sim.statuses.extend((sim.now, s) for s in statuses)
    sim.run_job("next")
    assert sim.active_ids == ["run", "next"]
    assert sim.states("drop") == ["accepted", "canceled"]
    t, p, _, _ = stitched([c for _, c, _ in sim.chunks])
    assert p[:, 0].max() == pytest.approx(0.010)  # never went towards x = 20 mm
    assert p[-1, :2] == pytest.approx([0.010, 0.010])


def test_cancel_of_an_unknown_or_finished_job_does_nothing():
    sim = Sim()
    sim.submit(move_job("done", [{"rapid": {"x": 1}}]))
    sim.run_job("done")
    assert sim.ex.cancel("done", sim.now) == []
    assert sim.ex.cancel("never", sim.now) == []
    sim.run_for(0.2)
    assert [s.state for _, s in sim.statuses if s.job_id == "done"].count("succeeded") == 1


def run_and_cancel(cancel_at_s: float, rpm: float = 1000.0):
    """A long straight feed (3 s at 20 mm/s along 3:4) canceled at ``cancel_at_s``."""
    sim = Sim()
    sim.submit(move_job("cut", [{"linear": {"x": 36, "y": 48}, "feed": 1200}], rpm=rpm))
    sim.run_for(cancel_at_s)
    cancel_ns = sim.now
    assert sim.ex.cancel("cut", cancel_ns) == []  # the stop runs first
    n_before = len(sim.chunks)
    final = sim.run_job("cut")
    return sim, cancel_ns, n_before, final


def test_cancel_of_the_running_job_stops_jerk_limited():
    sim, cancel_ns, n_before, final = run_and_cancel(1.5)
    settings = sim.settings
    assert final.state == "canceled" and final.reason == "canceled by request"
    after = [c for _, c, _ in sim.chunks[n_before:]]
    assert after, "the stop is streamed"
    stop_ns = after[0].stamp_ns
    # the stop continues right after what was already sent (never late for the bridge),
    # so it begins at most the look-ahead (plus a chunk) after the request
    assert stop_ns == sim.chunks[n_before - 1][1].end_ns + MS
    assert stop_ns <= cancel_ns + settings.lookahead_ns + settings.chunk_points * MS
    for prev, cur in zip(after, after[1:]):
        assert cur.stamp_ns == prev.end_ns + MS
    t, p, v, a = stitched([c for _, c, _ in sim.chunks])
    assert np.all(np.diff(t) == MS)
    assert_within_limits(p, 1e-3)
    stop = t >= stop_ns
    speed = np.linalg.norm(v[stop, :3], axis=1)
    assert speed[0] == pytest.approx(0.02, rel=1e-6)  # it was cutting at the feed
    assert np.all(np.diff(speed) <= 1e-12), "speed decreases during the stop"
    assert np.all(np.diff(np.abs(v[stop, 3])) <= 1e-9), "the spindle slows down too"
    assert np.all(v[-1] == 0.0) and np.all(a[-1] == 0.0)
    # it stopped on the path, short of the target
    xy = p[-1, :2]
    assert xy[0] < 0.036 and xy[0] * 4 == pytest.approx(xy[1] * 3, abs=1e-9)
    # and nothing after the stop
    assert t[-1] <= stop_ns + int(0.5 * NS)
    assert sim.states("cut")[-1] == "canceled" and sim.states("cut").count("canceled") == 1
    assert final.cycle_time_s == pytest.approx((t[-1] - t[0]) / NS)


def test_cancel_before_the_first_setpoint_stops_after_what_was_sent():
    sim = Sim()
    sim.submit(move_job("early", [{"rapid": {"x": 400}}]))
    sim.run_until(lambda: sim.chunks)  # started, and the first setpoints sent ahead of the start
    assert sim.chunks[0][1].stamp_ns > sim.now
    sent_until = sim.chunks[-1][1].end_ns
    sim.ex.cancel("early", sim.now)
    final = sim.run_job("early")
    assert final.state == "canceled"
    t, p, v, _ = stitched([c for _, c, _ in sim.chunks])
    assert np.all(np.diff(t) == MS)  # one contiguous stream: what was sent, then the stop
    assert t[-1] < sent_until + int(0.5 * NS) and np.all(v[-1] == 0.0)
    assert 0.0 < p[-1, 0] < 0.3  # moved a little, stopped well short of x = 400 mm


def test_abort_without_stop_ends_the_job_at_once():
    sim = Sim()
    sim.submit(move_job("doomed", [{"linear": {"x": 30}, "feed": 1200}]))
    sim.run_for(0.6)
    n = len(sim.chunks)
    statuses = sim.ex.abort("bridge alarm: following error", sim.now, stop=False)
    assert [(s.job_id, s.state, s.reason) for s in statuses] == [("doomed", "aborted", "bridge alarm: following error")]
    assert sim.ex.active is None
    assert sim.ex.abort("again", sim.now, stop=False) == []
    sim.run_for(1.0)
    assert len(sim.chunks) == n and not any(s.job_id == "doomed" for _, s in sim.statuses[1:] if s.final)


def test_after_an_abort_queued_jobs_start_from_the_fed_back_position():
    sim = Sim()
    sim.submit(move_job("a1", [{"linear": {"x": 30}, "feed": 1200}]))
    sim.submit(move_job("a2", [{"rapid": {"y": 10}}]))
    sim.run_for(0.6)
    sim.ex.abort("bridge gone", sim.now, stop=False)
    # the bridge stopped the axes where they were: that is where a2 must start
    sim.bridge.clear()
    sim.position = np.array([0.004, 0.0, 0.0, 0.0])
    final = sim.run_job("a2", limit_s=5.0)
    assert final.state == "succeeded"
    a2 = [c for _, c, a in sim.chunks if a == "a2"]
    assert a2[0].positions[0][:3] == pytest.approx([0.004, 0.0, 0.0])
    assert a2[-1].positions[-1][:3] == pytest.approx([0.004, 0.010, 0.0])


def test_a_job_submitted_before_any_feedback_starts_once_feedback_arrives():
    sim = Sim(feedback=False)
    sim.submit(move_job("waits", [{"rapid": {"x": 10}}]))
    sim.run_for(0.5)
    assert sim.chunks == []  # where the machine is is unknown: nothing moves
    sim.feedback = True
    assert sim.run_job("waits", limit_s=5.0).state == "succeeded"


def test_another_machines_joint_states_are_ignored_and_never_where_the_axes_stand():
    """A lathe's bridge in the same namespace (a second run) publishes x, z and spindle: a
    mill's planner once took that for its own feedback, and died on the missing y."""
    executive = Executive(MILL)
    reason = executive.feedback({"x": 0.1, "z": 0.2, SPINDLE: 0.0}, {"x": 0.0, "z": 0.0, SPINDLE: 0.0})
    assert reason == "joint_states without joint 'y' ignored (another machine's bridge?)"
    executive.bridge_report("")
    assert not executive.heard_bridge and executive.position is None
    assert executive.feedback({**ORIGIN, "x": 0.003}) == ""
    assert executive.position == {**ORIGIN, "x": 0.003}


def test_abort_with_stop_runs_a_stop_then_reports_aborted():
    sim = Sim()
    sim.submit(move_job("stopme", [{"linear": {"x": 30}, "feed": 1200}]))
    sim.run_for(1.0)
    assert sim.ex.abort("operator", sim.now) == []
    final = sim.run_job("stopme")
    assert final.state == "aborted" and final.reason == "operator"
    t, p, v, _ = stitched([c for _, c, _ in sim.chunks])
    assert_within_limits(p, 1e-3)
    assert np.all(v[-1] == 0.0) and p[-1, 0] < 0.030


# --- a long job, planned segment by segment while it streams --------------------------------
def plate_doc(holes: int) -> dict:
    """drill_row.yaml with ``holes`` holes on a 5 mm grid."""
    doc = load_job_file(Path(__file__).resolve().parents[3] / "config" / "jobs" / "drill_row.yaml")
    doc["job_id"] = f"plate-{holes}"
    doc["drill"]["holes"] = [[-50 + 5 * (i % 20), -50 + 5 * (i // 20)] for i in range(holes)]
    return doc


def test_the_executive_streams_a_long_job_and_reports_holes_and_progress():
    sim = Sim()
    doc = plate_doc(SEGMENT_HOLES + 10)
    status = sim.submit(json.dumps(doc))
    assert status.state == "accepted" and status.duration_s > 0
    final = sim.run_job(doc["job_id"], limit_s=120)
    assert final.state == "succeeded"
    chunks = [c for _, c, _ in sim.chunks]
    for a, b in zip(chunks, chunks[1:]):
        assert b.stamp_ns == a.end_ns + a.period_ns  # contiguous: nothing lost, repeated or overlapping
    assert [e["hole"] for e in sim.events if e["name"] == "S1"] == list(range(SEGMENT_HOLES + 10))
    running = [s for _, s in sim.statuses if s.state == "running"]
    progress = [s.progress for s in running]
    assert progress == sorted(progress) and progress[-1] > 0.95
    assert running[-1].detail["S3"] >= SEGMENT_HOLES + 9
    _, p, _, _ = stitched(chunks)
    dt = MS / NS  # within velocity and acceleration (the X/Y compensation may exceed the jerk, see kinds/drill/xy_moves.py)
    for k, joint in enumerate(MILL.joint_names):
        assert np.abs(np.diff(p[:, k])).max() / dt <= MILL.axes[joint].max_velocity * (1 + 1e-6), joint
        assert np.abs(np.diff(p[:, k], 2)).max() / dt**2 <= MILL.axes[joint].max_acceleration * (1 + 1e-6), joint



# --- goals prepared off the executive's thread ----------------------------------------------
def test_goals_prepared_at_once_are_admitted_in_order_and_one_id_only_once():
    ex = Executive(MILL)
    first, again, other = (ex.prepare(move_job(i, DEMO)) for i in ("a", "a", "b"))
    assert [ex.admit(p).state for p in (first, again, other)] == ["accepted", "rejected", "accepted"]
    assert [job.job_id for job in ex.queue] == ["a", "b"]


def test_a_cancel_that_overtakes_its_goal_cancels_it_as_it_is_admitted():
    ex = Executive(MILL)
    prepared = ex.prepare(move_job("late", DEMO))
    assert ex.cancel("late", 0, preparing=True) == []
    status = ex.admit(prepared)
    assert (status.state, status.reason) == ("canceled", "canceled before it started") and not ex.queue
    assert ex.cancel("never-sent", 0) == [] and "never-sent" not in ex.cancel_early  # nothing in preparation


def test_a_job_whose_later_segment_cannot_be_planned_ends_aborted_at_rest(monkeypatch):
    import cnc_planner.executive as executive
    real = executive.plan_segments

    def first_only(job, machine, start=None):
        segments = real(job, machine, start)
        yield next(segments)
        raise JobError("drill", "no safe timing found against the servo lag")

    monkeypatch.setattr(executive, "plan_segments", first_only)
    sim = Sim()
    doc = plate_doc(SEGMENT_HOLES + 10)
    assert sim.submit(json.dumps(doc)).state == "accepted"
    final = sim.run_job(doc["job_id"], limit_s=120)
    assert (final.state, final.reason) == ("aborted", "stopped where planning did: drill: no safe timing found "
                                                      "against the servo lag")
    last = sim.chunks[-1][1]
    assert np.all(last.velocities[-1] == 0.0) and np.all(last.accelerations[-1] == 0.0)
    assert [e["hole"] for e in sim.events if e["name"] == "S1"] == list(range(SEGMENT_HOLES))


def test_no_job_starts_until_the_bridge_is_heard_healthy():
    """A planner restarted beside a bridge whose alarm is still latched (its last planner
    died mid-job) would have every setpoint refused: it waits for an alarm-free report."""
    sim = Sim()
    sim.ex.bridge_alarm = None  # nothing heard from the bridge yet
    sim.submit(move_job("waits", DEMO))
    for report in (None, "setpoint buffer ran dry while moving: holding"):
        if report is not None:
            sim.ex.bridge_report(report)
        for _ in range(5):
            sim.tick()
            sim.now += STEP_NS
        assert not sim.chunks and sim.ex.active is None
        # what the planner's heartbeat says (a session submits once it is so): the axes'
        # position is known from the first tick's feedback, the bridge's state from a report
        assert sim.ex.heard_bridge == (report is not None)
    sim.ex.bridge_report("")  # the alarm was reset
    assert sim.run_job("waits").state == "succeeded"


def test_setpoints_run_further_ahead_while_a_goal_is_planned_beside_the_stream():
    sim = Sim()
    sim.submit(move_job("long", [{"rapid": {"x": 100}}, {"linear": {"x": 0}, "feed": 300}]))
    sim.run_until(lambda: sim.ex.active is not None and sim.ex.active.stream is not None)
    sim.run_for(0.5)
    stream = sim.ex.active.stream
    ahead = stream.served_until_ns - sim.now
    assert sim.ex.settings.lookahead_ns <= ahead < sim.ex.settings.lookahead_ns + 100 * MS
    sim.ex.tick(sim.now, planning=True)  # a goal arrived: it is planned on another thread
    ahead = stream.served_until_ns - sim.now
    assert sim.ex.settings.planning_lookahead_ns <= ahead < sim.ex.settings.planning_lookahead_ns + 100 * MS


def test_setpoints_stay_ahead_of_the_clock_when_the_feedback_arrives_late():
    """Real time under CPU load: the latest feedback the planner has heard is 200 ms old,
    but the bridge's clock (the wall, as the planner reads it) is now: the stream is kept
    a lookahead ahead of the clock, and the job still ends on the feedback."""
    sim = Sim()
    sim.submit(move_job("late", [{"rapid": {"x": 100}}, {"linear": {"x": 0}, "feed": 300}]))
    sim.run_until(lambda: sim.ex.active is not None and sim.ex.active.stream is not None)
    sim.run_for(0.5)
    stream = sim.ex.active.stream
    clock = sim.now + 200 * MS
    sim.ex.tick(sim.now, clock_ns=clock)
    ahead = stream.served_until_ns - clock
    assert sim.ex.settings.lookahead_ns <= ahead < sim.ex.settings.lookahead_ns + 100 * MS
    served = stream.served_until_ns
    sim.ex.tick(sim.now, clock_ns=sim.now - 50 * MS)  # a clock behind the feedback: the feedback counts
    assert stream.served_until_ns == served
    end = sim.ex.tick(stream.end_ns - MS, clock_ns=stream.end_ns + 10 * MS)
    assert sim.ex.active is not None and not [s for s in end.statuses if s.state == "succeeded"]


def first_chunks(sim: Sim):
    """Tick (feedback at rest) until the executive hands out the job's first chunks."""
    sim.ex.feedback(dict(zip(MILL.joint_names, sim.position.tolist())))
    while not (out := sim.ex.tick(sim.now)).chunks:
        sim.now += STEP_NS
    return out


def test_a_first_chunk_made_late_is_retimed_on_the_grid_not_sent_stale():
    """The bridge's clock ran 1 s on between the feedback that started the job and the
    moment its first chunk is published (a stalled planner): the job starts later instead."""
    sim = Sim()
    sim.submit(move_job("late", DEMO))
    out = first_chunks(sim)
    assert out.chunks[0].stamp_ns == sim.settings.start_delay_ns  # as planned: the delay after the start
    bridge_now = sim.now + NS  # 1 s later the chunk would be 0.6 s in the past
    sim.ex.retime(out, bridge_now)
    first = out.chunks[0]
    assert first.stamp_ns - bridge_now >= sim.settings.min_lead_ns
    assert first.stamp_ns % sim.settings.period_ns == 0
    assert all(b.stamp_ns == a.end_ns + a.period_ns for a, b in zip(out.chunks, out.chunks[1:]))
    assert out.events[0]["stamp_ns"] == first.stamp_ns  # the first move's mark moved with it
    # Published now, the rest of the job streams on from the new start, and it succeeds.
    sim.now = bridge_now
    for chunk in out.chunks:
        times = chunk.stamp_ns + np.arange(len(chunk.positions)) * chunk.period_ns
        sim.bridge.insert(sim.bridge.validate(list(chunk.joints), times, chunk.positions, chunk.velocities,
                                              chunk.accelerations, sim.now, (sim.position, np.zeros_like(sim.position))))
        sim.chunks.append((sim.now, chunk, "late"))
    sim.ex.retime(out, bridge_now + 10 * MS)  # once on its way, a stream is never moved again
    assert out.chunks[0].stamp_ns == first.stamp_ns
    final = sim.run_job("late")
    assert final.state == "succeeded"
    times = stitched([c for _, c, _ in sim.chunks])[0]
    assert np.all(np.diff(times) == sim.settings.period_ns)


def test_a_first_chunk_with_lead_enough_is_not_moved():
    sim = Sim()
    sim.submit(move_job("ontime", DEMO))
    out = first_chunks(sim)
    stamp = out.chunks[0].stamp_ns
    sim.ex.retime(out, stamp - sim.settings.min_lead_ns)
    assert out.chunks[0].stamp_ns == stamp
