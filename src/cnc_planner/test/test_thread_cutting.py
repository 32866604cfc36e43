"""Thread cutting with vibration (issue 9): the example job on the lathe, judged on the
drive model's feedback (DriveModel.simulate of the plan sampled every servo period), as
the bridge would publish it.

Example job: 600 rpm, start_z 4, end_z -16, major_radius 6, pitch 1.75, depth 1.07 (mm),
6 passes, infeed 29.5 deg, 1 spring pass; vibration D 1.5, Q 1.2, phase_shift 180, D_step 0.
"""
import dataclasses
import math
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import exactly_as_described, load_machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import mm
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.jerk_profile import ROW_LENGTH, rest_row
from cnc_planner.planning import plan_job
from cnc_planner.kinds.thread import cycle
from cnc_planner.kinds.thread._stock_kernel import inside_stock
from cnc_planner.kinds.thread.checks import check_thread
from cnc_planner.kinds.thread.planning import plan_thread
from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec, ThreadVibration, pass_depths
from cnc_servo_bridge.drive import DriveModel
from cnc_analysis.threads import analyze_thread

T = 1e-3
# The lathe exactly as described (tolerance closed): these tests hold the plan to the described
# drives' feedback to the count; what a tolerance costs is test_thread_tolerance.py's.
LATHE = exactly_as_described(load_machine("lathe"))
JOB = {
    "schema": "cnc_job/1", "job_id": "thread-9", "kind": "thread", "machine": "lathe", "spindle_rpm": 600,
    "thread": {"start_z": 4.0, "end_z": -16.0, "major_radius": 6.0, "pitch": 1.75, "depth": 1.07,
               "passes": 6, "infeed_angle": 29.5, "spring_passes": 1},
    "vibration": {"D": 1.5, "Q": 1.2, "phase_shift": 180, "D_step": 0.0},
}
SPEC = ThreadSpec.from_job(parse_job(JOB))
PLAIN = dataclasses.replace(SPEC, vibration=None)
# hand-computed: d_k = 1.07 * sqrt(k / 6), then the spring pass at full depth
DEPTHS_MM = [0.436826, 0.617765, 0.756604, 0.873651, 0.976772, 1.07, 1.07]


def rpm(value: float) -> float:
    return value * 2 * math.pi / 60


def plan(spec: ThreadSpec, machine=LATHE, compensate: bool = True):
    builder = PlanBuilder(machine, {"x": 7e-3, "z": 4e-3})
    info = plan_thread(builder, spec, compensate=compensate)
    return builder.build(), info


def run(spec: ThreadSpec, machine=LATHE, compensate: bool = True):
    """Plan, command on the servo grid, feedback, and the analysis of the feedback."""
    result, info = plan(spec, machine, compensate)
    t = np.arange(0.0, result.duration + T / 2, T)
    command = result.sample(t)
    feedback = DriveModel(machine, T).simulate(*command)[0]
    thread = dict(JOB["thread"], start_z=spec.start_z * 1e3, end_z=spec.end_z * 1e3,
                  major_radius=spec.major_radius * 1e3, pitch=spec.pitch * 1e3, depth=spec.depth * 1e3,
                  starts=spec.starts, internal=spec.internal, taper=spec.taper)
    report = analyze_thread(t, feedback[:, 0], feedback[:, 1], feedback[:, 2], thread)
    return dict(plan=result, info=info, t=t, command=command, feedback=feedback, report=report)


@pytest.fixture(scope="module")
def vibrating():
    return run(SPEC)


@pytest.fixture(scope="module")
def conventional():
    return run(PLAIN)


def test_pass_depths_are_hand_computed_and_the_cut_never_grows():
    depths = pass_depths(SPEC)
    assert np.allclose(np.array(depths) * 1e3, DEPTHS_MM, atol=1e-6)
    docs = np.diff([0.0] + depths[:6])
    assert np.all(np.diff(docs) < 0)
    # constant chip area: d_k^2 - d_(k-1)^2 = depth^2 / passes
    assert np.allclose(np.diff(np.square([0.0] + depths[:6])), 1.07e-3**2 / 6)
    given = dataclasses.replace(SPEC, passes=4, depths=(0.5e-3, 0.8e-3, 1.0e-3, 1.07e-3), spring_passes=2)
    assert pass_depths(given) == [0.5e-3, 0.8e-3, 1.0e-3, 1.07e-3, 1.07e-3, 1.07e-3]


