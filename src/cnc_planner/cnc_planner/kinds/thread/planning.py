"""Planning a thread job: the checked thread cycle placed on the axes after the spindle
and the rapid to its start, its axis the spindle's, whatever the setup and tool length."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.thread.checks import check_thread
from cnc_planner.kinds.thread.cycle import JOIN_ROOM_REVS, ThreadCycle
from cnc_planner.kinds.thread.ends import fit_end_taper
from cnc_planner.kinds.thread.spec import JOINTS, TWO_PI, ThreadSpec
from cnc_planner.kinds.thread.tolerance import join_room, leave_material
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.timeline import Piece


SETTLE_TIME = 0.05  # s at rest before the cycle: the drives settle after the rapid to its start
SPINDLE_SETTLE = 0.05  # s after the spindle reaches speed: its following error has died out
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
    probes = [(c, s, r, z) for c, s in quarters for r, z in ((0.0, 0.0), (THREAD_PROBE, 0.0), (0.0, THREAD_PROBE))]
    try:  # a tool axis tilted out of the plane normal to the spindle, or a lathe tip off y = 0
        axes = kin.ik_many(np.array([(r * c, r * s, z) for c, s, r, z in probes]),
                           np.array([(c, s, 0.0) for c, s, _, _ in probes]), check=False)
    except JobError as err:
        raise JobError("setup", reason) from err
    x0, z0 = float(axes["x"][0]), float(axes["z"][0])  # the face, at angle 0
    for i, (_, _, r, z) in enumerate(probes):
        expected = {"x": x0 + r, "z": z0 + z}
        if any(abs(float(axes[j][i]) - expected.get(j, 0.0)) > THREAD_AXIS_TOL for j in axes if j != SPINDLE):
            raise JobError("setup", reason)
    return x0, z0


def plan_thread_job(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Multi-pass thread on the lathe, with vibration along the infeed if given, placed on
    the axes by the setup and tool length."""
    origin = thread_origin(kin)
    plan_thread(builder, ThreadSpec.from_job(job, origin))


def plan_thread(builder: PlanBuilder, spec: ThreadSpec, servo_period: float = 1e-3,
                compensate: bool = True) -> list[dict]:
    """Append the whole thread cycle to the builder; returns one JSON-ready dict per pass.

    Spindle to speed; every pass and start as one ThreadCycle (drive-compensated unless
    `compensate` is False), from where the tool stands if that is in front of the face and
    outside the clearance radius (the first pass runs straight onto its helix), else from
    the cycle start (clearance radius, start_z; a rapid from wherever the tool is, clear of
    the stock); it ends at the cycle start. Events: "thread_pass"
    as each pass's air path begins, "sync" where it is on its helix.

    Tapered ends get their ramps' corners fitted to the x axis (ends.fit_end_taper).

    Raises:
        ThreadError: check_thread's and fit_end_taper's rejections (before anything is added),
            or a pass whose helix cannot be reached before the face (the builder is then
            half-built: discard it).
    """
    machine = builder.machine
    spec = fit_end_taper(spec, machine)
    check_thread(spec, machine)
    x_origin, z_origin = spec.origin
    drive = DriveModel(machine, servo_period, joints=JOINTS) if compensate else None
    spindle = builder.timelines[SPINDLE]
    builder.spindle(spec.spindle_speed)
    start = (builder.position("x"), builder.position("z"))
    x_clear = x_origin + spec.clear_radius
    if spec.direction * (start[1] - z_origin) >= 0.0 or spec.radial * (start[0] - x_clear) > 0.0:
        # not in the air in front of the face and outside the clearance radius: the cycle
        # starts at the clearance radius and start_z
        builder.rapid({"x": x_clear, "z": z_origin + spec.start_z})
        start = None
    # the cycle begins once the axes have settled, at rest (in front of the face); its
    # first pass joins the helix no sooner than SPINDLE_SETTLE after the spindle's ramp,
    # and leaves for it at the last instant it can
    t0 = math.ceil((builder.end_time(list(JOINTS)) + SETTLE_TIME) / servo_period - 1e-9) * servo_period
    t_speed = max(t0, builder.spindle_ready)  # the spindle's angle, as if it turned at speed since t0
    theta0 = spindle.position_at(t_speed) - spec.spindle_speed * (t_speed - t0)

    # compensated for the description, and joining and leaving material for every drive inside its tolerance
    room = JOIN_ROOM_REVS if drive is None else join_room(spec, machine)

    def planned(pulls: dict[int, float]) -> ThreadCycle:
        return ThreadCycle(spec, machine, servo_period, theta0, drive,
                           settled=builder.spindle_ready + SPINDLE_SETTLE - t0, start=start, pulls=pulls, room=room)

    cycle = planned({}) if drive is None else leave_material(planned({}), planned)
    for j, joint in enumerate(JOINTS):
        builder.timelines[joint].add(Piece(t0, cycle.duration, cycle.sampler(j)), cycle.end[j])
    report = []
    for c in cycle.cuts:
        cut = c.cut
        info = {
            "index": cut.index, "start": c.start, "spring": cut.spring,
            "depth_mm": to_mm(cut.depth), "doc_mm": to_mm(cut.doc),
            "amplitude_mm": to_mm(cut.amplitude),
            "vibration_per_rev": cut.per_rev or None,
            "vibration_phase_deg": cut.phase * 360.0 if cut.amplitude else None,
            "spindle_phase_deg": math.degrees(TWO_PI * c.start / spec.starts),
            "t_start": t0 + c.t_begin, "t_sync": t0 + c.t_join, "t_end": t0 + c.t_end,
        }
        builder.event(info["t_start"], "thread_pass", **{k: info[k] for k in (
            "index", "start", "spring", "depth_mm", "doc_mm", "amplitude_mm",
            "vibration_per_rev", "vibration_phase_deg")})
        builder.event(info["t_sync"], "sync", index=cut.index, start=c.start,
                      spindle_phase_deg=info["spindle_phase_deg"])
        report.append(info)
    builder.rapid({"z": z_origin + spec.start_z})
    return report
