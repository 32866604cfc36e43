"""From a validated job (SI units) to a Plan: the planner's one entry point.

Every target is converted from program to axis coordinates and checked against the
soft limits before anything is planned, so a job either plans whole or is rejected
with the field that broke it.

Drill jobs: a setup (or ``setup.work_offset``) moves and turns the hole pattern. On the
5-axis machines a setup that tilts the program's Z is drilled in the tilted frame
(``tilted_frame``): rotaries positioned once, then the overlapped cycle planned on a
3-DOF stand-in machine whose axes are program u, v, w and mapped linearly to X/Y/Z.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from types import SimpleNamespace
from typing import Callable

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Axis, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_deg, to_mm, to_mm_per_min, to_rpm

from cnc_servo_bridge.drive import DriveModel

from .builder import PlanBuilder
from .clamps import OBSTACLE_MARGIN, crossed, under_tool
from .drilling import RETURN_CLEARANCE, DrillCycle, plan_drilling
from .headroom import plan_within_limits
from .hole_order import shortest_order
from .peck import PLANE_GAP as PECK_PLANE_GAP, Peck
from .kinematics import Kinematics
from .motion import axis_limits, path_limits, shared_samples
from .path_job import plan_path
from .timeline import Event, Piece, Plan
from .thread_cutting import ThreadError, ThreadSpec, check_thread, plan_thread
from .turning import TurningError, check_outlines, plan_roughing
from .vibration import Vibration, VibrationError, VibrationFeed, check_vibration, er_vibration

TWO_PI = 6.283185307179586
SERVO_PERIOD = 1e-3  # the bridge's servo period: compensation and the plan check use it
XYZ = ("x", "y", "z")
INTERNAL = "cannot be planned: internal planner error"
MAX_VIBRATION_FEED_S = 600.0  # one vibrated feed move at most this long: its compensation is
# precomputed on the servo grid, so its memory grows with its duration
# The layouts each kind of job can run on (move runs on every layout).
KIND_LAYOUTS = {
    "drill": ("mill3", "5ax_table_table", "5ax_head_table"),
    "turn": ("lathe", "lathe_y"),
    "thread": ("lathe", "lathe_y"),
}


def to_axes(kin: Kinematics, point: dict[str, float], field: str) -> dict[str, float]:
    """Kinematics.to_axes, with an unreachable point blamed on the job field it came from."""
    try:
        return kin.to_axes(point)
    except JobError as err:
        if err.field:
            raise
        raise JobError(field, err.reason) from err


def check_travel(machine: Machine, axes: dict[str, float], field: str) -> None:
    """Raise JobError if an axis position lies outside the machine's soft limits."""
    for name, position in axes.items():
        axis = machine.axes[name]
        if not axis.within_travel(position):
            raise JobError(
                field,
                f"puts axis {name} at {to_mm(position):.3f} mm, outside its travel "
                f"[{to_mm(axis.min):g}, {to_mm(axis.max):g}] mm",
            )


def _program_axes(machine: Machine, target: SimpleNamespace, field: str) -> list[str]:
    given = [k for k, v in vars(target).items() if v is not None]
    for key in given:
        if key not in machine.linear_axes:
            raise JobError(f"{field}.{key}", f"machine '{machine.name}' has no {key} axis")
    return given


def vibration_of(job: SimpleNamespace) -> Vibration | None:
    """The job's vibration; E and R without Q take the method's straight-stroke waveform
    (vibration.er_vibration)."""
    v = job.vibration
    if v is None:
        return None
    return Vibration(D=v.D, Q=v.Q, E=v.E, R=v.R) if v.Q is not None else er_vibration(v.E, v.R)


def _vibration_error(err: VibrationError) -> JobError:
    """A VibrationError ('vibration.X: reason') as the JobError naming that field."""
    name, _, reason = str(err).partition(":")
    return JobError(name, reason.strip())


