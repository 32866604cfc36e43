"""From a validated job (SI units) to a Plan: the planner's one entry point.

Every target is converted from program to axis coordinates and checked against the
soft limits before anything is planned, so a job either plans whole or is rejected
with the field that broke it.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Callable

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_rpm

from .builder import PlanBuilder
from .kinematics import Kinematics
from .timeline import Plan


def check_travel(machine: Machine, axes: dict[str, float], field: str) -> None:
    """Raise JobError if an axis position lies outside the machine's soft limits."""
    for name, position in axes.items():
        axis = machine.axes[name]
        if not axis.within_travel(position):
            raise JobError(
                field,
                f"puts axis {name} at {position * 1e3:.3f} mm, outside its travel "
                f"[{axis.min * 1e3:g}, {axis.max * 1e3:g}] mm",
            )


def _program_axes(machine: Machine, target: SimpleNamespace, field: str) -> list[str]:
    given = [k for k, v in vars(target).items() if v is not None]
    for key in given:
        if key not in machine.linear_axes:
            raise JobError(f"{field}.{key}", f"machine '{machine.name}' has no {key} axis")
    return given


def plan_move(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """A list of rapid, linear and dwell moves in absolute program coordinates."""
    tip = kin.to_program({j: builder.position(j) for j in machine.linear_axes})
    if job.spindle_rpm > 0:
        builder.spindle(job.spindle_rpm)
    for i, move in enumerate(job.move):
        start = builder.end_time()
        if move.dwell is not None:
            for joint in machine.linear_axes:
                builder.timelines[joint].add_hold(start, move.dwell)
            builder.event(start, "dwell", move=i)
            continue
        kind = "rapid" if move.rapid is not None else "linear"
        target = getattr(move, kind)
        field = f"move[{i}].{kind}"
        for key in _program_axes(machine, target, field):
            tip[key] = getattr(target, key)
        axes = kin.to_axes(tip)
        check_travel(machine, axes, field)
        builder.event(start if kind == "rapid" else max(start, builder.spindle_ready), kind, move=i)
        if kind == "rapid":
            builder.rapid(axes)
        else:
            builder.linear(axes, move.feed)


PLANNERS: dict[str, Callable[[SimpleNamespace, Machine, PlanBuilder, Kinematics], None]] = {
    "move": plan_move,
}


def plan_job(job: SimpleNamespace, machine: Machine, start_position: dict[str, float] | None = None) -> Plan:
    """Plan a validated job from the machine's current position.

    Raises:
        JobError: the job cannot be done on this machine (field and reason named).
    """
    if job.machine != machine.name:
        raise JobError("machine", f"job is for '{job.machine}', this planner runs '{machine.name}'")
    planner = PLANNERS.get(job.kind)
    if planner is None:
        raise JobError("kind", f"'{job.kind}' jobs are not implemented by this planner yet")
    if job.spindle_rpm > machine.axes[SPINDLE].max_velocity:
        raise JobError("spindle_rpm", f"exceeds the spindle's {to_rpm(machine.axes[SPINDLE].max_velocity):.0f} rpm")
    builder = PlanBuilder(machine, start_position)
    planner(job, machine, builder, Kinematics(machine, job.setup, job.tool))
    return builder.build()
