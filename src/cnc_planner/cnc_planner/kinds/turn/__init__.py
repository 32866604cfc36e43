"""Rough turning with short air moves (method 2): passes over the largest diameter, each
starting where it meets the real stock; lathes."""
from __future__ import annotations

from types import SimpleNamespace

from .planning import plan_turn
from .roughing import plan_of
from cnc_planner.kinds.kind import Figures, JobKind, ProgressCount, ReportSection


def cutting_passes(job: SimpleNamespace) -> int:
    """How many roughing passes cut (the progress total)."""
    return sum(1 for m in plan_of(job.turn).moves if m.cutting)


KIND = JobKind(
    name="turn",
    plan=plan_turn,
    layouts=("lathe", "lathe_y"),
    report=ReportSection("turn", f"{__name__}.report:turn_section", times_cycle=True,
                         cards_at=f"{__name__}.page:cards"),
    figures=Figures(f"{__name__}.figures"),
    progress=ProgressCount("pass", "pass", total=cutting_passes),
)
