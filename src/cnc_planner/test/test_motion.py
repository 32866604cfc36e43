"""Jerk-limited motion primitives, the plan builder and joint timelines.

Limits are checked on the sampled setpoints by finite differences at the 1 ms
interpolation period: for a trajectory whose jerk is bounded by J, the k-th divided
difference is a weighted mean of the k-th derivative, so |dp/dt| <= V, |d2p/dt2| <= A and
|d3p/dt3| <= J hold for the samples too (up to floating-point noise).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.planning import plan_job
from cnc_planner.motion.moves import LinearMove, Limits, MotionError, path_limits, point_to_point, velocity_change
from cnc_planner.motion.timeline import JointTimeline, Piece

MILL = load_machine("mill3")
LATHE = load_machine("lathe")
DT = 1e-3
REL = 1e-6  # relative slack on the limits for floating-point noise
LINEAR = ("x", "y", "z")


def grid(duration: float, dt: float = DT, extra: float = 0.05, offset: float = 0.0) -> np.ndarray:
    n = int(math.ceil((duration + extra) / dt)) + 1
    return offset + np.arange(n) * dt


def assert_within_limits(machine, joints, p, v, a, dt=DT):
    """Finite differences of sampled positions, and the sampled v and a, within each axis's limits."""
    for k, joint in enumerate(joints):
        axis = machine.axes[joint]
        vel = np.diff(p[:, k]) / dt
        acc = np.diff(p[:, k], 2) / dt**2
        jerk = np.diff(p[:, k], 3) / dt**3
        assert np.abs(vel).max() <= axis.max_velocity * (1 + REL) + 1e-9, joint
        assert np.abs(acc).max() <= axis.max_acceleration * (1 + REL) + 1e-6, joint
        assert np.abs(jerk).max() <= axis.max_jerk * (1 + REL) + 1e-3, joint
        assert np.abs(v[:, k]).max() <= axis.max_velocity * (1 + REL), joint
        assert np.abs(a[:, k]).max() <= axis.max_acceleration * (1 + REL), joint


def assert_velocity_matches_positions(machine, joints, p, v, dt=DT):
    """Sampled velocity is the derivative of sampled position (central difference error <= J dt^2)."""
    for k, joint in enumerate(joints):
        central = (p[2:, k] - p[:-2, k]) / (2 * dt)
        assert np.abs(central - v[1:-1, k]).max() <= machine.axes[joint].max_jerk * dt**2 + 1e-9, joint


# --- rapids ---------------------------------------------------------------------------------

RAPIDS = [
    ({"x": 0.0, "y": 0.0, "z": 0.0}, {"x": 0.4, "y": 0.0, "z": 0.0}),  # long: reaches max velocity
    ({"x": 0.0, "y": 0.0, "z": 0.0}, {"x": 0.0005, "y": 0.0, "z": 0.0}),  # 0.5 mm: never reaches a_max
    ({"x": -0.2, "y": 0.1, "z": 0.05}, {"x": 0.3, "y": -0.25, "z": -0.2}),  # three axes, different lengths
    ({"x": 0.1, "y": 0.1, "z": 0.0}, {"x": 0.1, "y": 0.1, "z": -0.29}),  # z alone
]


@pytest.mark.parametrize("start, target", RAPIDS)
def test_rapid_within_limits_and_ends_at_target_at_rest(start, target):
    builder = PlanBuilder(MILL, start)
    end = builder.rapid(target)
    plan = builder.build()
    assert plan.duration == pytest.approx(end)
    ts = grid(plan.duration)
    p, v, a = plan.sample(ts)
    assert_within_limits(MILL, plan.joints, p, v, a)
    assert_velocity_matches_positions(MILL, plan.joints, p, v)
    # Starts where it was, at rest; ends exactly at the target, at rest.
    for k, joint in enumerate(LINEAR):
        assert p[0, k] == start[joint] and v[0, k] == 0.0
        after = ts >= plan.duration
        assert np.all(p[after, k] == target[joint]), joint
        assert np.all(v[after, k] == 0.0) and np.all(a[after, k] == 0.0)
        assert builder.position(joint) == target[joint]
        # ruckig's own end state, just before the end, is already at the target
        q, w, _ = plan.timelines[joint].sample(np.array([plan.duration - 1e-9]))
        assert q[0] == pytest.approx(target[joint], abs=1e-9) and abs(w[0]) < 1e-6
    assert plan.final_position()["x"] == target["x"]
    # the spindle never moved
    assert np.all(p[:, plan.joints.index(SPINDLE)] == 0.0)


