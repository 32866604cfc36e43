"""The path job without ROS: limits by finite differences, the tip on the programmed line
(commanded and on the simulated drives' feedback), exact stops, rejections by field."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import mm
from cnc_planner.planning import plan_job
from cnc_planner.kinematics import Kinematics, KinematicsError
from cnc_planner.kinds.path.report import _segment_distances, distance_to_polyline, path_figures, tip_deviations
from cnc_planner.prediction import simulated_feedback

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
PERIOD = 1e-3  # the bridge's servo period and the planner's interpolation period
LIMIT_SLACK = 1e-6  # relative: rounding of ruckig profiles sampled at 1 ms


def tilted(angle_deg: float, azimuth_deg: float = 0.0) -> list[float]:
    a, z = math.radians(angle_deg), math.radians(azimuth_deg)
    return [math.sin(a) * math.cos(z), math.sin(a) * math.sin(z), math.cos(a)]


def path_doc(machine: str, points, tool_axis=None, feed=1000.0, tol=0.01, **extra) -> dict:
    path = {"points": points, "feed": feed, "chord_tolerance": tol}
    if tool_axis is not None:
        path["tool_axis"] = tool_axis
    return {"schema": "cnc_job/1", "job_id": "p", "kind": "path", "machine": machine,
            "tool": {"length": 60.0}, "path": path, **extra}


ARC = [[20 * math.cos(x), 20 * math.sin(x), -1.0] for x in np.linspace(0.0, 2 * math.pi, 200)]
CASES = {
    "path_5ax_tilt": load_job_file(JOBS / "path_5ax_tilt.yaml"),
    "path_mill3": load_job_file(JOBS / "path_mill3.yaml"),
    # C turns 90 deg on the spot at the vertical middle point, tip off the C axis
    "c_turn_head_table": path_doc("5ax_head_table", [[80, 0, 0], [80, 30, 0], [50, 60, -10]],
                                  [tilted(20, 0), [0, 0, 1], tilted(20, 90)], tol=0.002),
    "c_turn_table_table": path_doc("5ax_table_table", [[80, 0, 0], [80, 30, 0], [50, 60, -10]],
                                   [tilted(20, 0), [0, 0, 1], tilted(20, 90)], tol=0.002),
    # a finely sampled circle at a high feed: no stops, the velocity steps bind
    "arc_mill3_fast": path_doc("mill3", ARC, feed=6000.0),
}


def planned(doc: dict):
    job = parse_job(doc)
    machine = load_machine(job.machine)
    plan = plan_job(job, machine)
    t = np.arange(int(np.ceil(plan.duration / PERIOD)) + 1) * PERIOD
    p, v, a = plan.sample(t)
    events = {e.name: e for e in plan.events}
    return job, machine, plan, t, p, v, a, events


@pytest.mark.parametrize("case", CASES)
def test_every_joint_within_its_velocity_and_acceleration_by_finite_differences(case):
    _, machine, plan, _, p, v, a, _ = planned(CASES[case])
    for i, name in enumerate(plan.joints):
        axis = machine.axes[name]
        fd_v = np.abs(np.diff(p[:, i])) / PERIOD
        fd_a = np.abs(np.diff(p[:, i], 2)) / PERIOD ** 2
        assert fd_v.max() <= axis.max_velocity * (1 + LIMIT_SLACK), name
        assert fd_a.max() <= axis.max_acceleration * (1 + LIMIT_SLACK), name
        # and what the setpoints say about themselves (the bridge checks these)
        assert np.abs(v[:, i]).max() <= axis.max_velocity * (1 + LIMIT_SLACK), name
        assert np.abs(a[:, i]).max() <= axis.max_acceleration * (1 + LIMIT_SLACK), name


@pytest.mark.parametrize("case", CASES)
def test_commanded_tip_within_the_chord_tolerance_and_at_the_feed(case):
    job, machine, plan, t, p, _, _, ev = planned(CASES[case])
    kin = Kinematics(machine, job.setup, job.tool)
    on = (t >= ev["path_start"].time - 1e-9) & (t <= ev["path_end"].time + 1e-9)
    joints = {j: p[on, parse_column(machine, j)] for j in kin.joints}
    assert tip_deviations(kin, joints, np.array(job.path.points)).max() <= job.path.chord_tolerance
    tips, _ = kin.fk_many(joints)
    # The waypoints are timed by their chords at the feed; between them the tip runs on an
    # arc within the chord tolerance, a little longer: the speed may exceed the feed by a hair.
    speed = np.linalg.norm(np.diff(tips, axis=0), axis=1) / PERIOD
    assert speed.max() <= job.path.feed * 1.005
    ends = plan.sample(np.array([ev["path_start"].time, ev["path_end"].time]))[0]
    ends, _ = kin.fk_many({j: ends[:, parse_column(machine, j)] for j in kin.joints})
    assert ends == pytest.approx(np.array(job.path.points)[[0, -1]], abs=1e-12)


def parse_column(machine, joint: str) -> int:
    return machine.joint_names.index(joint)


def test_the_5_axis_tilt_is_one_profile_at_the_feed():
    job, machine, plan, t, p, v, _, ev = planned(CASES["path_5ax_tilt"])
    start, end = ev["path_start"], ev["path_end"]
    assert start.data["stops"] == 0 and start.data["waypoints"] > 10
    assert end.data["chord_tolerance"] == pytest.approx(mm(0.01))
    assert start.data["feed"] == pytest.approx(job.path.feed)
    # 60 mm at 600 mm/min is 6 s; one jerk-limited ramp up and down costs a few ms
    assert 6.0 < end.time - start.time < 6.1
    kin = Kinematics(machine, job.setup, job.tool)
    on = (t >= start.time) & (t <= end.time)
    tips, axes = kin.fk_many({j: p[on, parse_column(machine, j)] for j in kin.joints})
    speed = np.linalg.norm(np.diff(tips, axis=0), axis=1) / PERIOD
    assert speed.max() == pytest.approx(job.path.feed, rel=1e-3)
    tilt = np.degrees(np.arccos(np.clip(axes[:, 2], -1, 1)))
    assert np.all(np.diff(tilt) >= 0.0) and tilt[-1] == pytest.approx(30.0, abs=1e-5)
    # the rapid put every joint on the first pose, at rest, by path_start
    at_start = [x[0] for x in plan.sample(np.array([start.time]))]
    tip, axis = kin.fk_many({j: [at_start[0][parse_column(machine, j)]] for j in kin.joints})
    assert tip[0] == pytest.approx(job.path.points[0], abs=1e-12)
    assert axis[0] == pytest.approx(job.path.tool_axis[0], abs=1e-12)
    for j in kin.joints:
        assert at_start[1][parse_column(machine, j)] == pytest.approx(0.0, abs=1e-12)
    assert at_start[0][parse_column(machine, "c")] == pytest.approx(-math.pi / 2, abs=1e-9)  # lean to +Y


def test_polyline_corners_are_exact_stops():
    job, machine, plan, t, p, v, _, ev = planned(CASES["path_mill3"])
    assert ev["path_start"].data["stops"] == 4  # every corner of plunge, rectangle, retract
    xyz = [parse_column(machine, j) for j in "xyz"]
    # one rest-to-rest traverse per side: they end on the corners, at rest
    ends = np.array([piece.end for piece in plan.timelines["x"].pieces if piece.start >= ev["path_start"].time - 1e-12])
    assert len(ends) == 5
    pos, vel, _ = plan.sample(ends)
    assert pos[:, xyz] == pytest.approx(np.array(job.path.points[1:]), abs=1e-12)
    assert np.abs(vel[:, xyz]).max() < 1e-9
    # straight sides run at the feed
    on = (t >= ev["path_start"].time) & (t <= ev["path_end"].time)
    assert np.linalg.norm(v[on][:, xyz], axis=1).max() == pytest.approx(job.path.feed, rel=1e-6)


def test_c_turn_on_the_spot_runs_through_instead_of_stopping_every_step():
    *_, ev = planned(CASES["c_turn_head_table"])
    assert ev["path_start"].data["waypoints"] > 50
    assert ev["path_start"].data["stops"] <= 4


@pytest.mark.parametrize("case", ["path_5ax_tilt", "path_mill3", "c_turn_table_table"])
def test_feedback_of_the_drive_model_within_tolerance_plus_servo_lag(case):
    job, machine, plan, *_ = planned(CASES[case])
    t, fb = simulated_feedback(plan, machine)
    p, _, _ = plan.sample(t)
    ev = {e.name: e.time for e in plan.events}
    kin = Kinematics(machine, job.setup, job.tool)
    cols = [parse_column(machine, j) for j in kin.joints]
    on = (t >= ev["path_start"] - 1e-9) & (t <= ev["path_end"] + 1e-9)
    settle = (t >= ev["path_start"] - 1e-9) & (t <= ev["path_end"] + 0.5)
    figures = path_figures(kin, np.array(job.path.points), t, p[:, cols], on, t[settle], fb[settle][:, cols],
                           job.path.chord_tolerance)
    tol = figures["chord_tolerance_mm"]
    assert tol == pytest.approx(job.path.chord_tolerance * 1e3)
    assert figures["commanded_max_tip_deviation_mm"] <= tol
    # velocity feed-forward: lag only where joints accelerate; most where C turns a table
    # carrying the tip 80 mm off its axis at full speed (the C drive lags more than X/Y)
    assert 0.0 < figures["servo_lag_mm"] < (0.2 if case.startswith("c_turn") else 0.05)
    assert figures["max_tip_deviation_mm"] <= tol + figures["servo_lag_mm"]


def test_distance_to_polyline_matches_brute_force():
    rng = np.random.default_rng(7)
    vertices = np.cumsum(rng.normal(size=(300, 3)), axis=0)
    walk = vertices[:-1] + rng.uniform(size=(299, 1)) * np.diff(vertices, axis=0)
    points = np.repeat(walk, 7, axis=0) + rng.normal(scale=0.3, size=(299 * 7, 3))
    brute = _segment_distances(points, vertices[:-1], vertices[1:]).min(axis=1)
    assert distance_to_polyline(points, vertices) == pytest.approx(brute, abs=1e-12)
    alone = np.linalg.norm(points[:3] - vertices[0], axis=1)
    assert distance_to_polyline(points[:3], vertices[:1]) == pytest.approx(alone)


# --- rejections, named by field ----------------------------------------------------------------

def rejected(doc: dict) -> JobError:
    job = parse_job(doc)
    with pytest.raises(JobError) as err:
        plan_job(job, load_machine(job.machine))
    return err.value


def test_unreachable_tilt_rejected_with_the_point_and_axis_named():
    err = rejected(path_doc("5ax_head_table", [[0, 0, 0], [10, 0, 0], [20, 0, 0]],
                            [tilted(0), tilted(60), tilted(100)]))
    assert isinstance(err, KinematicsError)
    assert err.field == "path.points[2]"
    assert "axis b" in err.reason and "90 deg" in err.reason


def test_point_beyond_linear_travel_rejected_with_the_point_named():
    err = rejected(path_doc("mill3", [[0, 0, 0], [100, 0, 0], [600, 0, 0]]))
    assert err.field == "path.points[2]"
    assert "axis x" in err.reason and "500 mm" in err.reason


def test_path_kind_rejects_what_it_cannot_do():
    assert rejected(path_doc("mill3", [[0, 0, 0], [10, 0, 0]], spindle_rpm=1000,
                             vibration={"D": 1.5, "Q": 1.2})).field == "vibration"
    assert rejected(path_doc("lathe", [[10, 0, 0], [10, 0, -20]], spindle_rpm=500)).field == "spindle_rpm"
    assert rejected(path_doc("mill3", [[0, 0, 0], [10, 0, 0]], [[0, 0, 1], tilted(10)])).field == "path.points[1]"


def test_a_lathe_path_positions_the_spindle_as_c():
    job, machine, plan, t, p, *_ = planned(path_doc("lathe", [[10, 0, 2], [10, 0, -20], [14, 0, -25]], feed=300))
    final = plan.final_position()
    assert (final["x"], final["z"]) == pytest.approx((mm(14.0 + 60.0), mm(-25.0)), abs=1e-12)  # x reads the turret
    assert np.abs(p[:, parse_column(machine, "spindle")]).max() == 0.0


def test_repeated_points_and_a_standing_path_plan():
    _, _, plan, *_, ev = planned(path_doc("mill3", [[0, 0, 0], [10, 0, 0], [10, 0, 0], [10, 5, 0]]))
    assert ev["path_start"].data["stops"] == 1
    _, _, plan, *_, ev = planned(path_doc("mill3", [[5, 5, 5], [5, 5, 5]]))
    assert ev["path_end"].time == ev["path_start"].time and ev["path_start"].data["stops"] == 0
    assert plan.final_position()["x"] == pytest.approx(mm(5.0))
