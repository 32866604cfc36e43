"""Kinematic chain: program pose -> axes and back on every layout, limits, continuity, paths."""
from __future__ import annotations

import functools
import math
from dataclasses import replace
from types import SimpleNamespace as NS

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_msgs_py.machine import (DRIVE_KEYS, SPINDLE, KinematicParams, Machine, MachineError, load_machine,
                                 parse_machine)
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import deg, mm
from cnc_planner.kinematics import (
    LAYOUT_JOINTS,
    Kinematics,
    KinematicsError,
    Setup,
    Tool,
    load_work_offsets,
    rotation,
)

LAYOUTS = list(LAYOUT_JOINTS)
POSE_TOL = 1e-9  # m and rad
TWO_PI = 2 * math.pi


def machine(layout: str):
    """The shipped machine of a layout, with off-centre pivots so that they matter."""
    m = load_machine(layout)
    if layout.startswith("5ax"):
        m = replace(m, kinematics=KinematicParams(pivot=(0.03, -0.02, -0.08), pivot_length=m.kinematics.pivot_length))
    return m


def job_setup(origin_mm=(0.0, 0.0, 0.0), rotation_deg=(0.0, 0.0, 0.0)) -> NS:
    """A job's setup block as parse_job returns it (SI units)."""
    return NS(origin=[mm(v) for v in origin_mm], rotation_deg=[deg(v) for v in rotation_deg])


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def random_joints(m, rng: np.random.Generator, n: int, shrink: float = 0.5) -> dict[str, np.ndarray]:
    """Tilts over nearly all their travel, C and the spindle over a turn, linear axes in the
    middle part of the travel (so that a setup keeps the poses reachable)."""
    out = {}
    for name in LAYOUT_JOINTS[m.layout]:
        axis = m.axes[name]
        if axis.min is None or name == "c":
            out[name] = rng.uniform(-math.pi, math.pi, n)
        else:
            mid, half = (axis.min + axis.max) / 2, (axis.max - axis.min) / 2
            share = 0.98 if axis.type == "rotary" else shrink
            out[name] = rng.uniform(mid - share * half, mid + share * half, n)
    return out


def kin(layout: str, setup: NS | None = None, length: float = 0.0) -> Kinematics:
    return Kinematics(machine(layout), setup or job_setup(), NS(length=length, diameter=None, nose_radius=0.0))


# --- round trips ---------------------------------------------------------------------------

