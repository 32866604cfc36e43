"""Planning a turn job: roughing with short air moves, placed on the axes by the setup and
tool, each cutting pass a feed per revolution (vibrated if the job asks)."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.turn.moves import TurnMove
from cnc_planner.kinds.turn.roughing import plan_of
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.surface_speed import css_feeds, ramp_to_radius, surface_speed_of
from cnc_planner.travel import check_travel, to_axes
from cnc_planner.vibration.feed import feed_move, vibration_of


def plan_turn(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Roughing with short air moves: passes start where the stock really is.

    At a surface speed (``surface_speed``, G96) the spindle follows the radius as
    cnc_planner.motion.surface_speed says: ramped during the air moves to the speed the next
    cut starts at, stepped along a cut that changes radius; the feed per revolution holds at
    the spindle's actual speed throughout.

    Bad outlines or cycle parameters raise TurningError, a JobError that names the turn field.
    """
    t = job.turn
    plan = plan_of(t)
    moves = plan.job_moves()  # in the job's (z, x), whichever way the passes run

    def axes_of(z: float, r: float, field: str = "turn.profile") -> dict[str, float]:
        return to_axes(kin, {"x": r, "z": z}, field)
    origin = axes_of(*t.origin, "turn.origin")
    check_travel(machine, origin, "turn.origin")
    css = surface_speed_of(job, machine)
    starts = [tuple(t.origin)] + [m.end for m in moves[:-1]]  # (z, x) each move starts at
    cut_radius = _next_cut_radii(moves, starts)
    if css is None:
        builder.spindle(job.spindle_rpm)
    elif moves:
        ramp_to_radius(builder, css, cut_radius[0])
    builder.rapid(origin)
    vibration = vibration_of(job)
    passes = 0
    for i, move in enumerate(moves):
        target = axes_of(move.z, move.x)
        check_travel(machine, target, "turn.profile")
        start = builder.free_from(builder.moving(target) if move.kind == "rapid" else list(target))  # as it starts
        if move.kind == "rapid":
            if css is not None and i > 0 and moves[i - 1].kind == "feed":
                ramp_to_radius(builder, css, cut_radius[i])
            builder.rapid(target)
            continue
        if move.cutting:
            builder.event(max(start, builder.spindle_ready), "pass", index=passes)
            passes += 1
        if css is None:
            feed_move(builder, target, t.feed, vibration if move.cutting else None, "turn")
            continue
        at = {j: builder.position(j) for j in target}
        for piece in css_feeds(builder, css, at, target, abs(starts[i][1]), abs(move.x)):
            feed_move(builder, piece, t.feed, None, "turn")


def _next_cut_radii(moves: list[TurnMove], starts: list[tuple[float, float]]) -> list[float]:
    """Per move, the radius the next feed from it on starts at (the last feed's end after it);
    a radius is the distance from the spindle axis, x's on either side of it."""
    out: list[float] = []
    radius = abs(starts[-1][1]) if starts else 0.0
    for move, at in zip(reversed(moves), reversed(starts)):
        if move.kind == "feed":
            radius = abs(at[1])
        out.append(radius)
    return out[::-1]
