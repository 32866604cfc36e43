"""Drilling in a tilted setup on a 5-axis machine: rotaries positioned once, then the
overlapped cycle planned in the tilted frame (program u, v, w) and mapped onto X/Y/Z."""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Axis, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_deg, to_mm_per_min

from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE, DrillCycle
from cnc_planner.kinds.drill.drilling import plan_cycle
from cnc_planner.kinds.drill.peck import peck_of, xy_plane
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import shared_samples
from cnc_planner.motion.settle import settle_time
from cnc_planner.motion.timeline import Piece
from cnc_planner.travel import check_travel


XYZ = ("x", "y", "z")


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
    r_z = xy_plane(d, planes)
    frame = TiltedFrame(rotaries, origin, matrix,
                        DrillCycle(holes=[tuple(h) for h in d.holes], surface_z=max(p[0] for p in planes),
                                   bottom_z=min(p[2] for p in planes), r_z=r_z, feed=d.feed,
                                   overlap=d.overlap != "off", mode=None if d.mode == "auto" else d.mode,
                                   gentle_air_accel=d.gentle_air_accel, dwell=d.dwell,
                                   hole_planes=None if len(set(planes)) == 1 and planes[0][1] == r_z else planes,
                                   peck=peck_of(d)),
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
    plan_cycle(scratch, c)
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