@pytest.mark.parametrize("layout", LAYOUTS)
def test_round_trip_random_poses(layout):
    """FK of random joints gives reachable poses; IK then FK reproduces each one."""
    rng = np.random.default_rng(20240606)
    rot = (0.0, 0.0, 23.0) if layout == "mill3" else (7.0, -5.0, 23.0)  # a mill can't tilt the part
    k = kin(layout, job_setup((12.0, -8.0, 5.0), rot), length=mm(45.0))
    tips, axes = k.fk_many(random_joints(k.machine, rng, 300, shrink=0.4))
    for i in range(len(tips)):
        joints = k.ik_many(tips[i:i + 1], axes[i:i + 1])
        tip2, axis2 = k.fk_many(joints)
        assert np.linalg.norm(tip2[0] - tips[i]) < POSE_TOL
        assert angle_between(axis2, axes[i:i + 1])[0] < POSE_TOL
        assert np.allclose(np.linalg.norm(axis2, axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_vectorised_ik_follows_a_smooth_joint_path(layout):
    """A smooth random joint trajectory -> poses -> ik_many recovers the same joints."""
    rng = np.random.default_rng(7)
    k = kin(layout, job_setup((3.0, 4.0, -2.0), (0.0, 0.0, 10.0)), length=mm(30.0))
    start = random_joints(k.machine, rng, 1, shrink=0.3)
    steps = {j: rng.normal(0.0, 2e-4 if j in "xyz" else 2e-3, 2000) for j in start}
    joints = {j: start[j][0] + np.cumsum(steps[j]) for j in start}
    tilt = {"5ax_table_table": "a", "5ax_head_table": "b"}.get(layout)
    if tilt:  # keep the tilt away from the singular vertical, where C is free
        joints[tilt] = np.clip(joints[tilt], 0.2, 0.5)
    tips, axes = k.fk_many(joints)
    previous = {j: float(v[0]) for j, v in joints.items()}
    solved = k.ik_many(tips, axes if layout != "mill3" else None, previous)
    assert list(solved) == list(LAYOUT_JOINTS[layout])
    for j in solved:
        assert np.max(np.abs(solved[j] - joints[j])) < POSE_TOL, j
    tip2, axis2 = k.fk_many(solved)
    assert np.max(np.linalg.norm(tip2 - tips, axis=1)) < POSE_TOL
    assert np.max(angle_between(axis2, axes)) < POSE_TOL


# --- limits ----------------------------------------------------------------------------------

def tilted(angle_deg: float, azimuth_deg: float = 0.0) -> list[float]:
    t, a = math.radians(angle_deg), math.radians(azimuth_deg)
    return [math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)]


def test_head_beyond_b_limit_named():
    k = kin("5ax_head_table")
    axes = [tilted(0)] * 3 + [tilted(112.0)]
    with pytest.raises(KinematicsError) as info:
        k.ik_many(np.zeros((4, 3)), axes, field="path.points")
    assert str(info.value) == "path.points[3]: needs axis b at 112.0 deg, beyond its limit 90 deg"
    assert isinstance(info.value, JobError) and info.value.field == "path.points[3]"


def test_trunnion_reports_the_nearer_a_limit():
    """A tilt of 125 deg: -125 misses the -120 deg stop by less than +125 misses +30."""
    with pytest.raises(KinematicsError, match=r"^points\[0\]: needs axis a at -125.0 deg, beyond its limit -120 deg$"):
        kin("5ax_table_table").ik_many([[0.0, 0.0, 0.0]], [tilted(125.0, 90.0)])


def test_trunnion_takes_the_branch_within_limits():
    """+40 deg of A is beyond +30, so the solution is A = -40 with C turned half a turn."""
    joints = kin("5ax_table_table").ik_many([[0.0, 0.0, 0.0]], [tilted(40.0, 90.0)])
    assert joints["a"][0] == pytest.approx(deg(-40.0), abs=1e-12)


def test_linear_limit_named_in_mm():
    with pytest.raises(KinematicsError, match=r"^move\[1\]: needs axis x at 600.000 mm, beyond its limit 500 mm$"):
        kin("mill3").ik_many([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0]], field="move")


def test_rotation_moves_linear_axes_out_of_travel():
    """Tilting A swings a far point of the table below Z travel: named by the linear axis."""
    k = kin("5ax_table_table")
    with pytest.raises(KinematicsError, match=r"^points\[0\]: needs axis z at 3\d\d\.\d{3} mm, beyond its limit 200 mm$"):
        k.ik_many([[0.0, -0.45, 0.0]], [tilted(90.0, -90.0)])


def test_mill3_cannot_tilt_the_tool():
    with pytest.raises(KinematicsError, match=r"^points\[1\]: needs the tool tilted 10.000 deg from Z; layout mill3"):
        kin("mill3").ik_many(np.zeros((2, 3)), [[0, 0, 1], tilted(10.0)])


def test_lathe_without_y_rejects_an_off_plane_tool():
    k = kin("lathe")
    with pytest.raises(KinematicsError, match=r"^points\[0\]: needs axis y at 5.000 mm off the tool's plane"):
        k.ik_many([[0.02, 0.005, -0.01]], [[1.0, 0.0, 0.0]])
    # without a tool axis the spindle (C) turns the point onto the plane instead
    joints = k.ik_many([[0.02, 0.02, -0.01]])
    assert joints["x"][0] == pytest.approx(math.hypot(0.02, 0.02), abs=1e-15)
    assert joints["spindle"][0] == pytest.approx(-math.pi / 4, abs=1e-15)


# --- continuity ------------------------------------------------------------------------------

