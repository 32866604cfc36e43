"""Drilling as machinists program it, judged on the drive model's feedback: chip-breaking
vibration on the Z feed (D/Q and E/R), dwell at the bottom (G82), up-front refusals."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job
from cnc_planner.prediction import simulated_feedback
from cnc_analysis.aircut import analyze_aircut
from cnc_analysis.drilling import analyze_drilling

MACHINE = load_machine("mill3")
START = {"x": 0.0, "y": 0.0, "z": 0.05}
LIMIT_SHARE = 1.05  # the bridge refuses chunks beyond this share of the velocity/acceleration limits
DOC = {
    "schema": "cnc_job/1", "job_id": "drill-features", "kind": "drill", "machine": "mill3",
    "tool": {"diameter": 3.0}, "spindle_rpm": 600,
    "drill": {"holes": [[0, 0], [8, 0]], "depth": 3.0, "r_gap": 1.0, "feed": 60},
}


def job_with(**changes) -> dict:
    doc = copy.deepcopy(DOC)
    for key, value in changes.items():
        if key in ("vibration", "spindle_rpm"):
            doc[key] = value
        else:
            doc["drill"][key] = value
    return doc


def simulate(doc: dict):
    job = parse_job(doc)
    plan = plan_job(job, MACHINE, START)
    t, feedback = simulated_feedback(plan, MACHINE)
    return job, plan, t, plan.sample(t)[0], feedback


def within_limits(plan, t: np.ndarray, commands: np.ndarray) -> None:
    for j in ("x", "y", "z"):
        axis, p = MACHINE.axes[j], commands[:, plan.joints.index(j)]
        v = np.diff(p) / np.diff(t)
        a = np.diff(v) / np.diff(t[1:])
        assert np.max(np.abs(v)) <= LIMIT_SHARE * axis.max_velocity, j
        assert np.max(np.abs(a)) <= LIMIT_SHARE * axis.max_acceleration, j
        assert axis.min <= p.min() and p.max() <= axis.max, j


def hole_aircuts(plan, t: np.ndarray, positions: np.ndarray, surface_z: float = 0.0) -> list:
    """analyze_aircut of every hole's vibrated feed below the surface."""
    z, spindle = positions[:, plan.joints.index("z")], positions[:, plan.joints.index(SPINDLE)]
    starts = [e.time for e in plan.events if e.name == "vibration_feed"]
    ends = [e.time for e in plan.events if e.name == "vibration_end"]
    out = []
    for t0, t1 in zip(starts, ends):
        inside = (t >= t0) & (t <= t1)
        cut = inside & (z < surface_z)
        keep = inside & (np.arange(len(t)) >= np.argmax(cut))
        out.append(analyze_aircut(spindle[keep], -z[keep]))
    return out


@pytest.mark.parametrize("vibration", [{"D": 1.5, "Q": 1.2}, {"E": 2, "R": 0.5}])
def test_vibrated_drill_feed_breaks_the_chip_in_every_hole_on_feedback(vibration):
    job, plan, t, commands, feedback = simulate(job_with(vibration=vibration))
    within_limits(plan, t, commands)
    cuts = hole_aircuts(plan, t, feedback)
    assert len(cuts) == 2
    for cut in cuts:
        assert cut.revolutions >= 25  # 3 mm at 0.1 mm/rev, the first revolution has no surface yet
        # D 1.5 breaks the chip every revolution, E 2 every other one (one vibration per 2 revs)
        assert cut.max_chip_revs <= (1.5 if "D" in vibration else 2.5)
        assert cut.aircut_fraction > 0.05
    d = job.drill
    holes = [tuple(h) for h in d.holes]
    result = analyze_drilling(t, feedback[:, 0], feedback[:, 1], feedback[:, 2], holes, d.r_gap, 1e-5, 0.0)
    assert result["safety_violations"] == 0
    for hole in result["holes"]:
        assert hole["depth_mm"] == pytest.approx(3.0, abs=0.005)
    # the overlap is kept: X/Y still moves while Z descends to R
    assert all(h["overlap_down_s"] > 0 for h in result["holes"][1:])


