"""One analysis for both sides: recorded positions in, the table's figures out.

Only the project's analysis code judges: cnc_analysis.drilling.analyze_drilling
(cycle time, safety violations = samples with the tip below R while X/Y is off the
hole), cnc_analysis.summary.cycle_time (first to last axis motion),
cnc_analysis.threads.analyze_thread (passes, longest chip) and
cnc_planner.kinds.turn.stock.StockModel (which feed travel touches material). The inputs are
sampled positions every 1 ms, SI units.

LinuxCNC's sim loops each joint's command straight back as its feedback (an ideal
servo). For the comparison both sides' positions go through the same servo: the
bridge's DriveModel of the machine (kp, feed-forward, velocity lag, encoder), with the
references' velocity and acceleration taken from the recorded positions by central
differences. The table's LinuxCNC figures are on that feedback; the ideal-loop
recording is analysed too (the "raw" figures).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_planner.kinds.turn.stock import StockModel
from cnc_analysis import summary
from cnc_analysis.drilling import analyze_drilling
from cnc_servo_bridge.drive import DriveModel
from cnc_analysis.threads import analyze_thread

PERIOD = 1e-3
SIMPLIFY_TOLERANCE = 1e-6  # m: a recorded tool path is cut into straight pieces within this
FEED_MARGIN = 1.25  # a piece whose peak speed stays below this x the programmed feed is feed travel


def through_servo(t: np.ndarray, axes: dict[str, np.ndarray], machine: Machine) -> dict[str, np.ndarray]:
    """Positions (a command, as LinuxCNC records it) through our drive model."""
    joints = tuple(axes)
    p = np.stack([axes[j] for j in joints], axis=1)
    v = np.gradient(p, PERIOD, axis=0)
    a = np.gradient(v, PERIOD, axis=0)
    fb, _ = DriveModel(machine, PERIOD, joints).simulate(p, v, a)
    return {j: fb[:, k] for k, j in enumerate(joints)}


def cycle_time(t: np.ndarray, axes: dict[str, np.ndarray]) -> float:
    """cnc_analysis.summary.cycle_time on arrays (it reads a Run's feedback)."""
    joints = tuple(axes)
    run = SimpleNamespace(feedback_t=np.asarray(t), feedback=np.stack([axes[j] for j in joints], axis=1),
                          joints=joints, column=joints.index)
    return summary.cycle_time(run, joints)


def drilling(t: np.ndarray, axes: dict[str, np.ndarray], cycle) -> dict:
    """analyze_drilling with the job's holes, R plane and tolerance (a DrillCycle)."""
    return analyze_drilling(t, axes["x"], axes["y"], axes["z"], cycle.holes, cycle.r_z,
                            cycle.xy_tolerance, cycle.surface_z)


def off_hole(axes: dict[str, np.ndarray], cycle) -> tuple[float, float | None]:
    """While the tip is below R: the largest X/Y distance from the nearest hole (m), and the
    lowest tip height above the surface among the samples farther off than the tolerance
    (the ones analyze_drilling counts as violations; None if there are none)."""
    below = axes["z"] < cycle.r_z
    if not below.any():
        return 0.0, None
    h = np.asarray(cycle.holes, dtype=float).reshape(-1, 2)
    d = np.min(np.hypot(axes["x"][below, None] - h[:, 0], axes["y"][below, None] - h[:, 1]), axis=1)
    off = d > cycle.xy_tolerance
    low = float(axes["z"][below][off].min() - cycle.surface_z) if off.any() else None
    return float(d.max()), low


def thread(t: np.ndarray, axes: dict[str, np.ndarray], spindle: np.ndarray, thread_doc: dict) -> dict:
    return analyze_thread(t, axes["x"], axes["z"], spindle, thread_doc)


def _simplify(points: np.ndarray, tolerance: float) -> list[int]:
    """Douglas-Peucker: indices of the vertices of a polyline within tolerance of points."""
    keep = {0, len(points) - 1}
    stack = [(0, len(points) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = points[i], points[j]
        ab = b - a
        seg = points[i + 1:j] - a
        norm = math.hypot(*ab)
        if norm < 1e-15:
            dist = np.hypot(seg[:, 0], seg[:, 1])
        else:
            dist = np.abs(seg[:, 0] * ab[1] - seg[:, 1] * ab[0]) / norm
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            m = i + 1 + k
            keep.add(m)
            stack += [(i, m), (m, j)]
    return sorted(keep)


def turning_air(t: np.ndarray, axes: dict[str, np.ndarray], stock_mm: list, feed_mm_per_min: float) -> dict:
    """Feed travel and the part of it that touches no material, from a recorded tool path.

    The path (z, x) is cut into straight pieces (Douglas-Peucker, 1 um, and wherever the
    speed crosses FEED_MARGIN x the programmed feed); a piece is feed travel when its
    speed stays below that, rapid otherwise. The pieces are replayed in order against
    cnc_planner.kinds.turn.stock.StockModel of the job's stock (the tool sweeps away all
    material above its tip), which says how long each piece touched material. Lengths in mm.
    """
    zx = np.stack([axes["z"], axes["x"]], axis=1)
    speed = np.hypot(*np.gradient(zx, PERIOD, axis=0).T)
    moving = np.flatnonzero(speed > 1e-6)
    if len(moving) == 0:
        return {"feed_mm": 0.0, "air_feed_mm": 0.0, "air_share": 0.0, "rapid_cut_mm": 0.0}
    lo, hi = int(moving[0]), min(int(moving[-1]) + 1, len(zx) - 1)
    limit = FEED_MARGIN * feed_mm_per_min / 60e3
    fast = speed > limit
    switches = lo + 1 + np.flatnonzero(fast[lo + 1:hi + 1] != fast[lo:hi])  # rapid <-> feed on a line
    vertices = sorted({lo + v for v in _simplify(zx[lo:hi + 1], SIMPLIFY_TOLERANCE)} | set(switches.tolist()))
    model = StockModel([(z * 1e-3, r * 1e-3) for z, r in stock_mm])
    feed = air = rapid_cut = 0.0
    for i, j in zip(vertices, vertices[1:]):
        a, b = (float(zx[i, 0]), float(zx[i, 1])), (float(zx[j, 0]), float(zx[j, 1]))
        length = math.dist(a, b)
        if length <= 0.0:
            continue
        touched = model.cut(a, b)
        if not fast[i + 1:j].any() and not (fast[i] and fast[j]):
            feed += length
            air += max(0.0, length - touched)
        else:
            rapid_cut += touched
    return {"feed_mm": feed * 1e3, "air_feed_mm": air * 1e3, "air_share": air / feed if feed else 0.0,
            "rapid_cut_mm": rapid_cut * 1e3}