@pytest.mark.parametrize("layout,tilt,plane", [("5ax_head_table", "b", 0.0), ("5ax_table_table", "a", 90.0)])
def test_tool_axis_sweeping_through_vertical(layout, tilt, plane):
    """-25 .. +25 deg through the exact vertical: the tilt passes 0, C does not move."""
    k = kin(layout)
    angles = np.linspace(-25.0, 25.0, 101)  # includes 0 exactly
    axes = np.array([tilted(abs(a), plane if a >= 0 else plane + 180.0) for a in angles])
    joints = k.ik_many(np.zeros((101, 3)), axes, {tilt: deg(-25.0), "c": 0.0})
    assert np.max(np.abs(np.diff(joints[tilt]))) == pytest.approx(deg(0.5), abs=1e-9)
    assert np.max(np.abs(joints["c"])) < 1e-12
    assert joints[tilt][50] == 0.0
    tips, back = k.fk_many(joints)
    assert np.max(angle_between(back, axes)) < POSE_TOL


@pytest.mark.parametrize("layout,tilt,start", [("5ax_head_table", "b", 150.0), ("5ax_table_table", "a", 240.0)])
def test_c_crossing_180_deg_does_not_flip(layout, tilt, start):
    """The azimuth turns 60 deg so that C runs -150 .. -210 deg: past -180 in steps of 0.6 deg."""
    k = kin(layout)
    axes = np.array([tilted(20.0, a) for a in np.linspace(start, start + 60.0, 101)])
    joints = k.ik_many(np.zeros((101, 3)), axes, {tilt: deg(20.0), "c": deg(-150.0)})
    steps = np.diff(joints["c"])
    assert np.max(np.abs(steps)) == pytest.approx(deg(0.6), abs=1e-9) and np.min(np.abs(steps)) > deg(0.59)
    assert joints["c"][[0, -1]] == pytest.approx([deg(-150.0), deg(-210.0)], abs=1e-9)
    assert np.ptp(joints[tilt]) < 1e-12


def test_c_unwinds_continuously_over_turns():
    """Two turns of the azimuth on the continuous trunnion C: C runs 4 pi, never jumps."""
    k = kin("5ax_table_table")
    azimuth = np.linspace(0.0, 720.0, 721)
    joints = k.ik_many(np.zeros((721, 3)), [tilted(15.0, a) for a in azimuth], {"a": deg(-15.0), "c": 0.0})
    assert np.max(np.abs(np.diff(joints["c"]))) < deg(1.0) + 1e-9
    assert abs(joints["c"][-1] - joints["c"][0]) == pytest.approx(2 * TWO_PI, abs=1e-9)


def test_c_with_end_stops_shifts_by_whole_turns():
    """1.5 turns on the +-360 deg head-table C from C = 0: the run is moved a turn to fit."""
    k = kin("5ax_head_table")
    azimuth = np.linspace(0.0, 540.0, 541)
    joints = k.ik_many(np.zeros((541, 3)), [tilted(15.0, a) for a in azimuth], {"b": deg(15.0), "c": 0.0})
    c = joints["c"]
    assert np.max(np.abs(np.diff(c))) < deg(1.0) + 1e-9
    assert c.min() >= -TWO_PI - 1e-12 and c.max() <= TWO_PI + 1e-12
    with pytest.raises(KinematicsError, match=r"needs axis c at .* deg, beyond its limit -?360 deg"):
        k.ik_many(np.zeros((1081, 3)), [tilted(15.0, a) for a in np.linspace(0.0, 1080.0, 1081)])


def test_shortest_way_from_the_previous_position():
    """From C = 350 deg, a pose at azimuth 10 deg lands at 370 deg, not 10."""
    k = kin("5ax_table_table")
    previous = {"a": deg(-20.0), "c": deg(350.0)}
    joints = k.ik_many([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], previous)
    assert joints["c"][0] == pytest.approx(deg(350.0), abs=1e-12)  # vertical: C stays
    solved = k.to_axes({"x": 0.0}, tool_axis=k.fk_many({"a": deg(-20.0), "c": deg(10.0)})[1][0], previous=previous)
    assert solved["c"] == pytest.approx(deg(370.0), abs=1e-9) and solved["a"] == pytest.approx(deg(-20.0), abs=1e-9)


