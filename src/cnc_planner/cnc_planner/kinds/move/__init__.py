"""Move programs: rapid, linear and dwell moves, on every layout; a long program is
planned in segments of SEGMENT_MOVES moves."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import Machine

from .planning import move_targets, plan_move
from cnc_planner.kinds.kind import JobKind, ReportSection, Segmenting
from cnc_planner.kinematics import Kinematics


SEGMENT_MOVES = 500  # moves per segment of a move program


def _part(job: SimpleNamespace, lo: int, hi: int) -> SimpleNamespace:
    """The program with only its moves lo..hi-1."""
    return SimpleNamespace(**{**vars(job), "move": job.move[lo:hi]})


def _check_whole(job: SimpleNamespace, machine: Machine, kin: Kinematics, start: dict[str, float]) -> None:
    """Every target against the travel, before the first segment is planned."""
    move_targets(job, machine, kin, start)


KIND = JobKind(
    name="move",
    plan=plan_move,
    report=ReportSection("surface_speed", f"{__name__}.report:surface_speed_section",
                         cards_at=f"{__name__}.page:surface_speed_cards"),
    segmenting=Segmenting(size=SEGMENT_MOVES, index="move", count=lambda job: len(job.move), part=_part,
                          check_whole=_check_whole),
)