def test_long_rapid_is_time_optimal_at_max_velocity():
    builder = PlanBuilder(MILL, {"x": 0.0})
    builder.rapid({"x": 0.4})
    plan = builder.build()
    _, v, _ = plan.sample(grid(plan.duration))
    # It cruises at exactly max velocity, and for x (V=0.8, A=9.8, J=200) the
    # acceleration phase takes A/J + V/A = 0.049 + 0.0816 s, so the move takes
    # 0.4/0.8 + 0.049 + 0.08163 = 0.63063 s.
    assert np.abs(v[:, 0]).max() == pytest.approx(0.8, rel=1e-9)
    assert plan.duration == pytest.approx(0.4 / 0.8 + 9.8 / 200 + 0.8 / 9.8, rel=1e-6)


def test_short_rapid_duration_hand_computed():
    # A tiny move stays in the jerk-only regime: four jerk phases of T each,
    # distance = 2 J T^3  ->  T = (d / (2 J))^(1/3).
    d = 1e-6
    builder = PlanBuilder(MILL, {"x": 0.0})
    builder.rapid({"x": d})
    t = (d / (2 * 200.0)) ** (1 / 3)
    assert builder.build().duration == pytest.approx(4 * t, rel=1e-6)


@pytest.mark.parametrize("start, target", RAPIDS[2:3])
def test_rapid_axes_start_and_arrive_together(start, target):
    builder = PlanBuilder(MILL, start)
    builder.rapid({"x": 0.0, "y": 0.0, "z": 0.0})  # a first move: the rapid under test starts later
    begin = builder.end_time()
    end = builder.rapid(target)
    plan = builder.build()
    pieces = [plan.timelines[j].pieces[-1] for j in LINEAR]
    assert {pc.start for pc in pieces} == {begin}
    assert {pc.end for pc in pieces} == {end}
    # from the instant the first move has ended (all at rest) to after the rapid
    ts = begin + np.arange(int((end - begin) / DT) + 20) * DT
    _, v, _ = plan.sample(ts)
    moving = np.abs(v[:, :3]) > 0.0
    inside = (ts > begin) & (ts < end)
    assert not np.any(moving[0]) and inside[1] and inside[-20]
    assert np.all(moving[inside]), "every axis moves from the first to the last instant"
    assert not np.any(moving[~inside])


def test_rapid_to_where_it_is_plans_nothing():
    builder = PlanBuilder(MILL, {"x": 0.1})
    assert builder.rapid({"x": 0.1}) == 0.0
    assert builder.rapid_move({"x": 0.1}) is None
    assert builder.build().duration == 0.0


def test_rapid_move_predicts_the_rapid():
    builder = PlanBuilder(MILL, {"x": 0.1})
    predicted = builder.rapid_move({"x": 0.2, "y": 0.05})
    assert builder.rapid({"x": 0.2, "y": 0.05}) == pytest.approx(predicted.duration)


# --- linear moves ----------------------------------------------------------------------------

LINES = [
    ((0.0, 0.0, 0.0), (0.03, 0.0, 0.0), 0.02),  # along x, 1200 mm/min
    ((0.0, 0.0, 0.0), (0.03, 0.04, -0.01), 0.02),  # three axes
    ((0.01, -0.02, 0.05), (0.0, 0.0, 0.0), 0.001),  # slow, 60 mm/min
    ((0.0, 0.0, 0.0), (0.3, 0.1, -0.2), 5.0),  # feed beyond the axes: limits projected on the path
]


@pytest.mark.parametrize("start, end, feed", LINES)
def test_linear_move_is_straight_at_most_at_feed_within_limits(start, end, feed):
    builder = PlanBuilder(MILL, dict(zip(LINEAR, start)))
    builder.linear(dict(zip(LINEAR, end)), feed)
    plan = builder.build()
    ts = grid(plan.duration)
    p, v, a = plan.sample(ts)
    assert_within_limits(MILL, plan.joints, p, v, a)
    assert_velocity_matches_positions(MILL, plan.joints, p, v)
    xyz = p[:, :3]
    p0, p1 = np.array(start), np.array(end)
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    rel = xyz - p0
    perpendicular = rel - np.outer(rel @ u, u)
    assert np.linalg.norm(perpendicular, axis=1).max() < 1e-9
    along = rel @ u
    assert along.min() >= -1e-12 and along.max() <= np.linalg.norm(p1 - p0) + 1e-12
    speed = np.linalg.norm(np.diff(xyz, axis=0), axis=1) / DT
    assert speed.max() <= feed * (1 + 1e-9)
    assert np.linalg.norm(v[:, :3], axis=1).max() <= feed * (1 + 1e-9)
    # ends exactly at the target, at rest
    assert np.all(xyz[ts >= plan.duration] == p1)
    assert np.all(v[ts >= plan.duration, :3] == 0.0)


