"""The ``move`` job: a program of rapid, linear (optionally vibrated) and dwell moves in
absolute program coordinates."""
from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.surface_speed import css_feeds, radius_of, ramp_to_radius, surface_speed_of
from cnc_planner.travel import check_travel, program_axes, to_axes
from cnc_planner.vibration.feed import TWO_PI, feed_move, vibration_of


def move_targets(job: SimpleNamespace, machine: Machine, kin: Kinematics,
                 start: dict[str, float], block: str = "move") -> list[dict[str, float] | None]:
    """Every move's axis target (None for a dwell), from the machine at ``start``, checked
    against the travel: a program is checked whole before any of it is planned. ``block``:
    the job's list of moves (a sync job's holds synchronised moves too)."""
    tip = kin.to_program({j: start.get(j, 0.0) for j in machine.linear_axes})
    targets: list[dict[str, float] | None] = []
    for i, move in enumerate(getattr(job, block)):
        if move.dwell is not None:
            targets.append(None)
            continue
        kind = next(k for k in ("rapid", "linear", "sync", "tap") if getattr(move, k, None) is not None)
        target = getattr(move, kind)
        field = f"{block}[{i}].{kind}"
        before = dict(tip)
        for key in program_axes(machine, target, field):
            tip[key] = getattr(target, key)
        axes = to_axes(kin, tip, field)
        check_travel(machine, axes, field)
        targets.append(axes)
        if kind == "tap":  # a tap returns to where it started: its target is its bottom
            tip = before
    return targets


def plan_move(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics,
              block: str = "move", sync: Callable[[PlanBuilder, int, list], bool] | None = None) -> None:
    """A list of rapid, linear and dwell moves in absolute program coordinates; ``block``: the
    job's list of moves, the synchronised ones of which (a sync job's) ``sync`` plans, given
    the builder, the move's index and every move's axis target (True: that move is its own).

    At a surface speed (G96) the spindle starts at the speed for where the tool stands; from
    each rapid's start it ramps to the speed for the rapid's end point, as Fanuc's G96
    computes a rapid's rpm, and a linear move that changes radius is fed in pieces at the
    speeds along it (cnc_planner.motion.surface_speed). A feed per revolution is per
    revolution of the speed the spindle has."""
    here = {j: builder.position(j) for j in machine.linear_axes}
    targets = move_targets(job, machine, kin, here, block)
    vibration = vibration_of(job)
    css = surface_speed_of(job, machine)
    if job.spindle_rpm > 0:
        builder.spindle(job.spindle_rpm)
    elif css is not None:
        ramp_to_radius(builder, css, radius_of(kin, {}, here))
    for i, (move, axes) in enumerate(zip(getattr(job, block), targets)):
        start = builder.end_time()
        if sync is not None and sync(builder, i, targets):
            continue
        if axes is None:
            for joint in machine.linear_axes:
                builder.timelines[joint].add_hold(start, move.dwell)
            builder.event(start, "dwell", move=i)
            continue
        kind = "rapid" if move.rapid is not None else "linear"
        start = builder.free_from(builder.moving(axes) if kind == "rapid" else list(axes))  # as the move starts
        builder.event(start if kind == "rapid" else max(start, builder.spindle_ready), kind, move=i)
        if kind == "rapid":
            if css is not None:
                ramp_to_radius(builder, css, radius_of(kin, axes, {j: builder.position(j) for j in machine.linear_axes}))
            builder.rapid(axes)
        elif css is not None:
            here = {j: builder.position(j) for j in machine.linear_axes}
            for piece in css_feeds(builder, css, {j: here[j] for j in axes}, axes, radius_of(kin, {}, here),
                                   radius_of(kin, axes, here)):
                builder.linear(piece, _feed(move, builder))
        elif vibration is None:
            builder.linear(axes, _feed(move, builder))
        else:
            per_rev = move.feed / (job.spindle_rpm / TWO_PI) if move.feed_per_rev is None else move.feed_per_rev
            feed_move(builder, axes, per_rev, vibration, f"{block}[{i}]")


def _feed(move: SimpleNamespace, builder: PlanBuilder) -> float:
    """A linear move's feed (m/s): per minute as given, or per revolution of the spindle's speed now."""
    if move.feed_per_rev is None:
        return move.feed
    return move.feed_per_rev * abs(builder.timelines[SPINDLE].end_velocity) / TWO_PI
