"""G2/G3 arcs: their center from R or I/J/K, checked as LinuxCNC checks them, and expanded
into straight feed moves within 1 um of the arc (a move job has no arc of its own)."""
from __future__ import annotations

import math

CHORD_TOLERANCE_MM = 1.0e-3
# LinuxCNC 2.9 refuses an I/J/K arc whose end radius differs from its start radius by more
# than this (mm) and more than this share of the radius.
RADIUS_TOLERANCE_MM = 0.002
RADIUS_TOLERANCE_SHARE = 0.001

Point2 = tuple[float, float]


def center_from_radius(start: Point2, end: Point2, radius: float, clockwise: bool) -> Point2:
    """The center of the arc of ``radius`` (negative: the longer arc) from start to end.

    Raises:
        ValueError: the radius cannot reach the end, or the ends coincide.
    """
    (a0, b0), (a1, b1) = start, end
    chord = math.hypot(a1 - a0, b1 - b0)
    if chord < 1.0e-9:
        raise ValueError("an R arc needs an end different from its start")
    half = chord / 2.0
    if abs(radius) < half - 1.0e-9:
        raise ValueError(f"radius {abs(radius):g} mm cannot reach the end ({half:g} mm is half the chord)")
    h = math.sqrt(max(radius * radius - half * half, 0.0))
    # the center lies left of the chord for a short counter-clockwise arc
    left = (not clockwise) == (radius > 0.0)
    na, nb = -(b1 - b0) / chord, (a1 - a0) / chord
    sign = 1.0 if left else -1.0
    return (a0 + a1) / 2.0 + sign * h * na, (b0 + b1) / 2.0 + sign * h * nb


def check_center(start: Point2, end: Point2, center: Point2) -> float:
    """The arc's radius; ValueError if start and end lie at different distances from the center."""
    r0 = math.hypot(start[0] - center[0], start[1] - center[1])
    r1 = math.hypot(end[0] - center[0], end[1] - center[1])
    if r0 < 1.0e-9:
        raise ValueError("the center lies on the start point")
    if abs(r1 - r0) > RADIUS_TOLERANCE_MM and abs(r1 - r0) > RADIUS_TOLERANCE_SHARE * r0:
        raise ValueError(f"the end is {r1:g} mm from the center, the start {r0:g} mm")
    return r0


def chords(start: Point2, end: Point2, center: Point2, clockwise: bool) -> list[tuple[float, float, float]]:
    """Points along the arc after the start, as (a, b, share of the sweep), the end last."""
    ca, cb = center
    r = math.hypot(start[0] - ca, start[1] - cb)
    t0 = math.atan2(start[1] - cb, start[0] - ca)
    t1 = math.atan2(end[1] - cb, end[0] - ca)
    sweep = (t1 - t0) % (2.0 * math.pi)
    if clockwise:
        sweep = sweep - 2.0 * math.pi if sweep > 0.0 else 0.0
    if abs(sweep) < 1.0e-12:
        sweep = -2.0 * math.pi if clockwise else 2.0 * math.pi  # same start and end: a full circle
    step = 2.0 * math.acos(max(1.0 - CHORD_TOLERANCE_MM / r, -1.0))
    n = max(1, math.ceil(abs(sweep) / step))
    out = [(ca + r * math.cos(t0 + sweep * k / n), cb + r * math.sin(t0 + sweep * k / n), k / n) for k in range(1, n)]
    return out + [(end[0], end[1], 1.0)]
