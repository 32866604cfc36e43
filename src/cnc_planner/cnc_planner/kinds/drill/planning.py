"""Planning a drill job: the spindle to speed, up over the clamps, then the overlapped
(or conventional) cycle over the holes; a tilted setup on a 5-axis machine in its frame."""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.drill.block import drill_cycle, obstacle_tops
from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE
from cnc_planner.kinds.drill.drilling import plan_cycle
from cnc_planner.kinds.drill.tilted import plan_drill_tilted, tilted
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.travel import check_travel, to_axes


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
    plan_cycle(builder, cycle)