def test_pass_table_and_events(vibrating):
    info = vibrating["info"]
    assert [p["index"] for p in info] == list(range(7))
    assert [p["depth_mm"] for p in info] == pytest.approx(DEPTHS_MM, abs=1e-6)
    for k, p in enumerate(info[:6]):
        assert p["amplitude_mm"] == pytest.approx(1.2 * p["doc_mm"])
        assert p["vibration_per_rev"] == 1.5
        assert p["vibration_phase_deg"] == pytest.approx(180.0 * (k % 2))
        assert p["spindle_phase_deg"] == 0.0
    spring = info[6]
    assert spring["spring"] and spring["amplitude_mm"] == 0.0 and spring["vibration_per_rev"] is None
    events = vibrating["plan"].events
    starts = [e for e in events if e.name == "thread_pass"]
    syncs = [e for e in events if e.name == "sync"]
    assert [e.data["index"] for e in starts] == [e.data["index"] for e in syncs] == list(range(7))
    assert all(a.time < b.time for a, b in zip(starts, syncs))


def test_every_pass_meets_the_helix_at_the_same_spindle_phase():
    """Hand check on the plain command: wherever a pass is synchronised, the nominal groove
    line under the tool, g = z + depth*tan(29.5 deg), is start_z - pitch*theta/2pi with the
    spindle angle theta counted from a whole revolution: phase 0 on every pass."""
    result, info = plan(SPEC, compensate=False)
    tan = math.tan(SPEC.infeed_angle)
    for p in info:
        t = np.arange(math.ceil(p["t_sync"] / T), math.floor((p["t_end"] - 0.1) / T)) * T
        x, z, theta = result.sample(t)[0].T
        g = z + (SPEC.major_radius - x) * tan
        on_helix = g > SPEC.end_z  # before the pull-out
        phase = np.mod(2 * math.pi * (SPEC.start_z - g) / SPEC.pitch - theta + math.pi, 2 * math.pi) - math.pi
        assert on_helix.sum() > 500
        assert np.abs(phase[on_helix]).max() < 1e-9


def test_feedback_breaks_the_chip_in_every_cutting_pass(vibrating):
    report = vibrating["report"]
    assert report["synchronised_passes"] == 7
    assert report["cutting_passes"] == 6
    for p in report["passes"]:
        if p["doc_mm"] > 0.05:
            assert p["max_chip_revs"] <= 1.0
            assert p["aircut_share"] > 0.05
    assert report["max_chip_revs"] <= 1.0 and report["chips_broken"]


def test_feedback_holds_the_thread_geometry(vibrating):
    report = vibrating["report"]
    assert report["depth_error_mm"] <= 0.02
    assert report["overcut_mm"] <= 0.02
    assert report["full_depth"]
    assert report["helix_residual_mm"] < 0.01
    assert report["doc_never_grows"]
    assert report["infeed_angle_deg"] == pytest.approx(29.5, abs=0.05)
    assert [p["depth_mm"] for p in report["passes"]] == pytest.approx(DEPTHS_MM, abs=0.002)
    for k, p in enumerate(report["passes"][:6]):
        assert p["vibration_per_rev"] == pytest.approx(1.5, abs=0.005)
        # the phase shifts 180 deg against the spindle from pass to pass
        assert abs((p["vibration_phase_deg"] - 180.0 * (k % 2) + 180) % 360 - 180) < 3.0
        doc = DEPTHS_MM[k] - ([0.0] + DEPTHS_MM)[k]
        assert p["vibration_amplitude_mm"] == pytest.approx(1.2 * doc, rel=0.05)


def test_returns_reach_above_the_previous_turning_point(vibrating):
    """Hand computed at g = -1.25 mm, 3 revolutions after start_z: the first pass is at its
    turning point (u = 1.5*3 = 4.5 cycles: full depth 0.4368 mm), the second, shifted half a
    cycle, at its return point 0.6178 - 1.2*0.1809 = 0.4006 mm: 0.036 mm in the air."""
    t, (x, z, _) = vibrating["t"], vibrating["feedback"].T
    tan = math.tan(SPEC.infeed_angle)
    depth = SPEC.major_radius - x
    g = z + depth * tan
    found = []
    for p in vibrating["info"][:2]:
        inside = (t >= p["t_sync"]) & (t < p["t_end"]) & (np.abs(g + 1.25e-3) < 0.1e-3)
        found.append(np.interp(-1.25e-3, g[inside][::-1], depth[inside][::-1]) * 1e3)
    assert found == pytest.approx([0.436826, 0.617765 - 1.2 * 0.180939], abs=0.001)


