"""Move jobs: a list of rapid, linear (with a feed) and dwell moves, as G0, G1 and G4 are."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import JobError, List, Num, Obj
from .kind import MAX_LIST, MIN_FEED, THREAD_ONLY_VIBRATION, KindSchema

AXIS_KEYS = ("x", "y", "z", "a", "b", "c")

MOVE_TARGET = Obj({k: Num("mm", default=None) for k in AXIS_KEYS})
MOVE = List(Obj({
    "rapid": Obj(MOVE_TARGET.fields, default=None),
    "linear": Obj(MOVE_TARGET.fields, default=None),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED, default=None),
    "dwell": Num("1", gt=0.0, max=3600.0, default=None),
}), min_len=1, max_len=MAX_LIST, default=None)


def check(job: SimpleNamespace) -> None:
    """Each move is one of rapid, linear, dwell, and only a linear one takes a feed; a move job
    needs no spindle unless it vibrates. At a surface speed it only positions (rapids, dwells):
    the spindle follows the tool's radius between cuts (G96 in force around a G71)."""
    for i, move in enumerate(job.move):
        given = [k for k in ("rapid", "linear", "dwell") if getattr(move, k) is not None]
        if len(given) != 1:
            raise JobError(f"move[{i}]", "needs exactly one of rapid, linear, dwell")
        if move.linear is not None and move.feed is None:
            raise JobError(f"move[{i}].feed", "required for a linear move")
        if move.linear is None and move.feed is not None:
            raise JobError(f"move[{i}].feed", "only a linear move takes a feed")
        if given[0] != "dwell" and not any(v is not None for v in vars(getattr(move, given[0])).values()):
            raise JobError(f"move[{i}].{given[0]}", "names no axis")
        if move.linear is not None and job.surface_speed is not None:
            raise JobError(f"move[{i}].linear", "feed moves at constant surface speed are not supported yet (turn "
                                                "jobs cut at it): give spindle_rpm")
    if job.vibration is not None and job.spindle_rpm <= 0.0:
        raise JobError("spindle_rpm", "must be > 0 when a vibration is given")


KIND = KindSchema("move", MOVE, check, unused=THREAD_ONLY_VIBRATION)