def test_linear_move_cruises_at_the_feed():
    builder = PlanBuilder(MILL, {"x": 0.0, "y": 0.0})
    builder.linear({"x": 0.03, "y": 0.04}, 0.02)  # 50 mm at 20 mm/s
    plan = builder.build()
    p, v, _ = plan.sample(grid(plan.duration))
    speed = np.linalg.norm(v[:, :2], axis=1)
    assert speed.max() == pytest.approx(0.02, rel=1e-9)
    # 2.5 s at the feed plus the ramp, no more than 0.1 s longer
    assert 2.5 < plan.duration < 2.6
    # velocity components in the 3:4 ratio of the direction
    cruise = speed > 0.019
    assert np.allclose(v[cruise, 0] * 4, v[cruise, 1] * 3, atol=1e-12)


def test_path_limits_projected_by_hand():
    limits = [Limits(0.8, 9.8, 200.0), Limits(0.8, 9.8, 200.0), Limits(0.6, 9.8, 200.0)]
    direction = np.array([0.6, 0.0, 0.8])
    lim = path_limits(direction, limits, feed=None)
    assert lim.velocity == pytest.approx(min(0.8 / 0.6, 0.6 / 0.8))  # z binds: 0.75 m/s
    assert lim.acceleration == pytest.approx(9.8 / 0.8)
    assert lim.jerk == pytest.approx(200.0 / 0.8)
    assert path_limits(direction, limits, feed=0.02).velocity == 0.02


def test_linear_move_zero_length_plans_nothing():
    builder = PlanBuilder(MILL, {"x": 0.1})
    assert builder.linear({"x": 0.1}, 0.02) == 0.0
    assert builder.build().duration == 0.0


def test_linear_move_object_samples_endpoints():
    move = LinearMove(np.array([0.0, 0.0]), np.array([0.003, 0.004]), [Limits(0.8, 9.8, 200.0)] * 2, 0.01)
    assert move.length == pytest.approx(0.005)
    assert move.limits.velocity == 0.01
    t = np.array([0.0, move.duration])
    px, vx, _ = move.sampler(0)(t)
    py, _, _ = move.sampler(1)(t)
    assert px[0] == 0.0 and py[0] == 0.0
    assert px[1] == pytest.approx(0.003, abs=1e-12) and py[1] == pytest.approx(0.004, abs=1e-12)
    assert vx[0] == 0.0 and abs(vx[1]) < 1e-9


def test_point_to_point_refuses_impossible_input():
    with pytest.raises(MotionError, match="ruckig could not plan"):
        point_to_point([0.0], [float("nan")], [Limits(1.0, 1.0, 1.0)])


# --- spindle, waiting, dwell, coasting ------------------------------------------------------

def test_spindle_ramp_reaches_the_speed_and_feed_waits_for_it():
    w = 3000 * 2 * math.pi / 60  # 3000 rpm
    builder = PlanBuilder(MILL, {"x": 0.0, "y": 0.0, "z": 0.0})
    ready = builder.spindle(w)
    assert builder.spindle_ready == ready > 0.0
    linear_end = builder.linear({"z": -0.005}, 0.02)
    plan = builder.build()
    z_piece = plan.timelines["z"].pieces[0]
    assert z_piece.start == ready
    assert linear_end == pytest.approx(ready + z_piece.duration)
    ts = grid(plan.duration)
    p, v, a = plan.sample(ts)
    s = plan.joints.index(SPINDLE)
    assert_within_limits(MILL, plan.joints, p, v, a)
    # z holds until the spindle is at speed
    before = ts <= ready
    assert np.all(p[before, plan.joints.index("z")] == 0.0)
    # the spindle is at speed exactly when the feed starts and while it runs
    at_speed = (ts >= ready) & (ts < linear_end)
    assert np.all(v[at_speed, s] == w)
    # ramp up: speed rises monotonically to w (ruckig, jerk-limited)
    ramp = v[ts < ready, s]
    assert np.all(np.diff(ramp) >= -1e-9) and ramp[-1] <= w
    # the plan stops the spindle at the end
    assert v[-1, s] == 0.0 and plan.timelines[SPINDLE].end_velocity == 0.0