def test_without_vibration_a_correct_thread_with_long_chips(conventional, vibrating):
    report = conventional["report"]
    assert report["synchronised_passes"] == 7 and report["cutting_passes"] == 6
    assert report["full_depth"] and report["helix_residual_mm"] < 0.01 and report["doc_never_grows"]
    assert [p["depth_mm"] for p in report["passes"]] == pytest.approx(DEPTHS_MM, abs=0.002)
    assert all(p["vibration_per_rev"] is None for p in report["passes"])
    # every cutting pass is one chip over the whole thread: 16 mm / 1.75 mm = 9.14 revs
    assert report["max_chip_revs"] == pytest.approx(16 / 1.75, abs=0.01)
    assert not report["chips_broken"]
    assert vibrating["report"]["max_chip_revs"] < report["max_chip_revs"] / 9


@pytest.mark.parametrize("case", ["vibrating", "conventional"])
def test_command_within_the_axis_limits(case, request):
    result = request.getfixturevalue(case)
    p = result["command"][0]
    for j, joint in enumerate(("x", "z")):
        axis = LATHE.axis(joint)
        vel = np.diff(p[:, j]) / T
        acc = np.diff(vel) / T
        jerk = np.diff(acc) / T
        assert np.abs(vel).max() <= axis.max_velocity * 1.001
        assert np.abs(acc).max() <= axis.max_acceleration * 1.001
        assert np.abs(jerk).max() <= axis.max_jerk * 1.001
        assert axis.within_travel(p[:, j].min()) and axis.within_travel(p[:, j].max())


def test_at_the_highest_accepted_speed_the_feedback_still_breaks_chips():
    with pytest.raises(ThreadError, match=r"max spindle speed (\d+) rpm") as err:
        check_thread(dataclasses.replace(SPEC, spindle_speed=rpm(2000)), LATHE)
    top = int(err.value.args[0].rsplit("max spindle speed ", 1)[1].split()[0])
    assert 700 < top < 800  # the x jerk limit on the first pass's 0.52 mm vibration
    fast = run(dataclasses.replace(SPEC, spindle_speed=rpm(top)))
    report = fast["report"]
    assert report["chips_broken"] and report["full_depth"] and report["helix_residual_mm"] < 0.01
    p = fast["command"][0]
    jerk = np.diff(p[:, 0], 3) / T**3
    assert np.abs(jerk).max() <= LATHE.axis("x").max_jerk * 1.001


def test_compensation_keeps_the_vibration_where_the_lag_loses_it():
    """x and z drives without velocity feed-forward: the plain command's feedback lags and
    smooths the vibration away (one long chip per pass); the drive-compensated one still
    breaks every chip and stays on the helix."""
    drives = {j: dataclasses.replace(LATHE.drives[j], velocity_ff=0.0) for j in ("x", "z")}
    machine = dataclasses.replace(LATHE, drives={**LATHE.drives, **drives})
    lagging = run(SPEC, machine, compensate=False)["report"]
    following = run(SPEC, machine)["report"]
    assert lagging["max_chip_revs"] > 5
    assert following["chips_broken"] and following["full_depth"] and following["helix_residual_mm"] < 0.01


def test_the_command_reads_alike_on_and_off_the_servo_grid(vibrating):
    """The compensated cycle is kept on the servo grid and read there (within rounding of
    an instant, the same values); between two instants it is the motion there plus the
    correction interpolated, so it lies within a_max T^2 / 8 of the two instants' mean (the
    correction is interpolated linearly; the motion bends by at most its acceleration)."""
    result, info = vibrating["plan"], vibrating["info"]
    t = vibrating["t"]
    cycle = (t >= info[0]["t_start"]) & (t <= info[-1]["t_end"])
    columns = [result.joints.index(j) for j in ("x", "z")]
    on_grid = vibrating["command"][0][cycle][:, columns]
    assert np.array_equal(result.sample(t[cycle] + 1e-12)[0][:, columns], on_grid)
    mid = result.sample((t[cycle][:-1] + t[cycle][1:]) / 2)[0][:, columns]
    bound = np.array([LATHE.axis(j).max_acceleration for j in ("x", "z")]) * T**2 / 8 + 1e-12
    off = np.abs(mid - (on_grid[:-1] + on_grid[1:]) / 2)
    assert np.all(off <= bound), (off.max(axis=0), bound)
    assert np.max(off) > 0.0  # read off the grid, not the grid's neighbour


