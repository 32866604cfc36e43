"""Move programs with passes locked to the spindle's angle (LinuxCNC's G33) and rigid taps
(G33.1), on every layout: each pass waits for the spindle's index and runs on at its lead
per revolution, so that the passes of a thread cut by hand land in one groove; a tap
follows the spindle's reversal at the bottom."""
from __future__ import annotations

from types import SimpleNamespace

from .planning import pass_runs, plan_sync_job
from cnc_planner.kinds.kind import JobKind, ProgressCount, ReportSection


def _passes(job: SimpleNamespace) -> int:
    """Passes and taps."""
    return len(pass_runs(job.sync)) + sum(move.tap is not None for move in job.sync)


KIND = JobKind(
    name="sync",
    plan=plan_sync_job,
    report=ReportSection("spindle_sync", f"{__name__}.report:sync_section", cards_at=f"{__name__}.report:cards"),
    progress=ProgressCount("sync_pass", "pass", total=_passes),
)
