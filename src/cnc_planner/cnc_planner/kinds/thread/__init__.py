"""Thread cutting with vibration on two or three axes along the groove (method 4); lathes."""
from __future__ import annotations

from types import SimpleNamespace

from . import page
from .planning import plan_thread_job
from .report import thread_section
from cnc_planner.kinds.kind import Figures, JobKind, ProgressCount, ReportSection


def thread_passes(job: SimpleNamespace) -> int:
    """Cutting and spring passes over every start (the progress total)."""
    t = job.thread
    cuts = len(t.depths) if t.depths is not None else t.passes
    return (cuts + t.spring_passes) * t.starts


KIND = JobKind(
    name="thread",
    plan=plan_thread_job,
    layouts=("lathe", "lathe_y"),
    report=ReportSection("thread", thread_section, judges_chips=True, cards=page.cards, tables=page.tables),
    figures=Figures(f"{__name__}.figures"),
    progress=ProgressCount("thread_pass", "thread pass", total=thread_passes),
)