@pytest.mark.parametrize("change", [{}, {"taper": 1 / 16}, {"internal": True, "major_radius": 4.5e-3},
                                    {"taper": 1 / 16, "internal": True, "major_radius": 4.5e-3, "starts": 2}])
def test_the_compiled_stock_check_agrees_with_the_sampled_one_on_every_air_path(change):
    """Every air path the search tries is checked against the stock by the compiled kernel
    (_stock_kernel.c); the numpy check on the sampled tracks gives the same verdict on each
    (straight, tapered, internal, two-start), and both verdicts occur."""
    verdicts, original = [], cycle.ThreadCycle._cuts_stock
    compiled = []

    def both(self, x, z, t):
        verdicts.append((original(self, x, z, t), self._cuts_stock_sampled(x, z, t)))
        return verdicts[-1][0]

    def counted(*args):
        compiled.append(args)
        return inside_stock(*args)

    with mock.patch.object(cycle.ThreadCycle, "_cuts_stock", both), mock.patch.object(cycle, "inside_stock", counted):
        plan(dataclasses.replace(SPEC, **change))
    assert all(kernel == sampled for kernel, sampled in verdicts), verdicts
    assert len(compiled) == len(verdicts)
    assert sum(kernel for kernel, _ in verdicts) >= 10 and sum(not kernel for kernel, _ in verdicts) >= 7


def test_a_pass_whose_exit_time_divides_to_just_below_its_servo_instant_is_joined():
    """At 300 rpm the first pass of this two-start thread leaves its helix at 2.013 s of the
    cycle, and 2.013 / 0.001 is 2012.9999999999998: the stock check of every air path onto
    the next helix began an instant early, on the helix still cutting, and the job was
    refused ("cannot reach the helix of pass 1"). The check starts at the exit's instant."""
    job = dict(JOB, spindle_rpm=300, thread=dict(JOB["thread"], depth=1.073, passes=3, starts=2))
    result = plan_job(parse_job(job), LATHE)
    t = np.arange(0.0, result.duration + T / 2, T)
    feedback = DriveModel(LATHE, T).simulate(*result.sample(t))[0]
    report = analyze_thread(t, feedback[:, 0], feedback[:, 1], feedback[:, 2], job["thread"])
    assert [p["start"] for p in report["passes"]] == [0, 1] * 4
    assert report["chips_broken"] and report["full_depth"] and report["helix_residual_mm"] < 0.01


def test_the_stock_kernel_judges_a_held_tip_and_refuses_pieces_that_leave_instants_uncovered():
    row = np.zeros(ROW_LENGTH)
    with pytest.raises(ValueError, match="x_pieces: the pieces end at instant 3 of 4"):
        inside_stock([(row, 0.0, 0, 4)], [(row, 0.0, 0, 3)], np.zeros(4), 0.0, 0.0, -1.0, 0.02, -1.0, 0.006, 0.0)
    with pytest.raises(ValueError, match="z_pieces: piece 1 does not continue at instant 2"):
        inside_stock([(row, 0.0, 0, 2), (row, 0.0, 3, 4)], [(row, 0.0, 0, 4)], np.zeros(4), 0.0, 0.0, -1.0, 0.02,
                     -1.0, 0.006, 0.0)
    with pytest.raises(ValueError, match="x_pieces: piece 0's row is not 58 contiguous values"):
        inside_stock([(row, 0.0, 0, 4)], [(row[:57], 0.0, 0, 4)], np.zeros(4), 0.0, 0.0, -1.0, 0.02, -1.0, 0.006, 0.0)
    with pytest.raises(ValueError, match="ts: expected one dimension"):
        inside_stock([(row, 0.0, 0, 4)], [(row, 0.0, 0, 4)], np.zeros((2, 2)), 0.0, 0.0, -1.0, 0.02, -1.0, 0.006, 0.0)
    # a tip held at x 5.9 mm, z -1 mm over a 20 mm external thread: inside a 6 mm stock, not a 5.8 mm one
    z, x = rest_row(-1e-3), rest_row(5.9e-3)
    assert inside_stock([(z, 0.0, 0, 4)], [(x, 0.0, 0, 4)], np.zeros(4), 0.0, 0.0, -1.0, 0.02, -1.0, 0.006, 0.0)
    assert not inside_stock([(z, 0.0, 0, 4)], [(x, 0.0, 0, 4)], np.zeros(4), 0.0, 0.0, -1.0, 0.02, -1.0, 0.0058, 0.0)


