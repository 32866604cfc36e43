"""Arcs of lathe outlines (stock and profile in the Z-X plane), expanded into chords.

Pure Python so that job parsing can expand arcs without the planner.
"""
from __future__ import annotations

import math

EPS = 1.0e-12  # m: below float noise at workpiece sizes
CHORD_TOLERANCE = 1.0e-6  # m: the job's arcs are expanded with chords within 1 um of the arc

Point = tuple[float, float]  # (z, x): x is a radius, m


class ArcError(ValueError):
    """An arc that cannot be drawn: ``reason`` says why (lengths in m unless scaled by the
    caller), ``key`` names the arc's key at fault where one is ("center"), else ""."""

    def __init__(self, reason: str, key: str = "") -> None:
        super().__init__(f"arc: {reason}")
        self.reason = reason
        self.key = key


def arc_points(start: Point, end: Point, center: Point | None = None, radius: float | None = None,
               max_chord_error: float = CHORD_TOLERANCE) -> list[Point]:
    """Points of an arc of an outline, chords within max_chord_error of the arc, start and end included.

    Give the center, the signed radius, or both. A positive radius turns counter-clockwise in
    the Z-X plane (z right, x up): run right to left, as outlines are, that arc bulges away from
    the axis (convex, a rounded corner); negative is clockwise (concave, a fillet or groove).
    With the radius alone the arc is the shorter one; with the center alone it is the shorter
    one too, and a half circle needs the radius's sign to pick its side.
    """
    sz, sx = float(start[0]), float(start[1])
    ez, ex = float(end[0]), float(end[1])
    chord = math.hypot(ez - sz, ex - sx)
    if chord <= EPS:
        raise ArcError("start and end are the same point")
    if center is None:
        if radius is None or radius == 0.0:
            raise ArcError("give a center or a non-zero radius")
        half = chord / 2.0
        if abs(radius) < half - EPS:
            raise ArcError(f"radius {abs(radius):g} is shorter than half the chord ({half:g})")
        lz, lx = -(ex - sx) / chord, (ez - sz) / chord  # the chord direction turned counter-clockwise
        h = math.copysign(math.sqrt(max(radius * radius - half * half, 0.0)), radius)
        cz, cx = (sz + ez) / 2.0 + h * lz, (sx + ex) / 2.0 + h * lx
    else:
        cz, cx = float(center[0]), float(center[1])
    rho = math.hypot(sz - cz, sx - cx)
    if abs(math.hypot(ez - cz, ex - cx) - rho) > 1.0e-9 * max(rho, 1.0):
        raise ArcError("start and end are not equally far from the center")
    if radius is not None and abs(abs(radius) - rho) > 1.0e-9 * max(rho, 1.0):
        raise ArcError(f"radius {abs(radius):g} does not match the center ({rho:g} away)")
    a0 = math.atan2(sx - cx, sz - cz)
    ccw = (math.atan2(ex - cx, ez - cz) - a0) % (2.0 * math.pi)
    if radius is not None:
        sweep = ccw if radius > 0.0 else ccw - 2.0 * math.pi
    else:
        if abs(ccw - math.pi) < 1.0e-9:
            raise ArcError("a half circle needs a signed radius to pick its side", "center")
        sweep = ccw if ccw < math.pi else ccw - 2.0 * math.pi
    step = 2.0 * math.acos(max(1.0 - max_chord_error / rho, -1.0))
    n = max(1, math.ceil(abs(sweep) / step))
    pts = [(cz + rho * math.cos(a0 + sweep * k / n), cx + rho * math.sin(a0 + sweep * k / n)) for k in range(n + 1)]
    pts[0], pts[-1] = (sz, sx), (ez, ex)
    return pts
