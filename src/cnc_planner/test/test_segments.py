"""Long jobs planned segment by segment (segments.py) and served ahead of the stream
(lookahead.py): the joins are continuous, events are numbered over the whole job, the
feedback stays safe across drill joins, bad jobs are still rejected whole, and a
segment that cannot be planned ends the job at rest."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import NS, mm
from cnc_planner.planning import plan_job
from cnc_planner.kinds.drill.block import drill_cycle
from cnc_planner.kinematics import Kinematics
from cnc_planner.lookahead import JobPlan
from cnc_planner.segments import plan_segments, segment_count
from cnc_planner.kinds.drill import SEGMENT_HOLES
from cnc_planner.kinds.move import SEGMENT_MOVES
from cnc_planner.streaming import SetpointStream
from cnc_planner.motion.timeline import Plan
from cnc_analysis.drilling import analyze_drilling
from cnc_servo_bridge.drive import DriveModel

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
MILL = load_machine("mill3")
HOME = MILL.home_joints
HOLES = SEGMENT_HOLES * 2 + 20  # three segments, the last one short
PERIOD = 1e-3


def drill_doc(holes: int = HOLES) -> dict:
    doc = load_job_file(JOBS / "drill_row.yaml")
    doc["job_id"] = f"plate-{holes}"
    doc["drill"]["holes"] = [[-50 + 5 * (i % 20), -50 + 5 * (i // 20)] for i in range(holes)]
    return doc


@pytest.fixture(scope="module")
def drill_segments() -> list[Plan]:
    return list(plan_segments(parse_job(drill_doc()), MILL, HOME))


def joined(plans: list[Plan]) -> JobPlan:
    """The segments laid end to end, all planned."""
    plan = JobPlan(iter(plans), len(plans), PERIOD)
    plan.wait_until(float("inf"))
    return plan


def test_a_long_drill_job_is_cut_into_segments_that_join_at_rest(drill_segments):
    assert segment_count(parse_job(drill_doc())) == len(drill_segments) == 3
    for before, after in zip(drill_segments, drill_segments[1:]):
        end, start = before.final_position(), after.start_position()
        assert all(abs(end[j] - start[j]) < 1e-12 for j in MILL.joint_names)
        # the spindle keeps turning at the job's speed across the join
        speed = 2 * np.pi * 3000 / 60
        assert before.timelines[SPINDLE].end_velocity == pytest.approx(speed)
        assert after.sample(np.array([0.0]))[1][0, MILL.joint_names.index(SPINDLE)] == pytest.approx(speed)
        _, v, a = before.sample(np.array([before.duration]))
        axes = [MILL.joint_names.index(j) for j in ("x", "y", "z")]
        assert np.all(v[0, axes] == 0.0) and np.all(a[0, axes] == 0.0)
    assert drill_segments[-1].timelines[SPINDLE].end_velocity == 0.0  # stopped at the very end


def test_events_are_numbered_over_the_whole_job(drill_segments):
    plan = joined(drill_segments)
    events = plan.pop_events(1e9)
    assert [e.data["hole"] for e in events if e.name == "S1"] == list(range(HOLES))
    assert [e.name for e in events].count("job_start") == 1 and events[0].name == "job_start"
    assert [e.name for e in events].count("job_end") == 1 and events[-1].name == "job_end"
    assert all(a.time <= b.time for a, b in zip(events, events[1:]))


def test_the_feedback_is_safe_across_the_joins_and_the_joins_cost_little(drill_segments):
    plan = joined(drill_segments)
    ts = np.arange(int(np.ceil(plan.duration / PERIOD)) + 300) * PERIOD
    p, v, a = plan.sample(ts)
    feedback, _ = DriveModel(MILL, PERIOD, MILL.joint_names).simulate(p, v, a)
    job = parse_job(drill_doc())
    cycle = drill_cycle(job, MILL, Kinematics(MILL, job.setup, job.tool))
    cols = [MILL.joint_names.index(j) for j in ("x", "y", "z")]
    result = analyze_drilling(ts, *feedback[:, cols].T, cycle.holes, cycle.r_z, cycle.xy_tolerance, cycle.surface_z)
    assert result["safety_violations"] == 0 and len(result["holes"]) == HOLES
    whole = plan_job(job, MILL, HOME)
    # one exact stop per join instead of an overlapped transition: well under 0.2 s each
    assert whole.duration < plan.duration < whole.duration + 0.2 * (len(drill_segments) - 1)


def test_a_bad_hole_in_a_late_segment_is_rejected_before_anything_is_planned():
    doc = drill_doc()
    doc["drill"]["holes"][-1] = [900.0, 0.0]
    segments = plan_segments(parse_job(doc), MILL)
    with pytest.raises(JobError) as err:
        next(segments)
    assert err.value.field == f"drill.holes[{HOLES - 1}]"


def test_a_move_program_in_segments_reaches_every_target_as_planned_whole():
    moves = [{"linear": {"x": 10.0 * (i % 2), "y": 0.01 * i}, "feed": 3000} for i in range(1, SEGMENT_MOVES + 41)]
    doc = {"schema": "cnc_job/1", "job_id": "long-program", "kind": "move", "machine": "mill3",
           "spindle_rpm": 1000, "move": moves}
    job = parse_job(doc)
    plans = list(plan_segments(job, MILL))
    assert len(plans) == 2
    plan = joined(plans)
    events = plan.pop_events(1e9)
    starts = [e.time for e in events if e.name == "linear"]
    assert [e.data["move"] for e in events if e.name == "linear"] == list(range(len(moves)))
    p, _, _ = plan.sample(np.array(starts[1:] + [plan.duration]))
    x, y = MILL.joint_names.index("x"), MILL.joint_names.index("y")
    np.testing.assert_allclose(p[:, x], [mm(m["linear"]["x"]) for m in moves], atol=1e-12)
    np.testing.assert_allclose(p[:, y], [mm(m["linear"]["y"]) for m in moves], atol=1e-12)
    whole = plan_job(job, MILL)
    assert whole.duration <= plan.duration < whole.duration + PERIOD  # the join lands on the grid


def test_only_a_few_segments_are_held_while_streaming(drill_segments):
    plan = JobPlan(iter(drill_segments), len(drill_segments), PERIOD, ahead=10.0)
    stream = SetpointStream(plan, 0, int(PERIOD * NS), 100)
    held = []
    while not stream.done:
        stream.next_chunk()
        held.append(plan.segments_held)
    assert max(held) <= 2 and held[-1] == 1


def test_a_segment_that_cannot_be_planned_ends_the_job_at_rest(drill_segments):
    def segments():
        yield from drill_segments[:2]
        raise JobError("drill", "no safe timing found against the servo lag")

    plan = JobPlan(segments(), 3, PERIOD)
    stream = SetpointStream(plan, 0, int(PERIOD * NS), 100)
    chunks = []
    while not stream.done:
        chunks.append(stream.next_chunk())
    assert plan.error == "drill: no safe timing found against the servo lag"
    end = drill_segments[0].duration
    assert plan.duration == pytest.approx(np.ceil(end / PERIOD - 1e-9) * PERIOD + drill_segments[1].duration)
    assert np.all(chunks[-1].velocities[-1] == 0.0)