def test_spindle_ramp_duration_hand_computed():
    # From rest to w with A=500 rad/s^2 and J=1e5 rad/s^3: w > A^2/J = 2.5, so
    # the ramp has a constant-acceleration phase: T = w / A + A / J.
    w = 314.159265358979
    builder = PlanBuilder(MILL)
    assert builder.spindle(w) == pytest.approx(w / 500.0 + 500.0 / 1e5, rel=1e-9)
    assert builder.spindle(w) == builder.spindle_ready  # already there: no new piece
    assert len(builder.timelines[SPINDLE].pieces) == 1


def test_rapids_do_not_wait_for_the_spindle():
    builder = PlanBuilder(MILL, {"x": 0.0})
    ready = builder.spindle(300.0)
    builder.rapid({"x": 0.01})
    assert builder.timelines["x"].pieces[0].start == 0.0 < ready


def test_spindle_coasts_at_its_speed_between_pieces():
    w = 200.0
    builder = PlanBuilder(MILL, {"x": 0.0})
    ready = builder.spindle(w)
    end = builder.linear({"x": 0.02}, 0.01)  # 2 s of cutting while the spindle coasts
    plan = builder.build()
    timeline = plan.timelines[SPINDLE]
    ts = np.linspace(ready + 0.01, end - 0.01, 50)
    p, v, a = timeline.sample(ts)
    assert np.all(v == w) and np.all(a == 0.0)
    assert np.allclose(np.diff(p), w * np.diff(ts), rtol=0, atol=1e-9)
    # between the ramp's end state and the coast there is no jump
    p_ready = timeline.sample(np.array([ready]))[0][0]
    assert p[0] == pytest.approx(p_ready + w * (ts[0] - ready), abs=1e-9)
    # after the stop the spindle stands still
    q, u, _ = timeline.sample(np.array([plan.duration, plan.duration + 1.0]))
    assert q[0] == q[1] and u[0] == u[1] == 0.0


def test_timeline_coasting_hand_computed():
    timeline = JointTimeline(1.0)

    def ramp(t):  # from 1.0 at rest, constant acceleration 2 for 1 s: ends at 2.0, v = 2
        return 1.0 + t**2, 2 * t, np.full_like(t, 2.0)

    timeline.add(Piece(0.5, 1.0, ramp), end_position=2.0, end_velocity=2.0)
    p, v, a = timeline.sample(np.array([0.0, 0.5, 1.0, 1.5, 2.5]))
    assert p.tolist() == [1.0, 1.0, 1.25, 2.0, 4.0]
    assert v.tolist() == [0.0, 0.0, 1.0, 2.0, 2.0]
    assert a.tolist() == [0.0, 2.0, 2.0, 0.0, 0.0]
    assert timeline.position_at(3.0) == 5.0
    with pytest.raises(ValueError, match="overlaps"):
        timeline.add(Piece(1.0, 0.2, ramp), 0.0)


def test_timeline_coasts_after_a_piece_between_two_instants():
    """A piece that holds no instant still sets the coast after it, inside one gap between
    other pieces (the coast is evaluated per gap, and per instant where it changes)."""
    timeline = JointTimeline(0.0)

    def push(t):  # from 0 at rest to 0.25 at velocity 1 within 0.5 s
        return t**2, 2 * t, np.full_like(t, 2.0)

    def hold(t):
        return np.full_like(t, 9.0), np.zeros_like(t), np.zeros_like(t)

    timeline.add(Piece(0.25, 0.5, push), end_position=0.25, end_velocity=1.0)  # between 0 and 1
    timeline.add(Piece(3.0, 1.0, hold), end_position=9.0)
    p, v, a = timeline.sample(np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0]))
    assert p.tolist() == [0.0, 0.5, 1.5, 9.0, 9.0, 9.0]
    assert v.tolist() == [0.0, 1.0, 1.0, 0.0, 0.0, 0.0]
    assert a.tolist() == [0.0] * 6


