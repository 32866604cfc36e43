"""Overlapped drilling: safe on the drive model's feedback, within limits, faster than G81."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_msgs_py.machine import Machine, exactly_as_described, load_machine
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.kinds.drill.bound import lower_bound_time
from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinds.drill.drilling import plan_drilling
from cnc_analysis.drilling import analyze_drilling
from cnc_servo_bridge.drive import DriveModel
from cnc_servo_bridge.setpoints import SetpointBuffer

MACHINE = load_machine("mill3")
EXACT_MILL = exactly_as_described(MACHINE)
PERIOD = 1e-3
R_GAP = 0.002
FEED = 0.02  # 1200 mm/min
DIRECTIONS = {"x": (1.0, 0.0), "y": (0.0, 1.0), "diagonal": (0.6, 0.8)}


def make_cycle(pitch: float, depth: float, direction=(1.0, 0.0), n: int = 3, **options) -> DrillCycle:
    holes = [(i * pitch * direction[0] - 0.1, i * pitch * direction[1] - 0.1) for i in range(n)]
    return DrillCycle(holes=holes, surface_z=0.0, bottom_z=-depth, r_z=R_GAP, feed=FEED, **options)


def start_of(cycle: DrillCycle) -> dict[str, float]:
    """One pitch before the first hole, 1 mm above R: as if coming from a previous hole."""
    (x0, y0), (x1, y1) = cycle.holes[0], cycle.holes[1]
    return {"x": 2 * x0 - x1, "y": 2 * y0 - y1, "z": R_GAP + 0.001}


def run(cycle: DrillCycle, start: dict[str, float] | None = None, machine: Machine = MACHINE):
    """Plan the cycle, sample its commands every servo period and run the drive model."""
    builder = PlanBuilder(machine, start or start_of(cycle))
    infos = plan_drilling(builder, cycle)
    plan = builder.build()
    ts = np.arange(0.0, plan.duration + 0.2, PERIOD)
    p, v, a = plan.sample(ts)
    cols = [plan.joints.index(j) for j in ("x", "y", "z")]
    feedback, _ = DriveModel(machine, PERIOD, ("x", "y", "z")).simulate(p[:, cols], v[:, cols], a[:, cols])
    return plan, infos, ts, p[:, cols], feedback


def analysis(cycle: DrillCycle, ts: np.ndarray, xyz: np.ndarray) -> dict:
    return analyze_drilling(ts, xyz[:, 0], xyz[:, 1], xyz[:, 2], cycle.holes, cycle.r_z, cycle.xy_tolerance)


@pytest.mark.parametrize("direction", sorted(DIRECTIONS))
@pytest.mark.parametrize("depth", [0.002, 0.010, 0.030])
@pytest.mark.parametrize("pitch", [0.003, 0.010, 0.040])
def test_auto_cycle_is_safe_on_feedback(pitch, depth, direction):
    # X/Y commands are drive-compensated: the feedback, not the command, is the tool.
    cycle = make_cycle(pitch, depth, DIRECTIONS[direction])
    _, infos, ts, _, feedback = run(cycle)
    assert analysis(cycle, ts, feedback)["safety_violations"] == 0
    assert len(infos) == len(cycle.holes)


@pytest.mark.parametrize("depth", [0.002, 0.030])
@pytest.mark.parametrize("pitch", [0.003, 0.040])
def test_uncompensated_cycle_is_safe_on_feedback_and_commands(pitch, depth):
    cycle = make_cycle(pitch, depth, DIRECTIONS["diagonal"], compensate_xy=False)
    _, _, ts, commands, feedback = run(cycle)
    assert analysis(cycle, ts, feedback)["safety_violations"] == 0
    assert analysis(cycle, ts, commands)["safety_violations"] == 0


@pytest.mark.parametrize("pitch, depth", [(0.003, 0.002), (0.040, 0.002), (0.150, 0.010)])
def test_compensated_xy_feedback_arrives_with_the_move_and_shortens_the_cycle(pitch, depth):
    """Pre-compensated, the X/Y feedback is within tolerance at most ~5 ms after the S1
    ruckig move ends (uncompensated: 30-50 ms), and the safe-gap search turns that into
    a shorter cycle on feedback: on drives exactly as described (a tolerance of the drives
    makes the planner wait for its slowest corner, test_drill_tolerance.py)."""
    times = {}
    for compensate in (True, False):
        cycle = make_cycle(pitch, depth, DIRECTIONS["diagonal"], n=4, compensate_xy=compensate)
        _, infos, ts, _, feedback = run(cycle, machine=EXACT_MILL)
        result = analysis(cycle, ts, feedback)
        assert result["safety_violations"] == 0
        times[compensate] = result["cycle_time_s"]
        late = []
        for info in infos:
            window = (ts >= info["s1_end"]) & (ts <= info["r_up"])
            off = np.hypot(feedback[window, 0] - info["x"], feedback[window, 1] - info["y"]) > cycle.xy_tolerance
            late.append(ts[window][np.nonzero(off)[0][-1]] - info["s1_end"] if off.any() else 0.0)
        if compensate:
            assert max(late) <= 0.005
        else:
            assert min(late) >= 0.02
    assert times[True] < times[False] - 0.02 * len(cycle.holes)


@pytest.mark.parametrize("mode, pitch, depth", [
    (3, 0.003, 0.002), (3, 0.010, 0.010), (3, 0.040, 0.030), (3, 0.150, 0.010),
    (2, 0.003, 0.002), (2, 0.010, 0.010), (2, 0.040, 0.030), (2, 0.150, 0.002),
    (1, 0.003, 0.060), (1, 0.040, 0.060), (1, 0.150, 0.060),
])
def test_forced_modes_are_safe_on_feedback(mode, pitch, depth):
    cycle = make_cycle(pitch, depth, DIRECTIONS["diagonal"], mode=mode)
    _, infos, ts, _, feedback = run(cycle)
    assert analysis(cycle, ts, feedback)["safety_violations"] == 0
    assert {info["mode"] for info in infos} == {mode}


def test_holes_in_any_order_are_safe():
    holes = [(0.02, 0.0), (-0.01, 0.015), (0.0, 0.0), (0.025, 0.003), (0.004, 0.03)]
    cycle = DrillCycle(holes=holes, surface_z=0.0, bottom_z=-0.008, r_z=R_GAP, feed=FEED)
    _, infos, ts, _, feedback = run(cycle, {"x": 0.0, "y": -0.02, "z": 0.01})
    result = analysis(cycle, ts, feedback)
    assert result["safety_violations"] == 0
    r_down = [hole["r_down_s"] for hole in result["holes"]]
    assert r_down == sorted(r_down)  # drilled in the given order
    assert all(abs(hole["depth_mm"] - 8.0) < 0.1 for hole in analyze_drilling(
        ts, feedback[:, 0], feedback[:, 1], feedback[:, 2], holes, R_GAP, 1e-5, surface_z=0.0)["holes"])


@pytest.mark.parametrize("pitch, overlap, compensate", [
    (0.010, True, True), (0.150, True, True), (0.010, True, False), (0.010, False, True)])
def test_commands_respect_axis_limits(pitch, overlap, compensate):
    """Velocity and acceleration by finite differences, and the bridge's setpoint rules.
    (The compensated X/Y command may briefly exceed the jerk limit: not checked.)"""
    cycle = make_cycle(pitch, 0.010, DIRECTIONS["diagonal"], n=4, overlap=overlap, compensate_xy=compensate)
    plan, _, ts, commands, _ = run(cycle)
    p, v, a = plan.sample(ts)
    SetpointBuffer(MACHINE).validate(list(plan.joints), np.round(ts * 1e9).astype(np.int64), p, v, a, 0,
                                     (p[0], np.zeros_like(p[0])))
    velocity = np.diff(commands, axis=0) / PERIOD
    acceleration = np.diff(velocity, axis=0) / PERIOD
    for k, name in enumerate(("x", "y", "z")):
        axis = MACHINE.axes[name]
        assert np.abs(velocity[:, k]).max() <= axis.max_velocity * 1.001
        # Finite differences of a jerk-limited profile overshoot by at most jerk * period.
        assert np.abs(acceleration[:, k]).max() <= axis.max_acceleration + axis.max_jerk * PERIOD
    descending = (commands[1:, 2] < cycle.r_z) & (velocity[:, 2] < 0)
    assert -velocity[descending, 2].min() <= FEED * 1.01  # below R, Z goes down at cutting feed


@pytest.mark.parametrize("pitch, depth, mode", [
    (0.150, 0.060, 1),  # deep, wide pitch: rapid reached before R
    (0.150, 0.002, 2),  # shallow: speed at R below rapid
    (0.150, 0.030, 2),
    (0.003, 0.010, 3),  # close pitch: decelerate before R
    (0.010, 0.060, 3),
])
def test_auto_mode_follows_depth_and_pitch(pitch, depth, mode):
    _, infos, _, commands, _ = run(make_cycle(pitch, depth, n=4))
    # The last hole brakes to rest above R (mode 3): no next hole to hurry to.
    assert [info["mode"] for info in infos] == [mode] * 3 + [3]


def test_mode_definitions_at_r():
    """Speed at R going up: mode 1 at rapid, mode 2 below rapid still accelerating,
    mode 3 lower and already decelerating before R, the lower the closer the pitch."""
    def exit_state(pitch, depth, mode=None):
        plan, infos, *_ = run(make_cycle(pitch, depth, n=3, mode=mode))
        t_up = infos[0]["r_up"]
        _, v, a = plan.timelines["z"].sample(np.array([t_up - 1e-4]))
        return v[0], a[0]

    rapid = MACHINE.axes["z"].max_velocity
    v1, _ = exit_state(0.150, 0.060)
    v2, a2 = exit_state(0.150, 0.002)
    v3_close, a3_close = exit_state(0.003, 0.030, mode=3)
    v3_wide, _ = exit_state(0.040, 0.030, mode=3)
    assert v1 == pytest.approx(rapid, rel=1e-3)
    assert v2 < rapid and a2 > 0.5 * MACHINE.axes["z"].max_acceleration
    assert a3_close < 0 and v3_close < v3_wide < rapid


def test_forced_mode_that_the_depth_forbids_is_rejected():
    with pytest.raises(ValueError, match="mode: 1"):
        plan_drilling(PlanBuilder(MACHINE, {"z": 0.01}), make_cycle(0.01, 0.005, mode=1))


def test_tool_below_r_is_rejected():
    with pytest.raises(ValueError, match="above the R plane"):
        plan_drilling(PlanBuilder(MACHINE, {"z": 0.0}), make_cycle(0.01, 0.005))


@pytest.mark.parametrize("pitch, depth", [(0.003, 0.002), (0.040, 0.010), (0.150, 0.030)])
def test_overlapped_is_faster_than_conventional_and_above_the_bound(pitch, depth):
    times = {}
    for overlap in (True, False):
        cycle = make_cycle(pitch, depth, n=4, overlap=overlap)
        _, _, ts, _, feedback = run(cycle)
        result = analysis(cycle, ts, feedback)
        assert result["safety_violations"] == 0
        times[overlap] = result["cycle_time_s"]
    start = start_of(cycle)
    bound = lower_bound_time(MACHINE, cycle, (start["x"], start["y"]))
    assert bound < times[True] < times[False]


def test_events_mark_every_phase_in_order():
    cycle = make_cycle(0.040, 0.010, n=3)
    builder = PlanBuilder(MACHINE, start_of(cycle))
    infos = plan_drilling(builder, cycle)
    plan = builder.build()
    for info in infos:
        names = [e.name for e in plan.events if e.data.get("hole") == info["hole"]]
        assert sorted(names) == ["R_down", "R_up", "S1", "S2", "S3"]
        assert info["s2"] <= info["r_down"] <= info["s3"] <= info["r_up"]
        assert all(e.data["mode"] == info["mode"] for e in plan.events if e.data.get("hole") == info["hole"])
    for before, after in zip(infos, infos[1:]):
        # S1 starts as the tip passes R going up (a few ms early where the commands allow),
        # and S2 starts before S1 ends: the air path is an arc.
        assert abs(after["s1"] - before["r_up"]) < 0.01
        assert after["s2"] < after["s1_end"]


@pytest.mark.parametrize("pitch, depth", [(0.010, 0.010), (0.040, 0.002), (0.150, 0.030)])
def test_gentle_air_keeps_cycle_time_and_lowers_energy(pitch, depth):
    results = {}
    for gentle in (False, True):
        cycle = make_cycle(pitch, depth, n=4, gentle_air_accel=gentle)
        plan, infos, ts, _, feedback = run(cycle)
        assert analysis(cycle, ts, feedback)["safety_violations"] == 0
        results[gentle] = (plan.duration, sum(info["air_energy"] for info in infos))
    assert results[True][0] == pytest.approx(results[False][0], abs=1e-3)
    assert results[True][1] < results[False][1]


def test_conventional_cycle_is_sequential():
    cycle = make_cycle(0.010, 0.005, n=3, overlap=False)
    _, infos, ts, commands, feedback = run(cycle)
    assert analysis(cycle, ts, feedback)["safety_violations"] == 0
    for before, after in zip(infos, infos[1:]):
        assert after["s1"] >= before["r_up"]
    result = analysis(cycle, ts, commands)
    assert all(hole["overlap_down_s"] == 0.0 and hole["overlap_up_s"] == 0.0 for hole in result["holes"])


def test_a_hole_given_twice_or_a_hair_apart_plans_and_stays_safe():
    """A repeated hole (or one closer than the X/Y tolerance) is drilled again, safely."""
    builder = PlanBuilder(MACHINE, {"x": 0.0, "y": 0.0, "z": 0.01})
    holes = [(0.0, 0.0), (0.0, 0.0), (1e-6, 0.0), (0.01, 0.0)]
    cycle = DrillCycle(holes=holes, surface_z=0.0, bottom_z=-0.005, r_z=0.002, feed=0.02)
    infos = plan_drilling(builder, cycle)
    assert len(infos) == 4
    plan = builder.build()
    t = np.arange(0.0, plan.duration, 1e-3)
    p, v, a = plan.sample(t)
    fb, _ = DriveModel(MACHINE, 1e-3, plan.joints).simulate(p, v, a)
    result = analyze_drilling(t, fb[:, 0], fb[:, 1], fb[:, 2], holes, cycle.r_z, cycle.xy_tolerance)
    assert result["safety_violations"] == 0


@pytest.mark.parametrize("hole", [(0.0, 0.0), (2e-6, 0.0), (0.005, 0.0), (0.01, 0.01), (0.3, -0.2), (-0.45, 0.0)])
def test_s1_tolerance_crossings_equal_a_scan_of_the_whole_move(hole) -> None:
    """S1 leaves and re-enters the hole's tolerance where sampling all of the move at
    CROSSING_STEP says, though only its ends are sampled (short, long and null moves)."""
    from cnc_planner.kinds.drill.xy_moves import CROSSING_STEP, _limited, _xy_move

    p0, tol = (0.0, 0.0), 1e-5
    xy = _xy_move(MACHINE, p0, hole, tol)
    move, joints = _limited(MACHINE, p0, hole, (1.0, 1.0, 1.0))
    if move is None:
        assert xy.move is None and xy.leave == np.inf and xy.arrive == 0.0
        return
    ts = np.arange(0.0, move.duration + CROSSING_STEP, CROSSING_STEP)
    p = move.sample_all(np.minimum(ts, move.duration))[0]
    axis = [("x", "y").index(j) for j in joints]
    left = np.nonzero(np.linalg.norm(p - np.take(p0, axis), axis=1) > tol)[0]
    away = np.nonzero(np.linalg.norm(p - np.take(hole, axis), axis=1) > tol)[0]
    assert xy.leave == (max(ts[left[0]] - CROSSING_STEP, 0.0) if len(left) else np.inf)
    assert xy.arrive == (ts[away[-1]] + CROSSING_STEP if len(away) else 0.0)



@pytest.mark.parametrize("compensate_xy", [True, False])
def test_s1_crossings_shared_by_a_displacement_equal_each_moves_own_scan(compensate_xy) -> None:
    """s1_moves scans the tolerance crossings once per displacement: over a grid across
    the travel (far from the origin too, where positions round differently) every hole's
    crossings are what a scan of its own whole move says."""
    from cnc_planner.kinds.drill.xy_moves import CROSSING_STEP, s1_moves

    holes = [(-0.45 + 0.005 * (i % 6) + 0.3 * (i // 12), -0.25 + 0.004 * (i // 6)) for i in range(36)]
    cycle = DrillCycle(holes=holes, surface_z=0.0, bottom_z=-0.002, r_z=0.002, feed=0.02, compensate_xy=compensate_xy)
    position = (0.0, 0.0)
    moves = s1_moves(MACHINE, cycle, {"x": position[0], "y": position[1], "z": 0.01})
    assert len({(round(b[0] - a[0], 9), round(b[1] - a[1], 9)) for a, b in zip(holes, holes[1:])}) < 8
    for hole, xy in zip(holes, moves):
        ts = np.arange(0.0, xy.move.duration + CROSSING_STEP, CROSSING_STEP)
        p = xy.move.sample_all(np.minimum(ts, xy.move.duration))[0]
        axis = [("x", "y").index(j) for j in xy.joints]
        left = np.nonzero(np.linalg.norm(p - np.take(position, axis), axis=1) > cycle.xy_tolerance)[0]
        away = np.nonzero(np.linalg.norm(p - np.take(hole, axis), axis=1) > cycle.xy_tolerance)[0]
        assert xy.leave == max(ts[left[0]] - CROSSING_STEP, 0.0)
        assert xy.arrive == ts[away[-1]] + CROSSING_STEP
        position = hole


def test_holes_of_one_pitch_share_their_air_arcs(monkeypatch):
    """A row of one pitch asks for the very same air arcs at every hole: each distinct
    Z move is planned once (ruckig called per distinct move, not per hole and round)."""
    from cnc_planner.kinds.drill import z_axis

    planned = []
    z_move = z_axis.z_move
    monkeypatch.setattr(z_axis, "z_move", lambda *args, **kw: planned.append(args) or z_move(*args, **kw))
    cycle = make_cycle(0.01, 0.003, n=40)
    infos = plan_drilling(PlanBuilder(MACHINE, start_of(cycle)), cycle)
    assert len(infos) == 40
    assert len(planned) == len(set(planned)) < 40  # 277 calls when every hole planned its own


def _lag_margins_scan(fb, starts, into, out, hole_x, hole_y, tol):
    """servo_lag's per-hole scan as numpy expressions (the reference the kernel replaced)."""
    z = fb[:, 2]
    down, up = np.zeros(len(into)), np.zeros(len(into))
    ku = 0
    for i in range(len(into)):
        lo, hi = max(starts[i], ku), starts[i + 2]
        low = z[lo:hi] < min(into[i], out[i])
        if not low.any():
            continue
        kv = lo + int(np.argmax(low))
        kw = hi if low[kv - lo:].all() else kv + int(np.argmin(low[kv - lo:]))
        kb = kv + int(np.argmin(z[kv:kw]))
        kd = lo + int(np.argmax(z[lo:hi] < into[i]))
        ku = kb + int(np.argmin(z[kb:hi] < out[i]))
        ku = hi if z[ku] < out[i] else ku
        far = np.hypot(fb[lo:hi, 0] - hole_x[i], fb[lo:hi, 1] - hole_y[i]) > tol
        before, after = np.nonzero(far[: kb - lo])[0], np.nonzero(far[kb - lo:])[0]
        down[i] = (lo + before[-1] + 1 if len(before) else lo) - kd
        up[i] = ku - (kb + after[0] if len(after) else hi)
    return down, up


