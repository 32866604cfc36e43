"""The benchmark's rows: one job document each, as our planner takes it (mm, mm/min, rpm),
and the start position both sides begin from.

Drilling (mill3): 6 holes along X, 6 along Y, a 3 x 3 grid (served in a serpentine, the
same order on both sides); close (5 mm) and wide (40 mm) pitch; shallow (3 mm) and deep
(30 mm) holes; R 2 mm above the surface, feed 1200 mm/min, 3000 rpm. Both sides start one
pitch before the first hole at the clearance level CLEARANCE_MM above the surface, the
initial Z that G98 returns to.

Deep holes (mill3): bench/deep_holes.py's pecked job, against LinuxCNC's G83 (same hole
list, peck depth, R, feed and limits).

Threading (lathe): issue 9's M12x1.75 example, config/jobs/thread_m12.yaml (vibration
D 1.5, Q 1.2, phase shift 180 deg), from the drive line 1 mm above the major radius at
start_z; the same thread without vibration (thread_m12_conventional.yaml) as our G76-like
reference.

Roughing (lathe): config/jobs/turn_cone.yaml (a cone stock, a stepped profile with a
groove), with the finishing contour pass on (G71 also ends along the contour), from its
origin Q0.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import deep_holes  # bench/: run.py puts it on the path
import yaml

ROOT = Path(__file__).resolve().parents[2]
JOBS = ROOT / "config" / "jobs"
CLEARANCE_MM = 5.0
R_GAP_MM = 2.0
HOLES = 6
THREAD_CLEARANCE_MM = 1.0  # drive line above the major radius (our RETRACT_CLEARANCE)


@dataclass
class Row:
    name: str
    kind: str  # drill | deep | thread | turn
    machine: str
    doc: dict
    start: dict[str, float]  # mm, axis -> position
    notes: list[str] = field(default_factory=list)
    reference_doc: dict | None = None  # thread: our cycle without vibration


def _serpentine(nx: int, ny: int, pitch: float) -> list[list[float]]:
    holes = []
    for j in range(ny):
        xs = range(nx) if j % 2 == 0 else reversed(range(nx))
        holes += [[i * pitch, j * pitch] for i in xs]
    return holes


def drill_rows() -> list[Row]:
    rows = []
    for pattern in ("X", "Y", "grid"):
        for pitch in (5.0, 40.0):
            for depth in (3.0, 30.0):
                if pattern == "X":
                    holes = [[i * pitch, 0.0] for i in range(HOLES)]
                    start = {"x": -pitch, "y": 0.0}
                elif pattern == "Y":
                    holes = [[0.0, i * pitch] for i in range(HOLES)]
                    start = {"x": 0.0, "y": -pitch}
                else:
                    holes = _serpentine(3, 3, pitch)
                    start = {"x": -pitch, "y": 0.0}
                name = f"drill {pattern:<4} p{pitch:g} d{depth:g}"
                doc = {"schema": "cnc_job/1", "job_id": name.replace(" ", "-"), "kind": "drill",
                       "machine": "mill3", "tool": {"length": 0.0, "diameter": 6.0}, "spindle_rpm": 3000,
                       "drill": {"holes": holes, "surface_z": 0.0, "depth": depth, "r_gap": R_GAP_MM,
                                 "feed": 1200, "overlap": "auto", "mode": "auto"}}
                rows.append(Row(name, "drill", "mill3", doc, {**start, "z": CLEARANCE_MM}))
    return rows


def _job(name: str) -> dict:
    return yaml.safe_load((JOBS / name).read_text())


def thread_row() -> Row:
    doc = _job("thread_m12.yaml")
    ref = _job("thread_m12_conventional.yaml")
    t = doc["thread"]
    start = {"x": t["major_radius"] + THREAD_CLEARANCE_MM, "z": t["start_z"]}
    return Row("thread M12x1.75", "thread", "lathe", doc, start, reference_doc=ref)


def turn_row() -> Row:
    doc = _job("turn_cone.yaml")
    doc["turn"]["finishing_pass"] = True
    oz, ox = doc["turn"]["origin"]
    return Row("rough cone+steps", "turn", "lathe", doc, {"x": ox, "z": oz})


def deep_hole_row() -> Row:
    """bench/deep_holes.py's pecked job (20 holes, 5 x D, pecks of 1 x D, full retracts),
    from the same start (its X/Y one pitch before the first hole, Z 50 mm)."""
    start = {axis: value * 1e3 for axis, value in deep_holes.START.items()}
    return Row("deep holes 5xD G83", "deep", "mill3", deep_holes.pecked_job(), start)


def all_rows() -> list[Row]:
    return drill_rows() + [deep_hole_row(), thread_row(), turn_row()]
