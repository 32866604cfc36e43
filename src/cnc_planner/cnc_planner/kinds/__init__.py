"""The job kinds, one folder per machining method, and the registry that finds them.

A kind's folder holds what its jobs mean: planning, segments, report section, figures and
progress count (cnc_planner.kinds.kind.JobKind). The planner's shell looks kinds up here
and never switches on a kind's name: a new kind is a new folder and a line in KINDS.
"""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.schema import JobError

from cnc_planner.kinds import drill, move, path, program, sync, thread, turn
from cnc_planner.kinds.kind import JobKind

KINDS: dict[str, JobKind] = {kind.name: kind for kind in (
    move.KIND,
    drill.KIND,
    turn.KIND,
    thread.KIND,
    sync.KIND,
    path.KIND,
    program.KIND,
)}


def kind_of(name: str) -> JobKind:
    """The registered kind of that name.

    Raises:
        JobError: no such kind in this planner.
    """
    kind = KINDS.get(name)
    if kind is None:
        raise JobError("kind", f"'{name}' jobs are not implemented by this planner yet")
    return kind


def progress_count(job: SimpleNamespace) -> dict:
    """What the job's statuses count (cnc_msgs_py.status.Status.count): the event marking
    one more item, what the item is called and the job's total; {} for a kind that counts nothing."""
    count = kind_of(job.kind).progress
    if count is None:
        return {}
    return {"event": count.event, "unit": count.unit, "total": count.total(job)}
