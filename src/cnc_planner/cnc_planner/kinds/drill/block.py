"""A job's drill block as the cycle the planner drills: holes and planes in axis
coordinates, checked against the travel, in drilling order, with obstacles and vibration."""
from __future__ import annotations

import functools
from types import SimpleNamespace

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm, to_mm_per_min

from cnc_planner.kinds.drill.clamps import OBSTACLE_MARGIN, crossed, under_tool
from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE, DrillCycle
from cnc_planner.kinds.drill.hole_order import shortest_order
from cnc_planner.kinds.drill.peck import peck_of, xy_plane
from cnc_planner.kinds.drill.tilted import tilted, tilted_frame
from cnc_planner.kinematics import Kinematics
from cnc_planner.travel import check_travel, to_axes
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.vibration.feed import TWO_PI, resolved, vibration_error, vibration_of
from cnc_planner.vibration.waveform import VibrationError, check_vibration


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
    # Z is not rotated on a mill; a plate's holes share a few surfaces: each converted once.
    z_of = functools.cache(lambda z: to_axes(kin, {"z": z}, "drill.surface_z")["z"])
    for i, ((x, y), (surface, depth)) in enumerate(zip(d.holes, d.hole_planes)):
        bottom = to_axes(kin, {"x": x, "y": y, "z": surface - depth}, f"drill.holes[{i}]")
        check_travel(machine, bottom, f"drill.holes[{i}]")
        holes.append((bottom["x"], bottom["y"]))
        planes.append((z_of(surface), z_of(surface + d.r_gap), bottom["z"]))
    order = list(range(len(holes)))
    if d.order == "shortest":
        order = shortest_order(holes, holes[0] if start_xy is None else start_xy)
    r_z = xy_plane(d, planes)
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
                      peck=peck_of(d), order=tuple(order), air_planes=tuple(air) if max(air) > r_z else None,
                      **drill_vibration(job, machine))


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
    like a move's: no air-cut or an axis that cannot follow is refused naming what works
    (vibration.feed.vibration_error). ``vibration: auto`` is chosen here for the Z axis,
    its drive and the job's feed and speed (vibration.auto)."""
    vibration = vibration_of(job)
    if vibration is None:
        return {}
    z = machine.axes["z"]
    feed_per_rev = job.drill.feed / (job.spindle_rpm / TWO_PI)
    vibration, chosen = resolved(vibration, feed_per_rev, job.spindle_rpm, z,
                                 lambda: DriveModel(machine, SERVO_PERIOD, ("z",)), SERVO_PERIOD, rests=False)
    try:
        check_vibration(vibration, feed_per_rev, job.spindle_rpm, z)
    except VibrationError as err:
        raise vibration_error(err, vibration, feed_per_rev, job.spindle_rpm, z) from err
    return {"vibration": vibration, "spindle_speed": job.spindle_rpm, "vibration_choice": chosen}
