"""Drill jobs: a pattern of holes drilled with one canned cycle (G81/G82/G83/G73-like), overlapped
or conventional, with optional pecks, dwell, clamps to travel over and a touring order."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import Bool, Either, JobError, List, Num, Obj, PointOr, Str, given
from .kind import MAX_LIST, MIN_FEED, THREAD_ONLY_VIBRATION, KindSchema, mm_text

HOLE_AT = Obj({"at": List(Num("mm"), length=2), "depth": Num("mm", gt=0.0, default=None),
               "surface_z": Num("mm", default=None)})
# A hole: ``[x, y]``, or ``{at: [x, y], depth, surface_z}`` overriding the block's values.
HOLE = PointOr(List(Num("mm"), length=2), HOLE_AT, "an [x, y] point or an {at: [x, y], ...} hole")

PECK = Obj({
    "depth": Num("mm", gt=0.0),  # Q: feed this much deeper per peck
    "retract": Str(("full", "break"), default="full"),  # G83 to R, or G73 chip-break
    "full_every": Num("1", min=1, max=1000, integer=True, default=None),  # with break: every N-th to R
}, default=None)
OBSTACLE = List(Num("mm"), length=5)  # [x0, y0, x1, y1, top_z]: a clamp's box, program coordinates

DRILL = Obj({
    "holes": List(HOLE, min_len=1, max_len=MAX_LIST),
    "surface_z": Num("mm", default=0.0),
    "depth": Num("mm", gt=0.0),
    "r_gap": Num("mm", gt=0.0, max=50.0, default=2.0),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED),
    "overlap": Str(("auto", "off"), default="auto"),
    "mode": Either((Str(("auto",)), Num("1", min=1, max=3, integer=True)), "auto, 1, 2 or 3", default="auto"),
    "gentle_air_accel": Bool(default=False),
    "dwell": Num("1", min=0.0, max=60.0, default=0.0),  # s at the bottom of every hole (G82)
    "peck": PECK,
    "clearance_z": Num("mm", default=None),  # X/Y travels no lower than this (G98-like)
    "obstacles": List(OBSTACLE, max_len=1000, default=None),
    "order": Str(("given", "shortest"), default="given"),
}, default=None)

# Drill keys that only the overlapped cycle uses.
OVERLAP_ONLY = {"mode": "the conventional cycle (overlap: off) has no retract modes",
                "gentle_air_accel": "the conventional cycle (overlap: off) has no air arc"}


def check(job: SimpleNamespace) -> None:
    """Per-hole values spelled out: ``holes`` becomes [x, y] points and ``hole_planes`` the
    (surface_z, depth) of each hole; pecks, clearance and obstacles checked against them."""
    d = job.drill
    points, planes = [], []
    for hole in d.holes:
        if isinstance(hole, list):
            points.append(hole)
            planes.append((d.surface_z, d.depth))
        else:
            points.append(hole.at)
            planes.append((d.surface_z if hole.surface_z is None else hole.surface_z,
                           d.depth if hole.depth is None else hole.depth))
    d.holes, d.hole_planes = points, planes
    top = max(surface for surface, _ in planes) + d.r_gap
    if d.clearance_z is not None and d.clearance_z < top - 1e-12:
        raise JobError("drill.clearance_z", f"{mm_text(d.clearance_z)} lies below the highest R plane ({mm_text(top)})")
    for k, (x0, y0, x1, y1, _) in enumerate(d.obstacles or []):
        if not (x0 < x1 and y0 < y1):
            raise JobError(f"drill.obstacles[{k}]", "needs x0 < x1 and y0 < y1")
        for i, (x, y) in enumerate(points):
            if x0 <= x <= x1 and y0 <= y <= y1:
                raise JobError(f"drill.obstacles[{k}]", f"covers drill.holes[{i}]")
    if d.peck is not None:
        if job.vibration is not None:
            raise JobError("drill.peck", "the vibration breaks the chip without pecking: give one of them")
        if d.peck.full_every is not None and d.peck.retract != "break":
            raise JobError("drill.peck.full_every", "only chip-break pecks (retract: break) retract fully every N")


def check_given(doc: dict, job: SimpleNamespace) -> None:
    """The conventional cycle (overlap: off) refuses the keys only the overlapped one uses."""
    if job.drill.overlap == "off":
        for key, why in OVERLAP_ONLY.items():
            if given(doc, f"drill.{key}"):
                raise JobError(f"drill.{key}", f"not used: {why}")


KIND = KindSchema(
    "drill", DRILL, check, check_given=check_given, needs_spindle=True,
    unused={"tool.nose_radius": "a drill has no nose radius (it is a lathe insert's)", **THREAD_ONLY_VIBRATION,
            "surface_speed": "a drill turns at one rpm (spindle_rpm): constant surface speed is for turning"},
)