# --- setup and tool --------------------------------------------------------------------------

def test_setup_moves_program_points_as_by_hand():
    """origin (100, 50, 20) mm, 90 deg about Z: program x runs along table y."""
    k = kin("mill3", job_setup((100.0, 50.0, 20.0), (0.0, 0.0, 90.0)))
    axes = k.to_axes({"x": mm(10.0), "y": mm(3.0), "z": mm(-4.0)})
    assert [axes[j] for j in "xyz"] == pytest.approx([mm(100.0 - 3.0), mm(50.0 + 10.0), mm(20.0 - 4.0)], abs=1e-15)
    assert k.to_program(axes) == pytest.approx({"x": mm(10.0), "y": mm(3.0), "z": mm(-4.0)}, abs=1e-15)


def test_setup_rotation_order_x_then_y_then_z():
    """[90, 0, 90] deg: program x -> (X: x) -> (Z: y); program y -> (X: z) -> (Z: z)."""
    r = rotation([deg(90.0), 0.0, deg(90.0)])
    assert r @ [1.0, 0.0, 0.0] == pytest.approx([0.0, 1.0, 0.0], abs=1e-15)
    assert r @ [0.0, 1.0, 0.0] == pytest.approx([0.0, 0.0, 1.0], abs=1e-15)
    # on the 5-axis the tilted setup tilts the tool with it: program +z is table +x here
    k = kin("5ax_head_table", job_setup(rotation_deg=(90.0, 0.0, 90.0)))
    joints = k.to_axes({"x": 0.0})
    assert abs(joints["b"]) == pytest.approx(math.pi / 2, abs=1e-12)
    _, axis = k.fk_many({j: [v] for j, v in joints.items()})
    assert axis[0] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


def test_work_offset_by_name():
    offsets = load_work_offsets()
    assert offsets["G55"].origin == pytest.approx([0.15, 0.0, 0.0], abs=1e-15)
    setup = NS(origin=[0.0, 0.0, 0.0], rotation_deg=[0.0, 0.0, 0.0], work_offset="G56")
    k = kin("mill3", setup)
    axes = k.to_axes({"x": mm(10.0)})  # 90 deg about Z: program x -> table y
    assert [axes[j] for j in "xyz"] == pytest.approx([mm(-150.0), mm(90.0), 0.0], abs=1e-15)
    with pytest.raises(KinematicsError, match=r"^setup.work_offset: no work offset 'G99' in .*known: G54"):
        kin("mill3", NS(origin=None, rotation_deg=None, work_offset="G99"))
    with pytest.raises(KinematicsError, match=r"^setup.work_offset: names a work offset"):
        kin("mill3", NS(origin=[0.01, 0.0, 0.0], rotation_deg=[0.0, 0.0, 0.0], work_offset="G55"))


@pytest.mark.parametrize("layout", ["5ax_head_table", "5ax_table_table"])
def test_tool_length_along_the_tilted_tool_axis(layout):
    """Tool 100 mm longer: the head moves 100 mm along the tool axis in machine space
    (tilted on the head, vertical on the trunnion, which tilts the part instead)."""
    axis = tilted(30.0)
    short, long_ = (kin(layout, length=mm(length)).ik_many([[0.01, 0.0, 0.0]], [axis]) for length in (20.0, 120.0))
    moved = np.array([long_[j][0] - short[j][0] for j in "xyz"])
    head = [math.sin(deg(30.0)), 0.0, math.cos(deg(30.0))] if layout == "5ax_head_table" else [0.0, 0.0, 1.0]
    assert moved == pytest.approx(mm(100.0) * np.array(head), abs=1e-15)
    assert long_["c"][0] == short["c"][0]


def test_tool_data_from_the_job():
    k = Kinematics(load_machine("lathe"), None, NS(length=mm(30.0), diameter=mm(8.0), nose_radius=mm(0.4)))
    assert k.tool == Tool(length=mm(30.0), radius=mm(4.0), nose_radius=mm(0.4))
    assert k.to_axes({"x": mm(10.0), "z": mm(-5.0)}) == pytest.approx({"x": mm(40.0), "z": mm(-5.0)})


