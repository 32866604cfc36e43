"""Rough turning with short air moves (method 2): passes over the largest diameter, each
starting where it meets the real stock; lathes."""
from __future__ import annotations

from types import SimpleNamespace

from .planning import plan_turn
from .roughing import plan_roughing
from cnc_planner.kinds.kind import Figures, JobKind, ProgressCount, ReportSection


def cutting_passes(job: SimpleNamespace) -> int:
    """How many roughing passes cut (the progress total)."""
    t = job.turn
    rough = plan_roughing([tuple(p) for p in t.stock], [tuple(p) for p in t.profile], t.depth_of_cut,
                          t.clearance, tuple(t.origin), t.finish_allowance, t.finishing_pass,
                          t.finish_allowance_z)
    return sum(1 for m in rough.moves if m.cutting)


KIND = JobKind(
    name="turn",
    plan=plan_turn,
    layouts=("lathe", "lathe_y"),
    report=ReportSection("turn", f"{__name__}.report:turn_section", times_cycle=True,
                         cards_at=f"{__name__}.page:cards"),
    figures=Figures(f"{__name__}.figures"),
    progress=ProgressCount("pass", "pass", total=cutting_passes),
)
