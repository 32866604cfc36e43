"""Programs: a G-code program's operations (cnc_msgs_py.gcode), each planned by its own kind
into one builder, so that the program is one goal: one job id, one status stream counting
operations, one recording and one report with a section per operation."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.gcode.translate import Hold
from cnc_msgs_py.kinds.program import operations_from
from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm, to_rpm

from cnc_planner.kinematics import Kinematics
from cnc_planner.kinds.kind import JobKind, ProgressCount, ReportSection
from cnc_planner.motion.builder import PlanBuilder

OPERATION = "operation"  # the job_events mark at each operation's start
HOLD = "hold"  # the job_events mark at a hold point (M0/M1): line, code, hold (its index), before (the next operation)


def kinds() -> dict:
    """The registry (which holds this kind itself): looked up when planning and judging."""
    from cnc_planner.kinds import KINDS
    return KINDS


def operations_at(job: SimpleNamespace, machine: Machine, joints: dict[str, float]) -> list:
    """The program's operations when it begins with the machine's joints at ``joints``: a
    program that reads where the tool stands before it says so is translated from there (the
    tool tip in program coordinates with no tool length applied, as at LinuxCNC's G49)."""
    if not job.program.start_from_machine:
        return job.program.operations
    tip = Kinematics(machine, job.setup, None).to_program({j: v for j, v in joints.items() if j != SPINDLE})
    return operations_from(job, {axis: to_mm(v) for axis, v in tip.items()})


def plan_program(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Each operation through its kind's plan, one after the other; an operation's error
    names the program line it starts at."""
    registry = kinds()
    start = {j: builder.position(j) for j in machine.joint_names}
    operations = operations_at(job, machine, start)
    holds = list(enumerate(getattr(operations, "holds", ())))
    for index, (line, op, _) in enumerate(operations):
        kind = registry[op.kind]
        try:
            if kind.layouts is not None and machine.layout not in kind.layouts:
                raise JobError("kind", f"a {machine.layout} machine cannot run '{op.kind}' operations")
            if op.spindle_rpm > machine.axes[SPINDLE].max_velocity:
                raise JobError("spindle_rpm", f"exceeds the spindle's {to_rpm(machine.axes[SPINDLE].max_velocity):.0f} rpm")
            op_kin = Kinematics(machine, op.setup, op.tool)
            if index > 0 and kind.settle_before is not None:  # (a hold there begins settled too)
                kind.settle_before(op, machine, builder, op_kin)
            for k, hold in holds:
                if hold.before == index:
                    mark_hold(builder, hold, k)
            if index > 0 and op.surface_speed is None:  # (at a surface speed the operation sets it)
                builder.spindle_after(op.spindle_rpm)  # where the previous operation ended
            builder.event(builder.end_time(), OPERATION, index=index, kind=op.kind, line=line)
            kind.plan(op, machine, builder, op_kin)
        except JobError as err:
            raise JobError(f"line {line}", f"{op.kind}: {err}") from err
    for k, hold in holds:
        if hold.before == len(operations):
            mark_hold(builder, hold, k)


def mark_hold(builder: PlanBuilder, hold: Hold, index: int) -> None:
    """Mark hold point ``index`` (M0/M1, a zero-length hold in the plan) where every joint has
    settled and the spindle's last change is done; the axes stand until then, so the next
    operation starts after it. Over topics the executive holds there (cnc_planner.holding)."""
    for timeline in builder.timelines.values():
        timeline.flush()
    at = max(timeline.end_time for timeline in builder.timelines.values())
    for joint, timeline in builder.timelines.items():
        if joint != SPINDLE and timeline.end_time < at:
            timeline.add_hold(timeline.end_time, at - timeline.end_time)
    builder.event(at, HOLD, line=hold.line, code=hold.code, hold=index, before=hold.before)


KIND = JobKind(
    name="program",
    plan=plan_program,
    report=ReportSection("program", f"{__name__}.report:program_section"),
    progress=ProgressCount(OPERATION, "operation", total=lambda job: len(job.program.operations)),
)