def test_the_plain_drill_feed_has_no_aircut():
    _, plan, t, _, feedback = simulate(job_with())
    assert not [e for e in plan.events if e.name == "vibration_feed"]


@pytest.mark.parametrize("changes, field, words", [
    ({"spindle_rpm": 3000, "feed": 300}, "vibration.D", ["cannot follow", "max spindle speed"]),
    ({"vibration": {"D": 1.5, "Q": 0.8}}, "vibration.Q", ["no air-cut", "need Q > 1.00"]),
    ({"vibration": {"D": 2.0, "Q": 1.5}}, "vibration.D", ["whole number"]),
])
def test_a_vibration_that_cannot_work_is_refused_up_front(changes, field, words):
    doc = job_with(vibration={"D": 1.5, "Q": 1.2})
    doc = job_with(**{"vibration": doc["vibration"], **changes})
    with pytest.raises(JobError) as info:
        plan_job(parse_job(doc), MACHINE, START)
    assert info.value.field == field, str(info.value)
    for word in words:
        assert word in info.value.reason


def test_dwell_holds_the_bottom_on_feedback():
    job, plan, t, _, feedback = simulate(job_with(dwell=0.3))
    dwells = [e for e in plan.events if e.name == "dwell"]
    assert [e.data["hole"] for e in dwells] == [0, 1]
    z = feedback[:, plan.joints.index("z")]
    bottom = -job.drill.depth
    for e in dwells:
        held = (t >= e.time) & (t <= e.time + 0.3)
        assert np.all(np.abs(z[held] - bottom) <= 5e-6)
    # without the dwell the same job is 2 x 0.3 s shorter
    _, plain, *_ = simulate(job_with())
    assert plan.duration - plain.duration == pytest.approx(0.6, abs=0.02)


def test_straight_stroke_e_r_waveform_only_touches_until_the_retreat_passes_b1():
    """E 2, R 0.5 at equal speed (Q 1.5): drawn with straight strokes, revolution n+1
    retraces revolution n after B1 with zero clearance (no air-cut); with jerk-limited
    reversals the touch threshold is still exactly that Q, and er_vibration's retreat past
    B1 (ER_DEPARTURE feeds) cuts air in every vibration."""
    from cnc_planner.vibration.waveform import ER_DEPARTURE, _min_q, equal_speed_q, er_vibration

    q = equal_speed_q(2.0, 0.5)
    assert q == pytest.approx(1.5)  # v = E*F/(E-2R) = 2F/rev; A1 = 1.5 revs * 2F = 3F = 1.5F + 1.5 F
    theta = np.linspace(0.0, 2 * np.pi * 20, 200_001)
    revs = theta / (2 * np.pi)
    u = np.mod(revs, 2.0)  # position in the vibration, in revs
    base = 2.0 * np.floor(revs / 2.0)
    straight = base + np.where(u < 1.5, 2.0 * u, 3.0 - 2.0 * (u - 1.5))  # in feeds per rev
    clearance = -1e-6  # feeds per rev: a real air-cut is behind the surface, not on it
    touching = analyze_aircut(theta, straight)
    assert touching.revolutions_with_aircut > 0  # zero clearance over half a revolution ...
    assert analyze_aircut(theta, straight, tolerance=clearance).revolutions_with_aircut == 0  # ... only
    vib = er_vibration(2.0, 0.5)
    assert _min_q(vib) == pytest.approx(q, abs=1e-6)  # rounded reversals: still only touching at Q 1.5
    assert vib.Q == pytest.approx(q + ER_DEPARTURE)
    ours = analyze_aircut(theta, revs + vib.Q * vib.shape(revs / 2.0)[0], tolerance=-0.01)  # >= 1 um at 0.1 mm/rev
    assert ours.revolutions_with_aircut >= ours.revolutions // 2 and ours.max_chip_revs < 2.0