@pytest.mark.parametrize("turned", [0.0, 30.0])
def test_lathe_tip_radius_and_z_in_program_coordinates(turned):
    """Tool 20 mm, setup origin z -100 mm (turned about Z or not): axis x 26, z -96 mm is the
    tip at radius 6 mm, z 4 mm; on the spindle axis at x 20 mm; at any spindle angle."""
    k = Kinematics(load_machine("lathe"), job_setup((0.0, 0.0, -100.0), (0.0, 0.0, turned)), NS(length=mm(20.0)))
    x, z = np.array([mm(26.0), mm(20.0), mm(30.5)]), np.array([mm(-96.0), mm(-100.0), mm(-116.0)])
    radius, program_z = k.tip_radius_z(x, z)
    assert radius == pytest.approx([mm(6.0), 0.0, mm(10.5)], abs=1e-15)
    assert program_z == pytest.approx([mm(4.0), 0.0, mm(-16.0)], abs=1e-15)
    tips, _ = k.fk_many({"x": x, "z": z, "spindle": np.array([0.3, 2.0, -4.0])})
    assert np.hypot(tips[:, 0], tips[:, 1]) == pytest.approx(radius, abs=1e-15)
    assert tips[:, 2] == pytest.approx(program_z, abs=1e-15)


# --- the existing mill3 / lathe behaviour ----------------------------------------------------

@pytest.mark.parametrize("layout,point", [("mill3", {"x": 0.1, "y": -0.05, "z": 0.02}), ("lathe", {"x": 0.03, "z": -0.1}),
                                          ("lathe", {"x": -0.004, "z": 0.01}), ("lathe_y", {"x": 0.03, "y": 0.01, "z": -0.1})])
def test_zero_setup_and_tool_tip_equals_linear_axes(layout, point):
    k = Kinematics(load_machine(layout), NS(origin=[0.0] * 3, rotation_deg=[0.0] * 3), NS(length=0.0))
    axes = k.to_axes(point)
    assert axes == {j: point[j] for j in k.machine.linear_axes}
    assert k.to_program(axes) == axes


def test_mill3_tool_length_lifts_z():
    k = Kinematics(load_machine("mill3"), job_setup(), NS(length=mm(50.0)))
    assert k.to_axes({"x": 0.01, "z": -0.02}) == pytest.approx({"x": 0.01, "y": 0.0, "z": 0.03}, abs=1e-15)
    assert k.to_program({"x": 0.01, "y": 0.0, "z": 0.03}) == pytest.approx({"x": 0.01, "y": 0.0, "z": -0.02}, abs=1e-15)


# --- path sampler ----------------------------------------------------------------------------

def deviation(k: Kinematics, path, points: np.ndarray, fractions: int = 41) -> float:
    """Max distance of the FK tip of linearly interpolated joints from the programmed lines."""
    worst = 0.0
    seg = np.minimum(np.floor(path.param[:-1]), len(points) - 2).astype(int)
    still = (path.param[1:] == path.param[:-1])[:, None]  # C turning at a point: the tip stays there
    a = np.where(still, path.tips[:-1], points[seg])
    b = np.where(still, path.tips[:-1], points[seg + 1])
    length = np.linalg.norm(b - a, axis=1)[:, None]
    d = (b - a) / np.where(length > 0, length, 1.0)  # a standing tip: distance to the point
    for f in np.linspace(0.0, 1.0, fractions):
        tip, _ = k.fk_many({j: v[:-1] + f * (v[1:] - v[:-1]) for j, v in path.joints.items()})
        off = tip - a
        worst = max(worst, float(np.max(np.linalg.norm(off - np.einsum("ij,ij->i", off, d)[:, None] * d, axis=1))))
    return worst


