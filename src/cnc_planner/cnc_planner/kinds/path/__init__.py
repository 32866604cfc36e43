"""Tool-tip paths with tool-axis changes, through the machine's kinematics (method 5);
every layout, 5-axis included."""
from __future__ import annotations

from .planning import plan_path
from cnc_planner.kinds.kind import JobKind, ReportSection


KIND = JobKind(
    name="path",
    plan=plan_path,
    report=ReportSection("kinematics", f"{__name__}.report:path_section", cards_at=f"{__name__}.page:cards"),
)
