"""Sync jobs: a move program with passes locked to the spindle's angle (LinuxCNC's G33).

Besides rapid, linear and dwell moves (as a move job's), a ``sync`` move advances ``lead``
mm along its straight path per spindle revolution. Consecutive sync moves are one pass: it
waits at rest for the spindle's index (angle 0), then runs on without stopping, so that
every pass of a thread cut by hand starts at the same spindle angle and lands in one
groove, shifted only as its programmed start is. The spindle turns at one rpm (a surface
speed would change the lead's speed along a pass) and nothing is vibrated.

A ``tap`` move is a rigid tap (LinuxCNC's G33.1) from where the tool stands to ``tap.z``
and back: in at ``lead`` per revolution, the spindle reversed at the bottom, out locked to
it; the spindle turns forward again after it."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import JobError, List, Num, Obj
from .kind import MAX_LIST, THREAD_ONLY_VIBRATION, KindSchema
from .move import MOVE_FIELDS, MOVE_TARGET, MOTIONS, check_moves
from .thread import MIN_PITCH

SYNC = List(Obj({
    **MOVE_FIELDS,
    "sync": Obj(MOVE_TARGET.fields, default=None),
    "tap": Obj({"z": Num("mm")}, default=None),  # a rigid tap's bottom: in and back out
    "lead": Num("mm", gt=0.0, min=MIN_PITCH, max=100.0, default=None),  # along the path, per revolution
}), min_len=1, max_len=MAX_LIST, default=None)


def check(job: SimpleNamespace) -> None:
    """A move program's rules, a lead on every sync move and none elsewhere, at least one
    sync move, and the spindle turning."""
    check_moves(job, job.sync, "sync", (*MOTIONS, "sync", "tap"))
    for i, move in enumerate(job.sync):
        locked = move.sync is not None or move.tap is not None
        if locked != (move.lead is not None):
            raise JobError(f"sync[{i}].lead", "required for a sync or tap move (mm per revolution)" if locked
                           else "only a sync or tap move takes a lead")
    if not any(move.sync is not None or move.tap is not None for move in job.sync):
        raise JobError("sync", "no move locked to the spindle (a program without one is a move job)")
    if job.vibration is not None:
        raise JobError("vibration", "a move locked to the spindle is not vibrated")


KIND = KindSchema("sync", SYNC, check, needs_spindle=True, lathe_tool=True, unused={
    **THREAD_ONLY_VIBRATION,
    "surface_speed": "a move locked to the spindle turns at one rpm (spindle_rpm): its lead's speed is lead x rpm"})