def test_dwell_holds_every_linear_axis():
    job = parse_job(json.loads(json.dumps({
        "schema": "cnc_job/1", "job_id": "dwell-1", "kind": "move", "machine": "mill3",
        "move": [{"rapid": {"x": 10, "y": 5, "z": 2}}, {"dwell": 0.5}, {"linear": {"z": -1}, "feed": 600}],
    })))
    plan = plan_job(job, MILL)
    rapid_end = plan.timelines["x"].pieces[0].end
    for joint in LINEAR:
        hold = plan.timelines[joint].pieces[1]
        assert hold.start == pytest.approx(rapid_end) and hold.duration == 0.5
    assert plan.timelines["z"].pieces[2].start == pytest.approx(rapid_end + 0.5)
    ts = np.linspace(rapid_end, rapid_end + 0.5, 101)
    p, v, _ = plan.sample(ts)
    assert np.all(p[:, 0] == 0.010) and np.all(p[:, 1] == 0.005) and np.all(p[:, 2] == 0.002)
    assert np.all(v[:, :3] == 0.0)
    moves = [e for e in plan.events if "move" in e.data]  # the per-move phase marks
    assert [(e.name, e.data["move"]) for e in moves] == [("rapid", 0), ("dwell", 1), ("linear", 2)]
    dwell = moves[1]
    assert dwell.time == pytest.approx(rapid_end)
    assert plan.final_position()["z"] == pytest.approx(-0.001)


def test_move_job_on_the_lathe_with_the_spindle():
    job = parse_job({
        "schema": "cnc_job/1", "job_id": "lathe-1", "kind": "move", "machine": "lathe", "spindle_rpm": 1200,
        "move": [{"rapid": {"x": 10, "z": 2}}, {"linear": {"z": -20}, "feed": 120}],
    })
    plan = plan_job(job, LATHE)
    assert plan.joints == ("x", "z", SPINDLE)
    p, v, a = plan.sample(grid(plan.duration))
    assert_within_limits(LATHE, plan.joints, p, v, a)
    w = 1200 * 2 * math.pi / 60
    assert np.abs(v[:, 2]).max() == pytest.approx(w)
    linear = [e for e in plan.events if e.name == "linear"][0]
    assert plan.timelines["z"].pieces[-1].start == pytest.approx(linear.time)
    assert linear.time >= w / LATHE.axes[SPINDLE].max_acceleration  # waited for the ramp


# --- plan sampling continuity --------------------------------------------------------------

def busy_plan():
    """Many pieces: spindle ramp, rapid, overlapped z move, feeds, a dwell-like hold, stop."""
    builder = PlanBuilder(MILL, {"x": 0.0, "y": 0.0, "z": 0.02})
    builder.spindle(500.0)
    builder.rapid({"x": 0.05, "y": 0.02})
    x_end = builder.end_time(["x", "y"])
    builder.rapid({"z": 0.002}, start=x_end - 0.05)  # z starts before x/y have arrived
    builder.linear({"z": -0.003}, 0.02)
    builder.rapid({"z": 0.002})
    builder.timelines["x"].add_hold(builder.end_time(), 0.1)
    builder.rapid({"x": 0.06})
    builder.linear({"x": 0.07, "y": 0.03, "z": -0.001}, 0.05)
    builder.spindle(-300.0, start=builder.end_time())  # reverse: a ramp through zero
    builder.rapid({"x": 0.0, "y": 0.0, "z": 0.02})
    return builder.build()


@pytest.mark.parametrize("offset", [0.0, 0.00037, 0.0009999])
def test_plan_sample_continuous_at_piece_boundaries(offset):
    plan = busy_plan()
    ts = grid(plan.duration, offset=offset)
    p, v, a = plan.sample(ts)
    vmax = np.array([MILL.axes[j].max_velocity for j in plan.joints])
    jumps = np.abs(np.diff(p, axis=0))
    assert np.all(jumps <= vmax * DT * (1 + REL))
    assert_within_limits(MILL, plan.joints, p, v, a)
    assert_velocity_matches_positions(MILL, plan.joints, p, v)