def test_shortest_order_is_a_good_tour():
    """Nearest neighbour + 2-opt against every order of 7 random holes: within 5 % of the best."""
    import itertools

    from cnc_planner.kinds.drill.hole_order import shortest_order, tour_length

    rng = np.random.default_rng(7)
    for _ in range(4):
        holes = [tuple(p) for p in rng.uniform(0.0, 0.1, (7, 2))]
        order = shortest_order(holes, (0.0, 0.0))
        assert sorted(order) == list(range(7))
        best = min(tour_length(holes, list(p), (0.0, 0.0)) for p in itertools.permutations(range(7)))
        assert tour_length(holes, order, (0.0, 0.0)) <= 1.05 * best


def test_segment_over_a_clamp_hand_checked():
    from cnc_planner.kinds.drill.clamps import crossed, under_tool

    clamp = [[0.010, -0.010, 0.020, 0.010, 0.012]]  # 10 mm wide bar across y = 0
    assert crossed(clamp, [(0.0, 0.0), (0.030, 0.0)], 0.0) == [0]  # straight over it
    assert crossed(clamp, [(0.0, 0.020), (0.030, 0.020)], 0.0) == []  # 10 mm beside it
    assert crossed(clamp, [(0.0, 0.0125), (0.030, 0.0125)], 0.002) == [0]  # 2.5 mm off: radius + 1 mm margin
    assert under_tool(clamp, [(0.0, 0.0), (0.0085, 0.0)], 0.002) == (0, 1)  # a hole 1.5 mm from its edge
    assert under_tool(clamp, [(0.0, 0.0)], 0.002) is None


def test_peck_levels_and_reentry_above_the_previous_bottom():
    from cnc_planner.kinds.drill.peck import REENTRY_GAP, levels

    assert levels(0.0, -0.009, 0.003) == pytest.approx([-0.003, -0.006, -0.009])
    assert levels(0.0, -0.010, 0.003) == pytest.approx([-0.003, -0.006, -0.009, -0.010])
    _, plan, t, commands, feedback = simulate(job_with(depth=7.0, peck={"depth": 3.0}, feed=300, spindle_rpm=3000))
    z = commands[:, plan.joints.index("z")]
    entries = [e for e in plan.events if e.name == "reentry"]
    feeds = [e for e in plan.events if e.name == "peck"]
    assert len(entries) == len(feeds) == 2 * 2  # 2 holes, pecks at 3, 6 and 7 mm
    for entry, feed in zip(entries, feeds):
        fast = (t >= entry.time) & (t <= feed.time)
        assert np.min(z[fast]) >= entry.data["previous_bottom"] + REENTRY_GAP - 1e-9
        assert np.min(feedback[fast, plan.joints.index("z")]) > entry.data["previous_bottom"]
    # G83: every retract goes up to R (the hole's R plane, 1 mm above the surface)
    tops = [np.max(z[(t >= a.time - 0.3) & (t <= a.time)]) for a in entries]
    assert tops == pytest.approx([0.001] * 4, abs=1e-6)


@pytest.mark.parametrize("drill, field, words", [
    ({"clearance_z": 0.5}, "drill.clearance_z", ["below the highest R plane"]),
    ({"obstacles": [[9.2, -5, 20, 5, 10]]}, "drill.obstacles[0]", ["under the tool"]),
    ({"obstacles": [[-1, -1, 1, 1, 10]]}, "drill.obstacles[0]", ["covers drill.holes[0]"]),
    ({"peck": {"depth": 1, "full_every": 2}}, "drill.peck.full_every", ["retract: break"]),
])
def test_clamp_and_peck_mistakes_are_refused(drill, field, words):
    with pytest.raises(JobError) as info:
        plan_job(parse_job(job_with(**drill)), MACHINE, START)
    assert info.value.field == field, str(info.value)
    for word in words:
        assert word in info.value.reason
