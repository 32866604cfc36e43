"""A thread that leaves material, never overcuts, on every drive inside the tolerance.

The cycle's command is compensated with the described drives, so on them the feedback
reaches each pass's depth and no further. A real drive inside the description's tolerance
(cnc_msgs_py.machine.Tolerance) responds otherwise: a stiffer gain or a slower velocity
loop overshoots where the vibration turns at its deepest point and where x settles after
its plunge near the face, a few um past the thread's depth on the M12 example. So the plan
runs its compensated command through the described drives and every corner of their
tolerance (motion.compensation.tolerance_drives), finds how far below the thread's depth
any of them takes the tool on the thread, per pass, and raises each such pass by that
overcut plus an encoder count (spec.left_standing), re-planning until none is left
(PULL_ROUNDS at most). With vibration the pass raised is the last vibrating one: the
spring pass at full depth, which does not vibrate, still takes the thread to its depth on
the described drives. Each pass also joins its helix at least the slowest such drive's
settling time before the face (join_room), so that the join's transient on it (X settling
after its plunge, Z after its run-up to the lead) has mostly died out in the air rather
than on the flank. A closed tolerance trusts the description: nothing is checked, the join room is
JOIN_ROOM_REVS.

The tip's depth below the stock is linear in x and z apart (below a cone too),
and each axis's feedback depends on its own drive only, so the deepest point over every
pairing of an x corner with a z corner is the sum of the two axes' extremes: one simulation
per corner covers all pairings.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.units import to_mm
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.thread.cycle import JOIN_ROOM_REVS, ThreadCycle
from cnc_planner.kinds.thread.spec import JOINTS, TWO_PI, ThreadError, ThreadSpec
from cnc_planner.motion.compensation import tolerance_drives

PULL_ROUNDS = 3  # re-plans at most; the first leaves every pass within a count
ROUNDING_COUNTS = 1.5  # encoder counts: a reading one count past the depth is its rounding
SETTLE_TIMES = 1.0  # settling times of the slowest drive inside the tolerance between a join and the face
SETTLE_S = 0.05  # s past a pass's exit that its feedback, lagging, may still be on the thread


def join_room(spec: ThreadSpec, machine: Machine) -> float:
    """Revolutions of helix between joining it and the face: JOIN_ROOM_REVS where the
    tolerance is closed (the compensation is exact there), else at least SETTLE_TIMES the
    settling time of the slowest drive inside the tolerance (1/kp + velocity_lag + delay at
    its corner), so that what the join leaves on a drive unlike the description (X
    overshooting its plunge, Z its run-up to the lead) dies out in the air."""
    drives = [d for j in JOINTS for d in tolerance_drives(machine, j)]
    if len(drives) == len(JOINTS):
        return JOIN_ROOM_REVS
    settle = max(1.0 / d.kp + d.velocity_lag + d.delay for d in drives)
    return max(JOIN_ROOM_REVS, SETTLE_TIMES * settle * spec.spindle_speed / TWO_PI)


def overcuts(cycle: ThreadCycle) -> dict[int, float]:
    """Per pass index: the most any drive inside the tolerance (x and z each at any corner)
    takes the tool below the thread's depth on the thread, between the face and end_z as
    the analyser judges it (groove coordinate g = z - depth * tan(infeed) along the feed),
    on the cycle's compensated command (m; passes that stay above it are left out)."""
    spec, machine = cycle.spec, cycle.machine
    command = cycle.command
    xs, zs = tolerance_drives(machine, "x"), tolerance_drives(machine, "z")
    n = max(len(xs), len(zs))
    feedback = np.stack([DriveModel(machine, cycle.period, JOINTS, drives={"x": xs[i % len(xs)], "z": zs[i % len(zs)]})
                         .simulate(*command)[0] for i in range(n)])  # (drives, instants, x z)
    x, z = feedback[:, :, 0] - spec.origin[0], feedback[:, :, 1] - spec.origin[1]
    s, tan, half = spec.direction, math.tan(spec.infeed_angle), spec.taper / 2
    # depth below the surface at the groove coordinate g under the tool (the helix's and the
    # analyser's), solved for depth: (radial * x - half * z) / (1 - s * tan * half)
    scale = 1.0 - s * tan * half
    radial_x, axial_z = spec.radial * (x - spec.major_radius) / scale, -half * z / scale
    deepest = radial_x.max(axis=0) + axial_z.max(axis=0)
    shallowest = radial_x.min(axis=0) + axial_z.min(axis=0)
    # on the thread for some pairing: s * g spans [min s*z - deepest*tan, max s*z - shallowest*tan]
    on_thread = ((s * z).max(axis=0) - shallowest * tan >= 0.0) & ((s * z).min(axis=0) - deepest * tan
                                                                     <= s * spec.end_z)
    over = np.where(on_thread, deepest - spec.depth, -np.inf)
    found: dict[int, float] = {}
    for c in cycle.cuts:
        lo, hi = round(c.t_join / cycle.period), round((c.t_out + SETTLE_S) / cycle.period) + 1
        worst = float(np.max(over[lo:hi], initial=-np.inf))
        if worst > 0.0:
            found[c.cut.index] = max(worst, found.get(c.cut.index, 0.0))
    return found


def leave_material(cycle: ThreadCycle, replan: Callable[[dict[int, float]], ThreadCycle]) -> ThreadCycle:
    """The cycle, re-planned (``replan``: pulls by pass -> cycle) with its passes raised until
    no drive inside the tolerance cuts deeper than the thread by more than an encoder count's rounding;
    the cycle itself where the tolerance is closed.

    Raises:
        ThreadError: PULL_ROUNDS re-plans still overcut (a drive far from its description).
    """
    machine = cycle.machine
    if all(len(tolerance_drives(machine, j)) == 1 for j in JOINTS):
        return cycle
    count = float(machine.drives["x"].resolution)
    rounding = ROUNDING_COUNTS * count
    pulls: dict[int, float] = {}
    rounds = 0
    while over := {k: v for k, v in overcuts(cycle).items() if v > rounding}:
        if rounds == PULL_ROUNDS:
            raise ThreadError("thread.depth", f"a drive inside the tolerance still cuts "
                              f"{to_mm(max(over.values())) * 1e3:.1f} um deeper than the thread after "
                              f"{PULL_ROUNDS} re-plans that leave material: narrow drive.<axis>.tolerance "
                              "or identify the drives (cnc-identify)")
        for k, v in over.items():
            pulls[k] = pulls.get(k, 0.0) + v + count
        cycle = replan(pulls)
        rounds += 1
    return cycle
