"""Planning a turn job: roughing with short air moves, placed on the axes by the setup and
tool, each cutting pass a feed per revolution (vibrated if the job asks)."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.turn.roughing import plan_roughing
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.travel import check_travel, to_axes
from cnc_planner.vibration.feed import feed_move, vibration_of


def plan_turn(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Roughing with short air moves: passes start where the stock really is.

    Bad outlines or cycle parameters raise TurningError, a JobError that names the turn field.
    """
    t = job.turn
    stock = [tuple(p) for p in t.stock]
    profile = [tuple(p) for p in t.profile]
    rough = plan_roughing(stock, profile, t.depth_of_cut, t.clearance, tuple(t.origin),
                          t.finish_allowance, t.finishing_pass, t.finish_allowance_z)
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
        start = builder.free_from(builder.moving(target) if move.kind == "rapid" else list(target))  # as it starts
        if move.kind == "rapid":
            builder.rapid(target)
            continue
        if move.cutting:
            builder.event(max(start, builder.spindle_ready), "pass", index=passes)
            passes += 1
        feed_move(builder, target, t.feed, vibration if move.cutting else None, "turn")