@pytest.mark.parametrize("seed", range(6))
def test_the_compiled_lag_scan_equals_the_numpy_scan(seed) -> None:
    """The drive model's margins, hole after hole (_lag_kernel.margins), equal the numpy
    scan they replaced: dips below one plane or both, holes never entered, pecks (several
    visits), a tip still low when the next S1 starts, X/Y off the hole before and after."""
    from cnc_planner.kinds.drill._lag_kernel import margins

    rng = np.random.default_rng(seed)
    holes = 40
    starts = np.sort(rng.integers(0, 3000, holes + 2)).astype(np.intp)
    starts[-2:] = 3000
    t = np.arange(3000)
    z = 0.002 + 0.001 * np.cos(t / rng.uniform(5, 40)) - rng.uniform(0, 0.004) * (np.sin(t / 23.0) > 0.3)
    fb = np.stack((rng.normal(0, 8e-6, 3000) + (t % 97 < 5) * 1e-4, rng.normal(0, 8e-6, 3000), z), axis=1)
    into, out = rng.choice([0.001, 0.002], holes), rng.choice([0.001, 0.002, 0.0025], holes)
    hole_x, hole_y = rng.normal(0, 2e-6, holes), np.zeros(holes)
    down, up = np.zeros(holes), np.zeros(holes)
    margins(fb, starts, into, out, hole_x, hole_y, 1e-5, down, up)
    expected = _lag_margins_scan(fb, starts, into, out, hole_x, hole_y, 1e-5)
    assert np.array_equal(down, expected[0]) and np.array_equal(up, expected[1])
    assert np.any(down != 0) and np.any(up != 0)  # late arrivals and early exits were there to find
    with pytest.raises(ValueError, match="starts"):
        margins(fb, starts[::-1].copy(), into, out, hole_x, hole_y, 1e-5, down, up)


def test_the_xy_table_holds_each_axis_where_its_last_move_left_it():
    """XYMoveTable: after k moves each axis stands at the target of the last move that
    moved it (the start before any); an X/Y command takes the table's moves in order only."""
    from cnc_planner.kinds.drill.xy_command import XYCommand, XYMoveTable
    from cnc_planner.kinds.drill.xy_moves import s1_moves

    holes = [(0.01, 0.0), (0.01, 0.0), (0.02, 0.0), (0.02, 0.01), (0.0, 0.01)]
    cycle = DrillCycle(holes=holes, surface_z=0.0, bottom_z=-0.002, r_z=0.002, feed=0.02)
    start = {"x": 0.0, "y": -0.01, "z": 0.01}
    moves = s1_moves(MACHINE, cycle, start)
    table = XYMoveTable(start, moves, cycle.servo_period)
    assert len(table.moves) == 4  # the repeated hole is no move
    assert table.held["x"].tolist() == [0.0, 0.01, 0.02, 0.02, 0.0]
    assert table.held["y"].tolist() == [-0.01, 0.0, 0.0, 0.01, 0.01]
    command = XYCommand(table)
    with pytest.raises(ValueError, match="order"):
        command.add(0.0, table.moves[1])