@pytest.mark.parametrize("layout", ["5ax_table_table", "5ax_head_table"])
def test_path_sampler_keeps_the_tip_on_the_line_while_tilting_30_deg(layout):
    k = kin(layout, job_setup((20.0, -10.0, 15.0)), length=mm(80.0))
    points = np.array([[-0.06, -0.02, 0.0], [0.06, 0.03, -0.01]])
    axes = np.array([tilted(0.0), tilted(30.0, 45.0)])
    tol, feed = mm(0.01), mm(600.0) / 60.0
    coarse = k.ik_many(points, axes)
    path = k.sample_path(points, axes, feed, tol)
    assert deviation(k, path, points) <= tol
    assert deviation(k, NS(param=np.array([0.0, 1.0]), tips=points, joints=coarse), points) > 10 * tol  # why it samples
    assert len(path.param) > 10
    assert path.lengths.sum() == pytest.approx(np.linalg.norm(points[1] - points[0]), abs=1e-12)
    assert np.all(path.durations >= path.lengths / feed)
    ends, tool = k.fk_many({j: v[[0, -1]] for j, v in path.joints.items()})
    assert ends == pytest.approx(points, abs=1e-12)
    assert angle_between(tool, axes) == pytest.approx([0.0, 0.0], abs=1e-9)
    # the tool axis at every waypoint is the slerp of the two programmed axes
    cos_start = np.clip(path.tool_axes @ axes[0], -1, 1)
    assert np.arccos(cos_start) == pytest.approx(path.param * deg(30.0), abs=1e-6)


def test_path_sampler_several_points_and_a_pure_reorientation():
    k = kin("5ax_head_table")
    points = np.array([[0.0, 0.0, 0.0], [0.03, 0.0, 0.0], [0.03, 0.0, 0.0], [0.03, 0.04, -0.01]])
    axes = np.array([tilted(0.0), tilted(20.0, 90.0), tilted(35.0, 180.0), tilted(10.0, 270.0)])
    path = k.sample_path(points, axes, mm(1000.0) / 60.0, mm(0.005))
    assert deviation(k, path, points) <= mm(0.005)
    turning = (path.param[:-1] >= 1.0) & (path.param[1:] <= 2.0)
    assert turning.sum() > 1 and np.all(path.lengths[turning] == 0.0)
    assert np.all(path.durations[turning] > 0.0)  # timed by the rotary axes' max_velocity


@pytest.mark.parametrize("layout", ["5ax_table_table", "5ax_head_table"])
def test_path_sampler_turns_c_at_an_inner_vertical_point(layout):
    """Tilted towards +X, vertical at the middle point, then tilted towards +Y: C turns
    90 deg at the middle point while the tip stands there, within the tolerance."""
    k = kin(layout, length=mm(60.0))
    points = np.array([[0.08, 0.0, 0.0], [0.08, 0.03, 0.0], [0.05, 0.06, -0.01]])
    axes = np.array([tilted(20.0, 0.0), [0.0, 0.0, 1.0], tilted(20.0, 90.0)])
    tol = mm(0.002)
    path = k.sample_path(points, axes, mm(1000.0) / 60.0, tol)
    assert deviation(k, path, points) <= tol
    at_middle = path.param == 1.0
    assert at_middle.sum() > 10  # the turn, in steps
    assert np.ptp(path.joints["c"][at_middle]) == pytest.approx(math.pi / 2, abs=1e-9)
    assert np.max(np.abs(np.diff(path.joints["c"]))) < deg(5.0)
    assert np.all(path.lengths[at_middle[1:] & at_middle[:-1]] == 0.0)
    ends, tool = k.fk_many({j: v[[0, -1]] for j, v in path.joints.items()})
    assert ends == pytest.approx(points[[0, -1]], abs=1e-12)


def test_a_path_starting_vertical_takes_the_c_it_will_need():
    """The vertical first pose borrows C from the next one, not from before the path."""
    k = kin("5ax_head_table")
    joints = k.ik_many(np.zeros((3, 3)), [[0.0, 0.0, 1.0], tilted(1.0, 45.0), tilted(2.0, 45.0)], {"b": 0.0, "c": 0.3})
    assert joints["c"] == pytest.approx([deg(-45.0)] * 3, abs=1e-12)
    assert joints["b"] == pytest.approx([0.0, deg(1.0), deg(2.0)], abs=1e-12)


