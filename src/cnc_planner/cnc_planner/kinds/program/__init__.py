"""Programs: a G-code program's operations (cnc_msgs_py.gcode), each planned by its own kind
into one builder, so that the program is one goal: one job id, one status stream counting
operations, one recording and one report with a section per operation."""
from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_rpm

from cnc_analysis.recording import Run

from cnc_planner.kinematics import Kinematics
from cnc_planner.kinds.kind import JobKind, ProgressCount, ReportSection
from cnc_planner.motion.builder import PlanBuilder

OPERATION = "operation"  # the job_events mark at each operation's start


def _kinds() -> dict:
    from cnc_planner.kinds import KINDS  # the registry holds this kind: looked up when planning
    return KINDS


def _spindle_to(builder: PlanBuilder, speed: float) -> None:
    """Change the spindle's speed (S, M5) where the previous operation ended. A kind ramps
    its spindle from the end of the spindle's last change, which in a fresh plan is the
    start; here that lies inside the previous operation, which must run at its own speed."""
    spindle = builder.timelines[SPINDLE]
    if abs(spindle.end_velocity - speed) > 1e-12:
        builder.spindle(speed, start=max(builder.end_time(), spindle.end_time))


def plan_program(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Each operation through its kind's plan, one after the other; an operation's error
    names the program line it starts at."""
    kinds = _kinds()
    for index, (line, op, _) in enumerate(job.program.operations):
        kind = kinds[op.kind]
        try:
            if kind.layouts is not None and machine.layout not in kind.layouts:
                raise JobError("kind", f"a {machine.layout} machine cannot run '{op.kind}' operations")
            if op.spindle_rpm > machine.axes[SPINDLE].max_velocity:
                raise JobError("spindle_rpm", f"exceeds the spindle's {to_rpm(machine.axes[SPINDLE].max_velocity):.0f} rpm")
            if index > 0:
                _spindle_to(builder, op.spindle_rpm)
            builder.event(builder.end_time(), OPERATION, index=index, kind=op.kind, line=line)
            kind.plan(op, machine, builder, Kinematics(machine, op.setup, op.tool))
        except JobError as err:
            raise JobError(f"line {line}", f"{op.kind}: {err}") from err


def _operation_run(run: Run, part: np.ndarray, t0: float, t1: float, doc: dict) -> Run:
    """The recording as one operation's judge must see it: only the operation's share of the
    feedback and commands (a judge may look past its window, where the next operation cuts),
    and the operation's own goal (a judge may read the goal as sent, in mm)."""
    sent = (run.command_t >= t0 - 1e-9) & (run.command_t < t1 - 1e-9)
    return replace(run, feedback_t=run.feedback_t[part], feedback=run.feedback[part],
                   feedback_velocity=run.feedback_velocity[part], command_t=run.command_t[sent],
                   command=run.command[sent], command_velocity=run.command_velocity[sent],
                   goals=[json.dumps(doc)])


def program_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """One section per operation, judged by its kind's own judge on its share of the feedback."""
    kinds = _kinds()
    t = run.feedback_t
    begin = t[window][0] if window.any() else 0.0
    starts = sorted(e["stamp_ns"] / 1e9 for e in run.events
                    if e.get("name") == OPERATION and "stamp_ns" in e and e["stamp_ns"] / 1e9 >= begin - 1e-9)
    sections = []
    for index, (line, op, doc) in enumerate(job.program.operations):
        entry = {"index": index, "line": line, "kind": op.kind}
        if index < len(starts):
            t1 = starts[index + 1] if index + 1 < len(starts) else np.inf
            part = window & (t >= starts[index] - 1e-9) & (t < t1 - 1e-9)
            entry["duration_s"] = float(t[part][-1] - t[part][0]) if part.any() else 0.0
            section = kinds[op.kind].report
            if section is not None and part.any():
                own = _operation_run(run, part, starts[index], t1, doc)
                entry[section.key] = section.judge(own, op, machine, np.ones(len(own.feedback_t), dtype=bool))
        sections.append(entry)
    return {"operations": sections}


KIND = JobKind(
    name="program",
    plan=plan_program,
    report=ReportSection("program", program_section),
    progress=ProgressCount(OPERATION, "operation", total=lambda job: len(job.program.operations)),
)
