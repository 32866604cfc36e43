"""Thread cutting with vibration on two or three axes along the groove (method 4); lathes."""
from __future__ import annotations

from types import SimpleNamespace

from .planning import plan_thread_job
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
    report=ReportSection("thread", f"{__name__}.report:thread_section", judges_chips=True,
                         cards_at=f"{__name__}.page:cards", tables_at=f"{__name__}.page:tables"),
    figures=Figures(f"{__name__}.figures"),
    progress=ProgressCount("thread_pass", "thread pass", total=thread_passes),
)