def test_path_sampler_names_the_unreachable_point():
    k = kin("5ax_head_table")
    points = np.zeros((3, 3))
    axes = np.array([tilted(0.0), tilted(60.0), tilted(100.0)])
    with pytest.raises(KinematicsError, match=r"^path.points\[2\]: needs axis b at 100.0 deg, beyond its limit 90 deg$"):
        k.sample_path(points, axes, 0.01, mm(0.01))
    with pytest.raises(KinematicsError, match=r"^path.tool_axis\[1\]: turns 180 deg"):
        k.sample_path(points[:2], [[0, 0, 1], [0, 0, -1]], 0.01, mm(0.01))


def test_path_on_mill3_is_the_programmed_points():
    k = kin("mill3")
    points = np.array([[0.0, 0.0, 0.0], [0.05, 0.02, -0.01], [0.05, 0.05, -0.01]])
    path = k.sample_path(points, None, 0.01, mm(0.001))
    assert path.param == pytest.approx([0.0, 1.0, 2.0])
    assert np.stack([path.joints[j] for j in "xyz"], axis=1) == pytest.approx(points, abs=1e-15)


# --- machine descriptions --------------------------------------------------------------------

def test_shipped_machines_have_their_layout_joints():
    for layout in LAYOUTS:
        m = load_machine(layout)
        assert set(LAYOUT_JOINTS[layout]) <= set(m.joint_names)
        assert set(m.drives) == set(m.joint_names)
    assert load_machine("5ax_table_table").kinematics == KinematicParams(pivot=(0.0, 0.0, -0.05))
    a = load_machine("5ax_table_table").axes["a"]
    assert (a.min, a.max) == pytest.approx((deg(-120.0), deg(30.0)))


def test_kinematics_block_is_checked():
    doc = {"name": "t", "layout": "5ax_head_table", "kinematics": {"pivot": [0, 0], "pivot_length": 0.1},
           "axes": {}, "drive": {}}
    base = load_machine("5ax_head_table")
    doc["axes"] = {n: {"type": a.type, "min": a.min, "max": a.max, "max_velocity": a.max_velocity,
                       "max_acceleration": a.max_acceleration, "max_jerk": a.max_jerk} for n, a in base.axes.items()}
    doc["drive"] = {n: {k: v for k, v in vars(d).items() if k in DRIVE_KEYS} for n, d in base.drives.items()}
    with pytest.raises(MachineError, match=r"kinematics.pivot: expected \[x, y, z\]"):
        parse_machine(doc, "t")
    doc["kinematics"] = {"pivot": [0, 0, 0], "swing": 1}
    with pytest.raises(MachineError, match=r"kinematics.swing: unknown key"):
        parse_machine(doc, "t")
    doc["kinematics"] = {"pivot": [0.1, 0, 0], "pivot_length": 0.25}
    assert parse_machine(doc, "t").kinematics == KinematicParams(pivot=(0.1, 0.0, 0.0), pivot_length=0.25)


def test_layout_needs_its_axes():
    m = load_machine("mill3")
    with pytest.raises(MachineError, match=r"layout 5ax_head_table needs axis 'b'"):
        Kinematics(replace(m, layout="5ax_head_table"), Setup(), Tool())


# --- drawn 5-axis machines (hypothesis) ------------------------------------------------------

FIVE_AXIS = settings(derandomize=True, database=None, deadline=None, print_blob=False,
                     suppress_health_check=[HealthCheck.too_slow])
metres = lambda lo, hi: st.floats(lo, hi, allow_nan=False, allow_infinity=False)  # noqa: E731


@functools.cache
def shipped(layout: str) -> Machine:
    return load_machine(layout)