def feed_move(builder: PlanBuilder, target: dict[str, float], feed_per_rev: float,
              vibration: Vibration | None, field: str) -> float:
    """A straight feed at ``feed_per_rev`` of the turning spindle, with chip-breaking
    vibration along the path if given; returns the end time.

    The vibration is locked to the spindle angle, so the move starts once the spindle
    runs at speed; the drive model of the axis that moves most pre-compensates it.
    """
    machine = builder.machine
    speed = builder.timelines[SPINDLE].end_velocity
    if vibration is None:
        return builder.linear(target, feed_per_rev * abs(speed) / TWO_PI)
    joints = list(target)
    p0 = np.array([builder.position(j) for j in joints])
    delta = np.array([target[j] for j in joints]) - p0
    length = float(np.linalg.norm(delta))
    start = max(builder.end_time(), builder.spindle_ready)
    if length <= 1e-12:
        return start
    direction = delta / length
    lim = path_limits(direction, [axis_limits(machine.axes[j]) for j in joints], None)
    lead = joints[int(np.argmax(np.abs(direction)))]  # errors name the axis that moves most
    along = replace(machine.axes[lead], max_velocity=lim.velocity,
                    max_acceleration=lim.acceleration, max_jerk=lim.jerk)
    seconds = length / (feed_per_rev * abs(speed) / TWO_PI)
    if seconds > MAX_VIBRATION_FEED_S:
        raise JobError(f"{field}.feed", f"a vibrated feed of {to_mm(length):.4g} mm lasts {seconds:.4g} s at this "
                       f"feed and spindle speed, more than the maximum {MAX_VIBRATION_FEED_S:g} s")
    try:
        move = VibrationFeed(length, feed_per_rev, vibration, abs(speed), along,
                             start_angle=builder.timelines[SPINDLE].position_at(start),
                             drive_model_factory=lambda: DriveModel(machine, SERVO_PERIOD, (lead,)))
    except VibrationError as err:
        if not str(err).startswith("vibration"):  # about the move itself (e.g. its length)
            raise JobError(field, str(err)) from err
        raise _vibration_error(err) from err
    builder.event(start, "vibration_feed", start=p0.tolist(), direction=direction.tolist(),
                  joints=joints, length=length, feed_per_rev=feed_per_rev, field=field)
    for dof, joint in enumerate(joints):
        builder.timelines[joint].add(Piece(start, move.duration, _along(move, p0[dof], direction[dof])),
                                     float(target[joint]))
    builder.event(start + move.duration, "vibration_end")
    return start + move.duration


def _along(move: VibrationFeed, p0: float, d: float):
    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, v, a = move.sample(t)
        return p0 + d * s, d * v, d * a
    return sample


def move_targets(job: SimpleNamespace, machine: Machine, kin: Kinematics,
                 start: dict[str, float]) -> list[dict[str, float] | None]:
    """Every move's axis target (None for a dwell), from the machine at ``start``, checked
    against the travel: a program is checked whole before any of it is planned."""
    tip = kin.to_program({j: start.get(j, 0.0) for j in machine.linear_axes})
    targets: list[dict[str, float] | None] = []
    for i, move in enumerate(job.move):
        if move.dwell is not None:
            targets.append(None)
            continue
        kind = "rapid" if move.rapid is not None else "linear"
        target = getattr(move, kind)
        field = f"move[{i}].{kind}"
        for key in _program_axes(machine, target, field):
            tip[key] = getattr(target, key)
        axes = to_axes(kin, tip, field)
        check_travel(machine, axes, field)
        targets.append(axes)
    return targets


