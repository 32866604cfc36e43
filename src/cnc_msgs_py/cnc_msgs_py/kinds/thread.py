"""Thread jobs: a thread cut on the lathe in passes (G76-like), right to left."""
from __future__ import annotations

from types import SimpleNamespace

from ..schema import Bool, JobError, List, Num, Obj
from .kind import KindSchema

MIN_PITCH = 0.01  # mm

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
}, default=None)


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


# A thread uses every vibration key: it shifts the phase and raises D from pass to pass.
KIND = KindSchema("thread", THREAD, check, needs_spindle=True, lathe_tool=True,
                  unused={"surface_speed": "a thread turns at one rpm (spindle_rpm): its lead is locked to the "
                                           "spindle angle, pass after pass"})
