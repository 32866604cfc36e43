"""From a validated job (SI units) to a Plan: the planner's one entry point.

The job's kind (cnc_planner.kinds) plans it into a PlanBuilder; every target is converted
from program to axis coordinates and checked against the soft limits before anything is
planned, so a job either plans whole or is rejected with the field that broke it. The plan
is then checked against the bridge's contract, inside lowered limits if it must
(motion.derating).
"""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_rpm

from cnc_planner import kinds
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.derating import plan_within_limits
from cnc_planner.motion.timeline import Event, Plan


INTERNAL = "cannot be planned: internal planner error"


def plan_job(job: SimpleNamespace, machine: Machine, start_position: dict[str, float] | None = None) -> Plan:
    """Plan a validated job from the machine's current position.

    Raises:
        JobError: the job cannot be done on this machine (field and reason named).
    """
    def plan(planned_on: Machine) -> Plan:
        builder = PlanBuilder(planned_on, start_position)
        builder.event(0.0, "job_start", kind=job.kind)
        return plan_into(job, planned_on, builder)

    plan = plan_within_limits(plan, machine, SERVO_PERIOD, job.kind)
    plan.events.append(Event(plan.duration, "job_end"))
    return plan


def plan_into(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, stop_spindle: bool = True) -> Plan:
    """Plan a validated job (or one segment of a long one) into ``builder`` and build it.

    Raises:
        JobError: the job cannot be done on this machine (field and reason named).
    """
    if job.machine != machine.name:
        raise JobError("machine", f"job is for '{job.machine}', this planner runs '{machine.name}'")
    kind = kinds.kind_of(job.kind)
    layouts = kind.layouts
    if layouts is not None and machine.layout not in layouts:
        raise JobError("kind", f"a {machine.layout} machine cannot run '{job.kind}' jobs "
                               f"(layouts that can: {', '.join(layouts)})")
    if job.spindle_rpm > machine.axes[SPINDLE].max_velocity:
        raise JobError("spindle_rpm", f"exceeds the spindle's {to_rpm(machine.axes[SPINDLE].max_velocity):.0f} rpm")
    try:
        kind.plan(job, machine, builder, Kinematics(machine, job.setup, job.tool))
        return builder.build(stop_spindle)
    except JobError:
        raise
    except Exception as err:  # noqa: BLE001 (MemoryError, RecursionError, KeyError, ruckig's ...)
        # A planner bug must not take the node down with it: the job is refused instead,
        # as the kind's block (INTERNAL marks it, so tests can tell it from a real check).
        first = (str(err).splitlines() or [""])[0][:120]
        raise JobError(job.kind, f"{INTERNAL} ({type(err).__name__}: {first})") from err