def plan_move(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """A list of rapid, linear and dwell moves in absolute program coordinates."""
    targets = move_targets(job, machine, kin, {j: builder.position(j) for j in machine.linear_axes})
    vibration = vibration_of(job)
    if job.spindle_rpm > 0:
        builder.spindle(job.spindle_rpm)
    for i, (move, axes) in enumerate(zip(job.move, targets)):
        start = builder.end_time()
        if axes is None:
            for joint in machine.linear_axes:
                builder.timelines[joint].add_hold(start, move.dwell)
            builder.event(start, "dwell", move=i)
            continue
        kind = "rapid" if move.rapid is not None else "linear"
        builder.event(start if kind == "rapid" else max(start, builder.spindle_ready), kind, move=i)
        if kind == "rapid":
            builder.rapid(axes)
        elif vibration is None:
            builder.linear(axes, move.feed)
        else:
            feed_move(builder, axes, move.feed / (job.spindle_rpm / TWO_PI), vibration, f"move[{i}]")


def drill_cycle(job: SimpleNamespace, machine: Machine, kin: Kinematics,
                start_xy: tuple[float, float] | None = None) -> DrillCycle:
    """The drill block in axis coordinates, checked against the travel (shared with analysis).

    Holes are in drilling order (``order: shortest`` tours them from ``start_xy``, the
    first hole if not given); ``cycle.order`` maps them back to the job's hole indices.
    r_z is the plane X/Y moves above: the highest R, raised to clearance_z; a move between
    two holes rises higher only over the obstacles it passes over (air_planes)."""
    d = job.drill
    if tilted(kin):
        if machine.layout == "mill3":
            field = "setup.work_offset" if getattr(job.setup, "work_offset", None) else "setup.rotation_deg"
            raise JobError(field, "a 3-axis mill drills along Z only: tilt needs a 5-axis machine")
        return tilted_frame(job, machine, kin).cycle
    z_rapid = machine.axes["z"].max_velocity
    if d.feed > z_rapid:
        raise JobError("drill.feed", f"{to_mm_per_min(d.feed):g} mm/min is faster than the Z rapid "
                                     f"{to_mm_per_min(z_rapid):g} mm/min")
    holes, planes = [], []
    z_of = lambda z: to_axes(kin, {"z": z}, "drill.surface_z")["z"]  # noqa: E731  (Z is not rotated on a mill)
    for i, ((x, y), (surface, depth)) in enumerate(zip(d.holes, d.hole_planes)):
        bottom = to_axes(kin, {"x": x, "y": y, "z": surface - depth}, f"drill.holes[{i}]")
        check_travel(machine, bottom, f"drill.holes[{i}]")
        holes.append((bottom["x"], bottom["y"]))
        planes.append((z_of(surface), z_of(surface + d.r_gap), bottom["z"]))
    order = list(range(len(holes)))
    if d.order == "shortest":
        order = shortest_order(holes, holes[0] if start_xy is None else start_xy)
    r_z = _xy_plane(d, planes)
    if d.clearance_z is not None:
        r_z = max(r_z, z_of(d.clearance_z))
    path = [d.holes[k] for k in order]
    obstacle_tops(job, path)  # a hole under an obstacle is refused
    air = [r_z] + [max([r_z] + [z_of(top) for top in obstacle_tops(job, pair)]) for pair in zip(path, path[1:])]
    check_travel(machine, {"z": r_z + RETURN_CLEARANCE}, "drill.r_gap" if d.clearance_z is None else "drill.clearance_z")
    check_travel(machine, {"z": max(air) + RETURN_CLEARANCE}, "drill.obstacles")
    uniform = len(set(planes)) == 1 and planes[0][1] == r_z
    return DrillCycle(holes=[holes[k] for k in order], surface_z=max(p[0] for p in planes),
                      bottom_z=min(p[2] for p in planes), r_z=r_z,
                      feed=d.feed, overlap=d.overlap != "off", mode=None if d.mode == "auto" else d.mode,
                      gentle_air_accel=d.gentle_air_accel, dwell=d.dwell,
                      hole_planes=None if uniform else tuple(planes[k] for k in order),
                      peck=_peck(d), order=tuple(order), air_planes=tuple(air) if max(air) > r_z else None,
                      **drill_vibration(job, machine))


def _peck(d: SimpleNamespace) -> Peck | None:
    return None if d.peck is None else Peck(d.peck.depth, d.peck.retract == "full", d.peck.full_every)


def _xy_plane(d: SimpleNamespace, planes: list | tuple) -> float:
    """The highest R, and just above it when pecks retract fully to R (peck.PLANE_GAP)."""
    r_z = max(r for _, r, _ in planes)
    return r_z + PECK_PLANE_GAP if d.peck is not None and (d.peck.retract == "full" or d.peck.full_every) else r_z


def obstacle_tops(job: SimpleNamespace, path: list[list[float]]) -> list[float]:
    """Program z (m) the tip keeps over each obstacle that the X/Y path between the holes
    (program coordinates, in drilling order) passes over; a hole under one is refused."""
    obstacles = job.drill.obstacles or []
    radius = (job.tool.diameter or 0.0) / 2.0
    touched = under_tool(obstacles, path, radius)
    if touched is not None:
        k, i = touched
        raise JobError(f"drill.obstacles[{k}]", f"lies under the tool at a hole ({_mm_of(path[i])})")
    return [obstacles[k][4] + OBSTACLE_MARGIN for k in crossed(obstacles, path, radius)]


def _mm_of(point: list[float]) -> str:
    return ", ".join(f"{to_mm(v):g}" for v in point) + " mm"


def drill_vibration(job: SimpleNamespace, machine: Machine) -> dict:
    """The drill feed's vibration and spindle speed (DrillCycle fields), checked up front
    like a move's: no air-cut or an axis that cannot follow is refused naming min Q / max rpm."""
    vibration = vibration_of(job)
    if vibration is None:
        return {}
    try:
        check_vibration(vibration, job.drill.feed / (job.spindle_rpm / TWO_PI), job.spindle_rpm, machine.axes["z"])
    except VibrationError as err:
        raise _vibration_error(err) from err
    return {"vibration": vibration, "spindle_speed": job.spindle_rpm}


def tilted(kin: Kinematics) -> bool:
    """Whether the setup tilts the program's Z away from the table's Z."""
    return float(np.linalg.norm(kin.setup.rotation[:, 2] - [0.0, 0.0, 1.0])) > 1e-9


@dataclass(frozen=True)
class TiltedFrame:
    """A drill job in a tilted setup on a 5-axis machine, with the rotaries fixed.

    With the rotary axes standing still the linear axes are an affine function of the
    tip in program coordinates: ``xyz = origin + matrix @ (u, v, w)`` (w along the tool
    axis = program Z). ``cycle`` is the drill cycle in program coordinates and
    ``machine`` a 3-DOF stand-in whose axes x, y, z are u, v, w, their limits the
    machine's linear limits projected onto them; its drives are the real x, y, z drives
    (identical, so the drive model commutes with the map and feedback safety carries over).
    """

    rotaries: dict[str, float]
    origin: np.ndarray
    matrix: np.ndarray
    cycle: DrillCycle
    machine: Machine

    def to_axes(self, uvw: np.ndarray) -> np.ndarray:
        return self.origin + np.asarray(uvw, float) @ self.matrix.T

    def to_frame(self, xyz: np.ndarray) -> np.ndarray:
        return np.linalg.solve(self.matrix, np.asarray(xyz, float) - self.origin)


def tilted_frame(job: SimpleNamespace, machine: Machine, kin: Kinematics) -> TiltedFrame:
    """Rotaries that put the tool along program +Z, the affine map and the program-frame cycle."""
    d = job.drill
    if job.vibration is not None:
        raise JobError("vibration", "the drill feed vibrates along the machine's Z only: not in a tilted setup")
    for key, default in (("clearance_z", None), ("obstacles", None), ("order", "given")):
        if getattr(d, key) != default:
            raise JobError(f"drill.{key}", "not available in a tilted setup yet")
    z_axis = [0.0, 0.0, 1.0]
    def joints(point: dict[str, float], field: str, previous: dict[str, float] | None = None) -> dict[str, float]:
        try:
            return kin.to_axes(point, z_axis, previous)
        except JobError as err:
            if err.field:
                raise
            raise JobError(field, err.reason) from err
    x0, y0 = d.holes[0]
    first = joints({"x": x0, "y": y0, "z": d.surface_z}, "drill.holes[0]")
    rotaries = {j: v for j, v in first.items() if j not in XYZ}
    check_travel_any(machine, rotaries, "setup")
    at = lambda p: np.array([joints(dict(zip(XYZ, p)), "drill", rotaries)[j] for j in XYZ])  # noqa: E731
    base = np.array([x0, y0, d.surface_z])
    step = 1e-3  # the map is affine: any step gives it, a short one stays within the travel
    at_base = at(base)
    matrix = np.stack([(at(base + step * e) - at_base) / step for e in np.eye(3)], axis=1)
    origin = at_base - matrix @ base
    axes = {}
    for k, name in enumerate(XYZ):
        col = np.abs(matrix[:, k])
        real = [machine.axes[j] for j in XYZ]
        scale = lambda attr: min(getattr(a, attr) / c for a, c in zip(real, col) if c > 1e-12)  # noqa: E731
        axes[name] = Axis(name, "linear", -100.0, 100.0, scale("max_velocity"), scale("max_acceleration"),
                          scale("max_jerk"))
    axes[SPINDLE] = machine.axes[SPINDLE]
    frame_machine = Machine(f"{machine.name}/tilted", "mill3", axes,
                            {j: machine.drives[j] for j in (*XYZ, SPINDLE) if j in machine.drives})
    if d.feed > axes["z"].max_velocity:
        raise JobError("drill.feed", f"{to_mm_per_min(d.feed):g} mm/min is faster than the rapid along the "
                                     f"tilted tool axis {to_mm_per_min(axes['z'].max_velocity):g} mm/min")
    planes = tuple((s, s + d.r_gap, s - depth) for s, depth in d.hole_planes)
    r_z = _xy_plane(d, planes)
    frame = TiltedFrame(rotaries, origin, matrix,
                        DrillCycle(holes=[tuple(h) for h in d.holes], surface_z=max(p[0] for p in planes),
                                   bottom_z=min(p[2] for p in planes), r_z=r_z, feed=d.feed,
                                   overlap=d.overlap != "off", mode=None if d.mode == "auto" else d.mode,
                                   gentle_air_accel=d.gentle_air_accel, dwell=d.dwell,
                                   hole_planes=None if len(set(planes)) == 1 and planes[0][1] == r_z else planes,
                                   peck=_peck(d)),
                        frame_machine)
    c = frame.cycle
    for i, (x, y) in enumerate(d.holes):
        for z, field in ((c.planes(i)[2], f"drill.holes[{i}]"), (c.r_z + RETURN_CLEARANCE, "drill.r_gap")):
            check_travel(machine, dict(zip(XYZ, frame.to_axes([x, y, z]))), field)
    return frame


def check_travel_any(machine: Machine, axes: dict[str, float], field: str) -> None:
    """check_travel for any joint type (rotaries in deg)."""
    for name, position in axes.items():
        axis = machine.axes[name]
        if not axis.within_travel(position):
            raise JobError(field, f"puts axis {name} at {to_deg(position):.3f} deg, outside its travel "
                                  f"[{to_deg(axis.min):g}, {to_deg(axis.max):g}] deg")


def _mapped(timelines: list, t0: float, row: np.ndarray, offset: float):
    """A sampler of one real linear axis: offset + row . (u, v, w) of the frame timelines."""
    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if len(t) == 0:
            return t.copy(), t.copy(), t.copy()
        out = [np.zeros_like(t) for _ in range(3)]
        for k, timeline in enumerate(timelines):
            for q, s in zip(out, timeline.sample(t + t0)):
                q += row[k] * s
        out[0] += offset
        return out[0], out[1], out[2]
    return sample


def plan_drill_tilted(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Drilling along a tilted program Z: rotaries positioned once, then the cycle in the tilted frame."""
    frame = tilted_frame(job, machine, kin)
    c = frame.cycle
    builder.spindle(job.spindle_rpm)
    x0, y0 = c.holes[0]
    approach = dict(zip(XYZ, frame.to_axes([x0, y0, c.r_z + RETURN_CLEARANCE])))
    # Lift first, turn the rotaries, then position over the first hole (rapids).
    lift = max(builder.position("z"), approach["z"])
    builder.rapid({"z": lift})
    builder.event(builder.end_time(), "rotaries", **frame.rotaries)
    builder.rapid(frame.rotaries)
    builder.rapid(approach)
    t0 = builder.end_time()
    # The cycle's timing search starts with the drives at rest: wait for the rapids'
    # feedback (rotaries included) to settle, and for the spindle.
    settle = settle_time(builder, kin, t0, 0.1 * c.xy_tolerance, c.servo_period)
    for j in (*XYZ, *frame.rotaries):
        builder.timelines[j].add_hold(t0, max(settle, builder.spindle_ready - t0))
    start = dict(zip(XYZ, frame.to_frame([builder.position(j) for j in XYZ])))
    scratch = PlanBuilder(frame.machine, start)
    t1 = builder.end_time(XYZ)
    for j in XYZ:
        scratch.timelines[j].add_hold(0.0, t1)
    _drill(scratch, c)
    end = scratch.end_time(XYZ)
    frame_timelines = [scratch.timelines[j] for j in XYZ]
    final = frame.to_axes([scratch.position(j) for j in XYZ])
    for i, j in enumerate(XYZ):
        builder.timelines[j].add(Piece(t1, end - t1, _mapped(frame_timelines, t1, frame.matrix[i], frame.origin[i])),
                                 float(final[i]))
    builder.events.extend(scratch.events)
    # Travel of everything in between (air arcs above R): sampled on the servo grid.
    ts = np.arange(t1, end, 1e-3)
    if len(ts):
        with shared_samples():
            for i, j in enumerate(XYZ):
                p = builder.timelines[j].sample(ts)[0]
                worst = int(np.argmax(np.maximum(machine.axes[j].min - p, p - machine.axes[j].max)))
                check_travel(machine, {j: float(p[worst])}, "drill")


def settle_time(builder: PlanBuilder, kin: Kinematics, t0: float, tol: float, period: float,
                 horizon: float = 2.0) -> float:
    """How long after ``t0`` (all axes commanded at rest) the drive model's feedback puts
    the tip within ``tol`` of the commanded tip, in whole servo periods."""
    joints = tuple(j for j in builder.machine.joint_names if j != SPINDLE)
    ts = np.arange(int(np.ceil((t0 + horizon) / period)) + 1) * period
    with shared_samples():
        p, v, a = (np.stack(q, axis=1) for q in zip(*[builder.timelines[j].sample(ts) for j in joints]))
    feedback, _ = DriveModel(builder.machine, period, joints).simulate(p, v, a)
    commanded, _ = kin.fk_many(dict(zip(joints, p.T)))
    actual, _ = kin.fk_many(dict(zip(joints, feedback.T)))
    far = np.nonzero((np.linalg.norm(actual - commanded, axis=1) > tol) & (ts >= t0))[0]
    return 0.0 if len(far) == 0 else float(ts[far[-1]] + period - t0)


def _drill(builder: PlanBuilder, cycle: DrillCycle) -> None:
    try:
        plan_drilling(builder, cycle)
    except JobError:
        raise  # names its field already
    except ValueError as err:  # one line: ruckig appends its whole input to its errors
        first = (str(err).splitlines() or [""])[0]
        name, sep, reason = first.partition(": ")
        if sep and re.fullmatch(r"(holes(\[\d+\])?|feed|mode)", name):  # a field of the drill block
            raise JobError(f"drill.{name}", reason) from err
        if sep and name.startswith("vibration"):
            raise JobError(name, reason) from err
        if sep and name == "length":  # a vibrated stroke too short to ramp onto the waveform
            raise JobError("drill.depth", reason) from err
        raise JobError("drill", first) from err


def plan_drill(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Overlapped (or conventional) drilling of a hole list, spindle at speed first."""
    if tilted(kin) and machine.layout != "mill3":
        return plan_drill_tilted(job, machine, builder, kin)
    cycle = drill_cycle(job, machine, kin, (builder.position("x"), builder.position("y")))
    builder.spindle(job.spindle_rpm)
    # Over the obstacles between the start and the first hole too: the first move's plane.
    tip = kin.to_program({j: builder.position(j) for j in machine.linear_axes})
    first = job.drill.holes[cycle.order[0]]
    plane = max([cycle.r_z] + [to_axes(kin, {"z": top}, "drill.obstacles")["z"]
                               for top in obstacle_tops(job, [[tip["x"], tip["y"]], first])])
    if plane > cycle.r_z:
        air = cycle.air_planes or (cycle.r_z,) * len(cycle.holes)
        cycle = replace(cycle, air_planes=(plane,) + tuple(air[1:]))
    check_travel(machine, {"z": plane + RETURN_CLEARANCE}, "drill.obstacles")
    lift = plane + RETURN_CLEARANCE
    if builder.position("z") < lift:
        builder.rapid({"z": lift})
    builder.timelines["z"].add_hold(builder.end_time(), max(0.0, builder.spindle_ready - builder.end_time()))
    _drill(builder, cycle)


def plan_turn(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Roughing with short air moves: passes start where the stock really is."""
    t = job.turn
    stock = [tuple(p) for p in t.stock]
    profile = [tuple(p) for p in t.profile]
    try:
        check_outlines(stock, profile)
        rough = plan_roughing(stock, profile, t.depth_of_cut, t.clearance, tuple(t.origin),
                              t.finish_allowance, t.finishing_pass, t.finish_allowance_z)
    except TurningError as err:
        field, _, reason = str(err).partition(": ")
        raise JobError(field, reason) from err
    def axes_of(z: float, r: float, field: str = "turn.profile") -> dict[str, float]:
        return to_axes(kin, {"x": r, "z": z}, field)
    origin = axes_of(*t.origin, "turn.origin")
    check_travel(machine, origin, "turn.origin")
    builder.spindle(job.spindle_rpm)
    builder.rapid(origin)
    vibration = vibration_of(job)
    passes = 0
    for move in rough.moves:
        target = axes_of(move.z, move.x)
        check_travel(machine, target, "turn.profile")
        start = builder.end_time()
        if move.kind == "rapid":
            builder.rapid(target)
            continue
        if move.cutting:
            builder.event(max(start, builder.spindle_ready), "pass", index=passes)
            passes += 1
        feed_move(builder, target, t.feed, vibration if move.cutting else None, "turn")


THREAD_PROBE = 0.01  # m: program radius and z steps at which the thread's axis map is probed
THREAD_AXIS_TOL = 1e-9  # m: the probed axis positions agree with a translation within this


def thread_origin(kin: Kinematics) -> tuple[float, float]:
    """Axis (x, z) of the tip on the spindle axis at the program's face z=0.

    The thread planner works in program radius and z and adds this, so the map from them
    to axis x and z must be that translation at every angle around the part: the program
    Z is the spindle axis (a setup turned about Z only turns the part on the spindle).
    """
    reason = "a thread's axis must be the spindle axis: turn the setup about Z only, its origin on that axis"
    quarters = [(float(np.cos(a)), float(np.sin(a))) for a in np.arange(4) * (np.pi / 2)]
    try:  # a tool axis tilted out of the plane normal to the spindle, or a lathe tip off y = 0
        probes = [(kin.to_axes({"x": r * c, "y": r * s, "z": z}, [c, s, 0.0]), r, z)
                  for c, s in quarters for r, z in ((0.0, 0.0), (THREAD_PROBE, 0.0), (0.0, THREAD_PROBE))]
    except JobError as err:
        raise JobError("setup", reason) from err
    x0, z0 = probes[0][0]["x"], probes[0][0]["z"]  # the face, at angle 0
    if any(abs(axes[j] - {"x": x0 + r, "z": z0 + z}.get(j, 0.0)) > THREAD_AXIS_TOL
           for axes, r, z in probes for j in axes):
        raise JobError("setup", reason)
    return x0, z0


def plan_thread_job(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Multi-pass thread on the lathe, with vibration along the infeed if given, placed on
    the axes by the setup and tool length."""
    origin = thread_origin(kin)
    try:
        spec = ThreadSpec.from_job(job, origin)
        check_thread(spec, machine)
    except ThreadError as err:
        field, _, reason = str(err).partition(": ")
        raise JobError(field, reason) from err
    plan_thread(builder, spec, checked=True)


PLANNERS: dict[str, Callable[[SimpleNamespace, Machine, PlanBuilder, Kinematics], None]] = {
    "move": plan_move,
    "drill": plan_drill,
    "turn": plan_turn,
    "thread": plan_thread_job,
    "path": plan_path,
}


def plan_job(job: SimpleNamespace, machine: Machine, start_position: dict[str, float] | None = None) -> Plan:
    """Plan a validated job from the machine's current position.

    Raises:
        JobError: the job cannot be done on this machine (field and reason named).
    """
    def plan(planned_on: Machine) -> Plan:
        builder = PlanBuilder(planned_on, start_position)
        builder.event(0.0, "job_start", kind=job.kind)
        return plan_into(job, planned_on, builder)

    plan = plan_within_limits(plan, machine, SERVO_PERIOD, job.kind)
    plan.events.append(Event(plan.duration, "job_end"))
    return plan


def plan_into(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, stop_spindle: bool = True) -> Plan:
    """Plan a validated job (or one segment of a long one) into ``builder`` and build it.

    Raises:
        JobError: the job cannot be done on this machine (field and reason named).
    """
    if job.machine != machine.name:
        raise JobError("machine", f"job is for '{job.machine}', this planner runs '{machine.name}'")
    planner = PLANNERS.get(job.kind)
    if planner is None:
        raise JobError("kind", f"'{job.kind}' jobs are not implemented by this planner yet")
    layouts = KIND_LAYOUTS.get(job.kind)
    if layouts is not None and machine.layout not in layouts:
        raise JobError("kind", f"a {machine.layout} machine cannot run '{job.kind}' jobs "
                               f"(layouts that can: {', '.join(layouts)})")
    if job.spindle_rpm > machine.axes[SPINDLE].max_velocity:
        raise JobError("spindle_rpm", f"exceeds the spindle's {to_rpm(machine.axes[SPINDLE].max_velocity):.0f} rpm")
    try:
        planner(job, machine, builder, Kinematics(machine, job.setup, job.tool))
        return builder.build(stop_spindle)
    except JobError:
        raise
    except Exception as err:  # noqa: BLE001 (MemoryError, RecursionError, KeyError, ruckig's ...)
        # A planner bug must not take the node down with it: the job is refused instead,
        # as the kind's block (INTERNAL marks it, so tests can tell it from a real check).
        first = (str(err).splitlines() or [""])[0][:120]
        raise JobError(job.kind, f"{INTERNAL} ({type(err).__name__}: {first})") from err