@st.composite
def five_axis_machines(draw) -> Machine:
    """A 5-axis machine description as a YAML file holds it, the shipped one's dynamics
    with its geometry drawn anew: pivot, pivot_length (head-table) and every axis's travel
    (the tilt within +-180 deg, C continuous or with end stops of one to two turns)."""
    layout = draw(st.sampled_from(["5ax_table_table", "5ax_head_table"]))
    base = shipped(layout)
    kinematics = {"pivot": [draw(metres(-0.2, 0.2)) for _ in "xyz"]}
    if layout == "5ax_head_table":
        kinematics["pivot_length"] = draw(metres(0.0, 0.4))
    axes = {}
    for name, a in base.axes.items():
        spec = {"type": a.type, "max_velocity": a.max_velocity, "max_acceleration": a.max_acceleration,
                "max_jerk": a.max_jerk}
        if a.type == "linear":
            spec.update(min=draw(metres(-1.0, -0.05)), max=draw(metres(0.05, 1.0)))
        elif name == "c" and draw(st.booleans()):
            turns = draw(st.floats(1.0, 2.0))
            spec.update(type="rotary", min=-turns * TWO_PI, max=turns * TWO_PI)
        elif name == "c":
            spec["type"] = "continuous"
        elif name != SPINDLE:  # the tilt
            spec.update(type="rotary", min=-draw(st.floats(0.05, math.pi)), max=draw(st.floats(0.05, math.pi)))
        axes[name] = spec
    doc = {"name": f"drawn_{layout}", "layout": layout, "kinematics": kinematics, "axes": axes,
           "drive": {n: {k: v for k, v in vars(d).items() if k in DRIVE_KEYS} for n, d in base.drives.items()}}
    return parse_machine(doc, "drawn")


@st.composite
def tool_axes(draw) -> list[float]:
    """Unit tool axes of every tilt, the exact vertical and the near-singular ones included."""
    tilt = draw(st.sampled_from([0.0, 1e-13, 1e-9]) | st.floats(0.0, math.pi))
    azimuth = draw(st.floats(-math.pi, math.pi))
    return [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)]


def drawn_kin(draw, m) -> Kinematics:
    """Kinematics of a drawn machine with a drawn setup and tool length."""
    setup = job_setup([draw(st.floats(-50.0, 50.0)) for _ in "xyz"], [draw(st.floats(-30.0, 30.0)) for _ in "xyz"])
    return Kinematics(m, setup, NS(length=draw(metres(0.0, 0.2))))


def test_drawn_5_axis_machines_forward_inverts_inverse():
    """On drawn 5-axis machines, FK(IK(tip, tool axis)) is the tip and the tool axis within
    1e-9 wherever IK finds joints; where it does not, it refuses with a JobError (an
    exception of another type fails the test). Neither outcome is vacuous."""
    outcomes = []

    @settings(FIVE_AXIS, max_examples=400)
    @given(five_axis_machines(), st.lists(metres(-0.4, 0.4), min_size=3, max_size=3), tool_axes(), st.data())
    def run(m, tip, axis, data):
        k = drawn_kin(data.draw, m)
        try:
            joints = k.ik_many([tip], [axis])
        except JobError as err:
            assert err.field == "points[0]" and "needs axis" in str(err), err
            outcomes.append("refused")
            return
        for name, values in joints.items():
            assert m.axes[name].within_travel(float(values[0]), 1e-12), name
        tips, axes = k.fk_many(joints)
        assert np.linalg.norm(tips[0] - tip) < POSE_TOL
        assert angle_between(axes, np.array([axis]))[0] < POSE_TOL
        outcomes.append("reached")

    run()
    reached, refused = outcomes.count("reached"), outcomes.count("refused")
    assert reached > 100 and refused > 10, (reached, refused)


def test_drawn_5_axis_machines_refuse_a_point_out_of_reach():
    """A tip metres away from every drawn machine's work volume is refused as a JobError that
    names the pose and an axis beyond its limit, at any tool axis (vertical included)."""

    @settings(FIVE_AXIS, max_examples=200)
    @given(five_axis_machines(), tool_axes(), tool_axes(), metres(5.0, 100.0), st.data())
    def run(m, direction, axis, distance, data):
        k = drawn_kin(data.draw, m)
        with pytest.raises(JobError, match=r"^path\[0\]: needs axis \w+ at -?\d+\.\d+ (mm|deg), beyond its limit"):
            k.ik_many([distance * np.array(direction)], [axis], field="path")

    run()