def test_plan_sample_continuous_right_at_each_boundary():
    plan = busy_plan()
    boundaries = sorted({pc.start for tl in plan.timelines.values() for pc in tl.pieces}
                        | {pc.end for tl in plan.timelines.values() for pc in tl.pieces})
    assert len(boundaries) > 10
    for b in boundaries:
        ts = np.array([b - DT, b - 1e-9, b, b + 1e-9, b + DT])
        ts = ts[ts >= 0.0]
        p, v, _ = plan.sample(ts)
        for k, joint in enumerate(plan.joints):
            vmax = MILL.axes[joint].max_velocity
            assert np.all(np.abs(np.diff(p[:, k])) <= vmax * np.diff(ts) * (1 + REL) + 1e-12), (b, joint)
            # no velocity jump either: across 2 ns the velocity changes by at most A * 2 ns
            near = np.abs(ts - b) <= 1e-9
            if near.sum() > 1:
                assert np.ptp(v[near, k]) <= MILL.axes[joint].max_acceleration * 2e-9 + 1e-9, (b, joint)


def test_plan_sample_of_sub_ranges_equals_whole():
    plan = busy_plan()
    ts = grid(plan.duration)
    whole = plan.sample(ts)
    parts = [plan.sample(ts[i:i + 100]) for i in range(0, len(ts), 100)]
    for k in range(3):
        assert np.array_equal(whole[k], np.concatenate([part[k] for part in parts]))


def test_velocity_change_stops_from_motion():
    lim = [Limits(0.8, 9.8, 200.0)]
    stop = velocity_change([0.0], [0.5], [0.0], [0.0], lim)
    end_p, end_v, end_a = (x[0] for x in stop.trajectory.at_time(stop.duration))
    assert end_v == pytest.approx(0.0, abs=1e-12) and end_a == pytest.approx(0.0, abs=1e-9)
    # from v with a=0: T = v/A + A/J when v > A^2/J (0.48): 0.5/9.8 + 0.049
    assert stop.duration == pytest.approx(0.5 / 9.8 + 9.8 / 200.0, rel=1e-9)
    # and it travels v*T/2 (symmetric ramp)
    assert end_p == pytest.approx(0.5 * stop.duration / 2, rel=1e-9)


def test_a_plan_sample_evaluates_each_move_once_and_keeps_no_samples(monkeypatch):
    """Every joint of a three-axis rapid samples its own dof of the one ruckig move (one
    sample_spans call each, no instant twice, no joint evaluating all three dofs), and
    nothing sampled stays with the plan."""
    from cnc_planner.motion import moves as motion
    from cnc_planner.motion import timeline
    from cnc_planner.motion.jerk_profile import TrajectorySampler

    whole, spans = [], []
    evaluate, sample_spans = TrajectorySampler.sample, timeline.sample_spans
    monkeypatch.setattr(TrajectorySampler, "sample", lambda self, t: whole.append(len(t)) or evaluate(self, t))
    monkeypatch.setattr(timeline, "sample_spans",
                        lambda rows, starts, lo, hi, *rest: spans.append(int(np.sum(hi - lo))) or
                        sample_spans(rows, starts, lo, hi, *rest))
    builder = PlanBuilder(MILL, {"x": -0.2, "y": 0.1, "z": 0.05})
    builder.rapid({"x": 0.3, "y": -0.25, "z": -0.2})
    plan = builder.build()
    ts = grid(plan.duration)
    p, _, _ = plan.sample(ts)
    inside = int(np.sum(ts < plan.duration))
    assert whole == [] and spans == [inside, inside, inside]  # x, y and z their own dof
    assert p[-1, :3].tolist() == [0.3, -0.25, -0.2]
    assert motion._scope.depth == 0 and motion._scope.samples == {}
    plan.sample(ts)
    assert spans == [inside] * 6  # a second plan sample evaluates again: nothing was kept


def test_a_carried_correction_rides_on_later_pieces_and_holds_the_joint_where_none_is():
    """JointTimeline.carry: a correction from the timeline's end to 0.3 s is added to a
    piece that starts later (a hold fills the gap with it) and, after flush, to a hold
    until it has settled; the plan lasts until then."""
    from cnc_planner.motion.timeline import JointTimeline, Piece

    def ramp(t):
        return 0.01 * t, np.full_like(t, 0.01), np.zeros_like(t)

    def correction(t):
        return 1e-3 * (0.3 - t), np.full_like(t, -1e-3), np.zeros_like(t)

    line = JointTimeline(0.0)
    line.add(Piece(0.0, 0.1, ramp), 0.001)
    line.carry(0.1, 0.3, correction)
    assert line.settled_time == pytest.approx(0.3) and line.end_time == pytest.approx(0.1)
    line.add(Piece(0.2, 0.05, lambda t: (0.001 + 0.0 * t, 0.0 * t, 0.0 * t)), 0.001)
    line.flush()
    t = np.array([0.15, 0.22, 0.28, 0.35])
    p, v, _ = line.sample(t)
    assert p == pytest.approx(0.001 + 1e-3 * np.maximum(0.3 - t, 0.0) * (t < 0.3))
    assert v[:3] == pytest.approx([-1e-3] * 3) and v[3] == 0.0
    assert line.end_time == pytest.approx(0.3)


