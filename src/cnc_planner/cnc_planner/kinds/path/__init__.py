"""Tool-tip paths with tool-axis changes, through the machine's kinematics (method 5);
every layout, 5-axis included."""
from __future__ import annotations

from .page import cards
from .planning import plan_path
from .report import path_section
from cnc_planner.kinds.kind import JobKind, ReportSection


KIND = JobKind(
    name="path",
    plan=plan_path,
    report=ReportSection("kinematics", path_section, cards=cards),
)
