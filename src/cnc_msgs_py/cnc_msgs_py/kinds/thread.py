"""Thread jobs: a thread cut on the lathe in passes (G76-like), right to left."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import Bool, JobError, List, Num, Obj, Str
from ..units import to_mm
from .kind import KindSchema

MIN_PITCH = 0.01  # mm
END_TAPER_ENDS = ("entry", "exit", "both")  # G76's L 1, 2, 3

THREAD = Obj({
    "start_z": Num("mm"),
    "end_z": Num("mm"),
    "major_radius": Num("mm", gt=0.0),
    "pitch": Num("mm", gt=0.0, min=MIN_PITCH, max=100.0),
    "depth": Num("mm", gt=0.0),
    "passes": Num("1", min=1, max=100, integer=True, default=6),
    "depths": List(Num("mm", gt=0.0), min_len=1, max_len=100, default=None),
    "infeed_angle": Num("deg", min=0.0, max=90.0, default=29.5),
    "spring_passes": Num("1", min=0, max=10, integer=True, default=1),
    "starts": Num("1", min=1, max=16, integer=True, default=1),
    "internal": Bool(default=False),
    "taper": Num("1", min=0.0, max=0.5, default=0.0),  # diameter per length (NPT 1:16 = 0.0625)
    # G76's E and L: every pass ramps out by `depth` over `length` of the groove at these ends
    "end_taper": Obj({"length": Num("mm", gt=0.0), "ends": Str(choices=END_TAPER_ENDS)}, default=None),
}, default=None)


def tapered_ends(ends: str | None) -> tuple[bool, bool]:
    """(entry, exit): whether an end_taper.ends (None: no end_taper) tapers the thread's
    entry from start_z and its exit to end_z."""
    return ends in ("entry", "both"), ends in ("exit", "both")


def check(job: SimpleNamespace) -> None:
    """Pass depths that increase to the thread's depth, a depth that leaves an external thread
    some metal, and a cut that runs right to left."""
    t = job.thread
    if t.depths is not None:
        if any(b <= a for a, b in zip(t.depths, t.depths[1:])):
            raise JobError("thread.depths", "cumulative depths must increase")
        if abs(t.depths[-1] - t.depth) > 1e-9:
            raise JobError("thread.depths", "the last depth must equal thread.depth")
    if not t.internal and t.depth >= t.major_radius:
        raise JobError("thread.depth", "must be smaller than major_radius")
    if t.end_z >= t.start_z:
        raise JobError("thread.end_z", "must lie left of start_z (smaller z)")
    if t.end_taper is not None:
        tapered = t.end_taper.length * (2 if t.end_taper.ends == "both" else 1)
        if tapered > t.start_z - t.end_z + 1e-12:
            raise JobError("thread.end_taper.length", f"{to_mm(tapered):g} mm of tapered ends is longer than "
                           f"the thread's {to_mm(t.start_z - t.end_z):g} mm from start_z to end_z")


# A thread uses every vibration key: it shifts the phase and raises D from pass to pass.
KIND = KindSchema("thread", THREAD, check, needs_spindle=True, lathe_tool=True,
                  unused={"surface_speed": "a thread turns at one rpm (spindle_rpm): its lead is locked to the "
                                           "spindle angle, pass after pass"})