def test_a_plans_samples_are_each_pieces_own_values_at_its_own_instants():
    """Plan.sample equals every piece sampled on its own at its local instants (plan time
    minus its start), bit for bit. A perforated plate reuses its retract and air moves at
    every hole: a sample shared by two pieces of one move whose local instants agree at
    their ends but not in between once put one hole's values at another's (up to 4e-14 m/s^2)."""
    from pathlib import Path

    from cnc_msgs_py.job import load_job_file

    doc = load_job_file(Path(__file__).parents[3] / "config" / "jobs" / "drill_row.yaml")
    doc["drill"].update(holes=[[-250 + 5 * (i % 3), -250 + 5 * (i // 3)] for i in range(9)], depth=1.5, r_gap=1.0,
                        feed=1500)
    plan = plan_job(parse_job(doc), load_machine(doc["machine"]))
    ts = np.arange(int(np.ceil(plan.duration / 1e-3)) + 1) * 1e-3
    sampled = plan.sample(ts)
    shared = 0
    for i, joint in enumerate(plan.joints):
        moves = [piece.sample.move for piece in plan.timelines[joint].pieces if hasattr(piece.sample, "move")]
        shared += len(moves) - len(set(map(id, moves)))
        for piece in plan.timelines[joint].pieces:
            inside = (ts >= piece.start) & (ts < piece.end)
            if inside.any():
                own = piece.sample(ts[inside] - piece.start)
                for q in range(3):
                    assert np.array_equal(sampled[q][inside, i], own[q]), (joint, piece.start, "pva"[q])
    assert shared > 10  # moves used by more than one piece: the case the test is about


def test_a_writing_sampler_writes_into_the_timelines_samples_and_still_samples_alone():
    """A WritingSampler piece (the drill's X/Y command) writes straight into the arrays a
    timeline fills, at its local instants; called alone it returns the same samples."""
    from cnc_planner.motion.timeline import WritingSampler

    class Ramp(WritingSampler):
        def write(self, t, out):
            out[0][:], out[1][:], out[2][:] = 1.0 + 2.0 * t, 2.0, 0.0

    timeline = JointTimeline(1.0)
    timeline.add(Piece(0.5, 1.0, Ramp()), 3.0)
    ts = np.arange(0.0, 2.0, 0.25)
    p, v, a = timeline.sample(ts)
    assert p.tolist() == [1.0, 1.0, 1.0, 1.5, 2.0, 2.5, 3.0, 3.0]
    assert v.tolist() == [0.0, 0.0, 2.0, 2.0, 2.0, 2.0, 0.0, 0.0]
    assert [x.tolist() for x in Ramp()(np.array([0.0, 0.5]))] == [[1.0, 2.0], [2.0, 2.0], [0.0, 0.0]]


def test_a_replaced_piece_is_sampled_as_replaced_after_the_timeline_was_sampled():
    """A piece put in place of another (a settling correction superimposed on a ruckig
    piece) is what later samples show, though the timeline kept the ruckig piece's row."""
    move = point_to_point([0.0], [0.01], [Limits(0.5, 5.0, 100.0)])
    timeline = JointTimeline(0.0)
    timeline.add(Piece(0.0, move.duration, move.sampler(0)), 0.01)
    ts = np.linspace(0.0, move.duration, 50, endpoint=False)  # all inside the piece
    before = timeline.sample(ts)[0].copy()
    timeline.replace(0, Piece(0.0, move.duration, lambda t: tuple(x + 1e-3 for x in move.sampler(0)(t))))
    assert np.allclose(timeline.sample(ts)[0], before + 1e-3)
    with pytest.raises(ValueError, match="cannot replace"):
        timeline.replace(0, Piece(0.1, move.duration, move.sampler(0)))
