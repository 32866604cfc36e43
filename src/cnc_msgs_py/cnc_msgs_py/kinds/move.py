"""Move jobs: a list of rapid, linear (with a feed) and dwell moves, as G0, G1 and G4 are.

A linear move feeds at ``feed`` (mm/min, G94) or ``feed_per_rev`` (mm/rev, G95: per
revolution of the spindle's actual speed, which at a constant surface speed changes along
the move)."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import JobError, List, Num, Obj
from .kind import MAX_LIST, MIN_FEED, THREAD_ONLY_VIBRATION, KindSchema
from .turn import MIN_FEED_PER_REV

AXIS_KEYS = ("x", "y", "z", "a", "b", "c")

MOVE_TARGET = Obj({k: Num("mm", default=None) for k in AXIS_KEYS})
MOVE_FIELDS = {
    "rapid": Obj(MOVE_TARGET.fields, default=None),
    "linear": Obj(MOVE_TARGET.fields, default=None),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED, default=None),
    "feed_per_rev": Num("mm/rev", gt=0.0, min=MIN_FEED_PER_REV, max=5.0, default=None),
    "dwell": Num("1", gt=0.0, max=3600.0, default=None),
}
MOVE = List(Obj(MOVE_FIELDS), min_len=1, max_len=MAX_LIST, default=None)
MOTIONS = ("rapid", "linear", "dwell")


def check(job: SimpleNamespace) -> None:
    """Each move is one of rapid, linear, dwell, and only a linear one takes a feed (per minute
    or per revolution); a move job needs no spindle unless it vibrates or feeds per revolution."""
    check_moves(job, job.move, "move", MOTIONS)


def check_moves(job: SimpleNamespace, moves: list, block: str, motions: tuple[str, ...]) -> None:
    """The rules of a list of moves (the job's ``block``), each one of ``motions``."""
    for i, move in enumerate(moves):
        given = [k for k in motions if getattr(move, k) is not None]
        if len(given) != 1:
            raise JobError(f"{block}[{i}]", f"needs exactly one of {', '.join(motions)}")
        feeds = [k for k in ("feed", "feed_per_rev") if getattr(move, k) is not None]
        if move.linear is not None and len(feeds) != 1:
            raise JobError(f"{block}[{i}].feed", "required for a linear move (or feed_per_rev)"
                           if not feeds else "give feed or feed_per_rev, not both")
        if move.linear is None and feeds:
            raise JobError(f"{block}[{i}].{feeds[0]}", "only a linear move takes a feed")
        if move.feed_per_rev is not None and job.spindle_rpm <= 0.0 and job.surface_speed is None:
            raise JobError(f"{block}[{i}].feed_per_rev", "a feed per revolution needs the spindle turning "
                                                         "(spindle_rpm or surface_speed)")
        if given[0] != "dwell" and not any(v is not None for v in vars(getattr(move, given[0])).values()):
            raise JobError(f"{block}[{i}].{given[0]}", "names no axis")
    if job.vibration is not None and job.spindle_rpm <= 0.0:
        raise JobError("spindle_rpm", "must be > 0 when a vibration is given")


KIND = KindSchema("move", MOVE, check, unused=THREAD_ONLY_VIBRATION)
