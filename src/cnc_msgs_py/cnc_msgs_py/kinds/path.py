"""Path jobs: a polyline of tool tip points, optionally with a tool axis at each (5-axis)."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import JobError, List, Num, Obj
from .kind import MAX_LIST, MIN_FEED, THREAD_ONLY_VIBRATION, KindSchema

PATH = Obj({
    "points": List(List(Num("mm"), min_len=3, max_len=3), min_len=2, max_len=MAX_LIST),
    "tool_axis": List(List(Num("1"), length=3), min_len=2, max_len=MAX_LIST, default=None),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED),
    "chord_tolerance": Num("mm", gt=0.0, default=0.01),
}, default=None)


def check(job: SimpleNamespace) -> None:
    """A tool axis, if given, for every point."""
    if job.path.tool_axis is not None and len(job.path.tool_axis) != len(job.path.points):
        raise JobError("path.tool_axis", "needs one vector per point")


KIND = KindSchema("path", PATH, check, unused={**THREAD_ONLY_VIBRATION, "surface_speed": "constant surface speed is "
                                              "for turning on a lathe (turn and move jobs)"})
