"""Drilling: hole lists with overlapped positioning, approach and retract (method 1), pecks,
dwells, clamps and chip-breaking vibration on the drill feed; mills and 5-axis machines.
A job of more than SEGMENT_HOLES holes is planned in segments."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import SPINDLE

from .block import drill_cycle
from .cycle import DrillCycle
from .planning import plan_drill
from cnc_planner.kinds.kind import Figures, JobKind, ProgressCount, ReportSection, Segmenting
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.settle import settle_time


SEGMENT_HOLES = 50  # holes per segment: ~3 s of planning before a goal is accepted
SETTLE_SHARE = 0.1  # of the X/Y tolerance: a drill segment ends once the feedback is this close


def _part(job: SimpleNamespace, lo: int, hi: int) -> SimpleNamespace:
    """The job with only its holes lo..hi-1."""
    d = job.drill
    return SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{
        **vars(d), "holes": d.holes[lo:hi], "hole_planes": d.hole_planes[lo:hi]})})


def _check_whole(job: SimpleNamespace, machine, kin: Kinematics, start: dict[str, float]) -> DrillCycle:
    """Every hole against the travel; the whole job's cycle, for its hole tour and tolerances."""
    return drill_cycle(job, machine, kin, (start.get("x", 0.0), start.get("y", 0.0)))


def _prepare(job: SimpleNamespace, whole: DrillCycle) -> SimpleNamespace:
    """The whole job's short tour, then cut into segments."""
    return _in_order(job, whole.order) if job.drill.order == "shortest" else job


def _in_order(job: SimpleNamespace, order: tuple[int, ...]) -> SimpleNamespace:
    """The drill job with its holes in ``order``, drilled as given."""
    d = job.drill
    return SimpleNamespace(**{**vars(job), "drill": SimpleNamespace(**{
        **vars(d), "holes": [d.holes[k] for k in order], "hole_planes": [d.hole_planes[k] for k in order],
        "order": "given"})})


def _hold_until_settled(builder: PlanBuilder, cycle: DrillCycle, kin: Kinematics) -> None:
    """Hold every axis at the segment's end until the simulated feedback is at rest."""
    _hold_settled(builder, kin, cycle.xy_tolerance, cycle.servo_period)


def _settle_before(job: SimpleNamespace, machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """A program's drill operation starts where the operation before left the drives at rest
    (its timing search assumes it): hold until they have settled there. Else X/Y still
    settling from a rapid moves below R while the cycle climbs to it (hole-circle.ngc).
    No cycle of this job is built for it: every cycle has DrillCycle's tolerance and period."""
    _hold_settled(builder, kin, DrillCycle.xy_tolerance, DrillCycle.servo_period)


def _hold_settled(builder: PlanBuilder, kin: Kinematics, xy_tolerance: float, period: float) -> None:
    t_end = builder.end_time()
    settle = settle_time(builder, kin, t_end, SETTLE_SHARE * xy_tolerance, period)
    for joint in builder.machine.joint_names:
        if joint != SPINDLE and settle > 0.0:
            builder.timelines[joint].add_hold(t_end, settle)


KIND = JobKind(
    name="drill",
    plan=plan_drill,
    layouts=("mill3", "5ax_table_table", "5ax_head_table"),
    segmenting=Segmenting(size=SEGMENT_HOLES, index="hole", count=lambda job: len(job.drill.holes), part=_part,
                          check_whole=_check_whole, prepare=_prepare, settle=_hold_until_settled),
    report=ReportSection("drill", f"{__name__}.report:drill_section", judges_chips=True, times_cycle=True,
                         cards_at=f"{__name__}.page:cards", tables_at=f"{__name__}.page:tables",
                         baselines_at=(f"{__name__}.report:other_cycles",)),
    figures=Figures(f"{__name__}.figures", aircut_summary="first_hole_aircut"),
    progress=ProgressCount("S1", "hole", total=lambda job: len(job.drill.holes)),
    settle_before=_settle_before,
)