def test_internal_two_start_thread():
    spec = ThreadSpec(start_z=3e-3, end_z=-5e-3, major_radius=8e-3, pitch=2e-3, depth=0.6e-3,
                      spindle_speed=rpm(500), passes=3, starts=2, internal=True,
                      vibration=ThreadVibration(D=1.5, Q=1.3))
    result = run(spec)
    report, info = result["report"], result["info"]
    assert [(p["index"], p["start"], p["spindle_phase_deg"]) for p in info[:2]] == [(0, 0, 0.0), (0, 1, 180.0)]
    assert [p["start"] for p in report["passes"]] == [0, 1] * 4
    assert report["chips_broken"] and report["full_depth"] and report["helix_residual_mm"] < 0.01
    x = result["command"][0][:, 0]
    # the bore grows with depth: x from the clearance inside it to the full depth outside; the
    # compensated command leads the retract straight into the next plunge and passes the
    # clearance radius (away from the stock) by less than a micrometre
    assert x.min() == pytest.approx(7e-3, abs=1e-6) and x.min() <= 7e-3
    assert x.max() == pytest.approx(8.6e-3, abs=1e-6)


@pytest.mark.parametrize("internal, major_mm", [(False, 6.0), (True, 4.5)])
def test_taper_thread_follows_the_cone_on_feedback(internal, major_mm):
    """1:16 taper: x moves with the groove by taper/2 per unit of z, hand-computed at the face
    and at end_z on the full-depth pass of the motion (the plain command: the compensated
    one leads it near the join); the feedback is full depth below the cone."""
    spec = dataclasses.replace(SPEC, taper=1 / 16, internal=internal, major_radius=mm(major_mm))
    report = run(spec)["report"]
    assert report["chips_broken"] and report["full_depth"] and report["helix_residual_mm"] < 0.01
    motion, info = plan(spec, compensate=False)
    spring = info[-1]
    t = np.arange(math.ceil(spring["t_sync"] / T), math.floor(spring["t_end"] / T)) * T
    x, z, _ = motion.sample(t)[0].T
    tan, radial = math.tan(SPEC.infeed_angle), 1.0 if internal else -1.0
    g = z + 1.07e-3 * tan  # the groove's z under the tip at full depth (feed towards -z)
    on_thread = (g <= 0.0) & (g >= SPEC.end_z)
    assert on_thread.sum() > 800
    expected = mm(major_mm) + radial * (g / 32.0 + 1.07e-3)  # 1:16 on the diameter = 1:32 on x
    assert np.abs(x[on_thread] - expected[on_thread]).max() < 1e-6


BAD = [
    ({"depth": 0.0}, "thread.depth", "> 0"),
    ({"depth": 6.5e-3}, "thread.depth", "major_radius"),
    ({"pitch": 0.0}, "thread.pitch", "> 0"),
    ({"pitch": -1e-3}, "thread.pitch", "> 0"),
    ({"infeed_angle": math.radians(95)}, "thread.infeed_angle", "0..90"),
    ({"infeed_angle": math.radians(-1)}, "thread.infeed_angle", "0..90"),
    ({"end_z": 2e-3}, "thread.end_z", "wrong side"),
    ({"end_z": 6e-3}, "thread.end_z", "wrong side"),
    ({"start_z": -1e-3}, "thread.start_z", "air"),
    ({"start_z": 1e-3}, "thread.start_z", "room before the face"),
    ({"pitch": 60e-3, "vibration": None}, "thread.pitch",
     "z speed 0.6 m/s at 600 rpm, more than the z axis's 0.5 m/s; max 500 rpm"),
    ({"vibration": ThreadVibration(1.5, 1.0, math.pi)}, "vibration.Q", "need Q > 1"),
    ({"vibration": ThreadVibration(1.5, 1.2, math.radians(150))}, None, None),  # accepted
    ({"vibration": ThreadVibration(0.8, 1.2, math.pi)}, "vibration.Q", "need Q >= 1.48"),
    ({"vibration": ThreadVibration(1.5, 1.2, 0.0)}, "vibration.phase_shift", "180 deg"),
    ({"vibration": ThreadVibration(0.5, 1.2, math.pi)}, "vibration.D", "raise D"),
    ({"spindle_speed": rpm(1000)}, "vibration.D", "x axis cannot follow"),
    ({"spring_passes": 0}, "thread.spring_passes", ">= 1"),
    ({"taper": -0.1}, "thread.taper", ">= 0"),
    ({"taper": 0.9, "internal": True}, "thread.taper", "narrows"),
    ({"depths": (0.3e-3, 0.7e-3, 1.07e-3), "passes": 3}, "thread.depths", "grows"),
    ({"spindle_speed": rpm(7000), "vibration": None}, "spindle_rpm", "spindle's"),
]


@pytest.mark.parametrize("change,field,reason", BAD)
def test_bad_threads_are_rejected_naming_the_field(change, field, reason):
    spec = dataclasses.replace(SPEC, **change)
    if field is None:
        check_thread(spec, LATHE)
        return
    builder = PlanBuilder(LATHE, {"x": 7e-3, "z": 4e-3})
    with pytest.raises(ThreadError) as err:
        plan_thread(builder, spec)
    message = str(err.value)
    assert message.startswith(field + ": ") and reason in message and "\n" not in message
    assert all(not tl.pieces for tl in builder.timelines.values())  # nothing moved


def test_e_and_r_vibration_is_no_thread_vibration():
    job = dict(JOB, vibration={"E": 2.0, "R": 1.0, "Q": 1.2})
    with pytest.raises(ThreadError, match=r"^vibration\.E: "):
        ThreadSpec.from_job(parse_job(job))


# -- setup and tool length: the thread goes through the kinematic chain ----------------------
THREAD_M12 = load_job_file(Path(__file__).resolve().parents[3] / "config" / "jobs" / "thread_m12.yaml")


def plan_m12(start_mm: tuple[float, float], **blocks):
    """thread_m12.yaml with extra job blocks, planned from axis (x, z) start_mm."""
    return plan_job(parse_job({**THREAD_M12, **blocks}), LATHE, {"x": mm(start_mm[0]), "z": mm(start_mm[1])})


@pytest.mark.parametrize("turned", [0.0, 30.0])
def test_setup_and_tool_length_shift_the_whole_cycle_on_the_axes(turned):
    """Tool 20 mm, setup origin z -100 mm (from a start shifted alike): every x and z command
    is the unplaced one plus (20, -100) mm, the spindle the same; turning the setup about Z
    only turns the part on the spindle."""
    plain = plan_m12((10.0, 10.0))
    setup = {"origin": [0, 0, -100], "rotation_deg": [0, 0, turned]}
    placed = plan_m12((30.0, -90.0), setup=setup, tool={"length": 20})
    assert placed.joints == plain.joints == ("x", "z", "spindle")
    assert placed.duration == pytest.approx(plain.duration, abs=1e-9)
    t = np.arange(0.0, plain.duration + T / 2, T)
    shift = placed.sample(t)[0] - plain.sample(t)[0]
    assert np.abs(shift[:, 0] - mm(20.0)).max() < 1e-6
    assert np.abs(shift[:, 1] - mm(-100.0)).max() < 1e-6
    assert np.abs(shift[:, 2]).max() == 0.0
    assert [e.name for e in placed.events] == [e.name for e in plain.events]
    assert [e.time for e in placed.events] == pytest.approx([e.time for e in plain.events], abs=1e-9)


@pytest.mark.parametrize("setup", [{"rotation_deg": [0, 10, 0]}, {"rotation_deg": [10, 0, 0]},
                                   {"origin": [5, 0, 0]}, {"origin": [0, 5, 0]}])
def test_a_setup_that_moves_the_thread_off_the_spindle_axis_is_rejected(setup):
    with pytest.raises(JobError) as err:
        plan_m12((10.0, 10.0), setup=setup)
    assert err.value.field == "setup" and "spindle axis" in err.value.reason and "\n" not in str(err.value)


def test_a_setup_beyond_the_z_travel_names_the_thread_field_and_the_axis_position():
    """Origin z -290 mm: the pull-out past end_z (-16 mm in the program) reaches axis z -309.1 mm."""
    with pytest.raises(JobError) as err:
        plan_m12((10.0, 10.0), setup={"origin": [0, 0, -290]})
    assert err.value.field == "thread.end_z"
    assert "axis z = -309.1 mm" in err.value.reason and "-300 mm..50 mm" in err.value.reason
