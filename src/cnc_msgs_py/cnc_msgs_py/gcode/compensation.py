"""Offset paths, as LinuxCNC 2.9 offsets a contour by the cutter radius (G41/G42) or a
finishing distance (G70): every line shifted along its normal, every arc's radius grown or
shrunk about its own center; where the offset path would leave a gap at an outside
(convex) corner an arc about the corner joins it, where it would cross itself at an inside
(concave) corner both neighbours end at their intersection.

Points are (a, b) in the plane's own order (``translate.PLANES``: X, Y for G17, Z, X for
G18), so that G2 is clockwise in it. A positive distance offsets to the right of the
direction of travel (G42), a negative one to the left (G41).

Refused, as LinuxCNC refuses them (``ValueError`` with the reason): an inside arc whose
radius is not larger than the distance, an inside corner whose neighbours are too short to
meet (the cutter would gouge the contour), a path that doubles back on itself.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

Point2 = tuple[float, float]
EPS = 1.0e-9


@dataclass(frozen=True)
class Segment:
    """A straight move, or an arc about ``center`` (``clockwise`` as G2) from start to end."""

    start: Point2
    end: Point2
    center: Point2 | None = None
    clockwise: bool = False

    @property
    def radius(self) -> float:
        assert self.center is not None
        return math.hypot(self.start[0] - self.center[0], self.start[1] - self.center[1])

    def tangent(self, at_end: bool) -> Point2:
        """The unit direction of travel at the start (or the end)."""
        if self.center is None:
            da, db = self.end[0] - self.start[0], self.end[1] - self.start[1]
            n = math.hypot(da, db)
            return da / n, db / n
        p = self.end if at_end else self.start
        ra, rb = p[0] - self.center[0], p[1] - self.center[1]
        n = math.hypot(ra, rb)
        return (rb / n, -ra / n) if self.clockwise else (-rb / n, ra / n)

    def sweep(self) -> float:
        """An arc's swept angle (rad, > 0), a full circle where start and end meet."""
        assert self.center is not None
        t0 = math.atan2(self.start[1] - self.center[1], self.start[0] - self.center[0])
        t1 = math.atan2(self.end[1] - self.center[1], self.end[0] - self.center[0])
        s = ((t0 - t1) if self.clockwise else (t1 - t0)) % (2.0 * math.pi)
        return s if s > EPS else 2.0 * math.pi


def _right(t: Point2) -> Point2:
    return t[1], -t[0]


def _cross(u: Point2, v: Point2) -> float:
    return u[0] * v[1] - u[1] * v[0]


def _shift(p: Point2, n: Point2, d: float) -> Point2:
    return p[0] + d * n[0], p[1] + d * n[1]


def offset_segment(seg: Segment, d: float) -> Segment:
    """The segment moved ``d`` to the right of its travel (left if negative)."""
    if seg.center is None:
        n = _right(seg.tangent(False))
        return Segment(_shift(seg.start, n, d), _shift(seg.end, n, d))
    r = seg.radius
    grown = r + d if not seg.clockwise else r - d  # a G3 arc has its center on the left
    if grown <= EPS:
        raise ValueError(f"an inside arc of radius {r:g} mm is not larger than the offset {abs(d):g} mm")
    c, k = seg.center, grown / r
    scale = lambda p: (c[0] + (p[0] - c[0]) * k, c[1] + (p[1] - c[1]) * k)  # noqa: E731
    return Segment(scale(seg.start), scale(seg.end), c, seg.clockwise)


def _meets(a: Segment, b: Segment, near: Point2) -> Point2 | None:
    """Where a's line or circle meets b's, the crossing nearest ``near``."""
    if a.center is None and b.center is None:
        ta, tb = a.tangent(False), b.tangent(False)
        den = _cross(ta, tb)
        if abs(den) < EPS:
            return None
        w = (b.start[0] - a.start[0], b.start[1] - a.start[1])
        s = _cross(w, tb) / den
        return a.start[0] + s * ta[0], a.start[1] + s * ta[1]
    if a.center is None or b.center is None:
        line, arc = (a, b) if a.center is None else (b, a)
        t, c, r = line.tangent(False), arc.center, arc.radius
        f = (line.start[0] - c[0], line.start[1] - c[1])
        half_b = f[0] * t[0] + f[1] * t[1]
        disc = half_b * half_b - (f[0] ** 2 + f[1] ** 2 - r * r)
        if disc < -EPS:
            return None
        roots = [-half_b + s * math.sqrt(max(disc, 0.0)) for s in (1.0, -1.0)]
        points = [(line.start[0] + u * t[0], line.start[1] + u * t[1]) for u in roots]
    else:
        (c0, r0), (c1, r1) = (a.center, a.radius), (b.center, b.radius)
        dist = math.hypot(c1[0] - c0[0], c1[1] - c0[1])
        if dist < EPS or dist > r0 + r1 + EPS or dist < abs(r0 - r1) - EPS:
            return None
        along = (r0 * r0 - r1 * r1 + dist * dist) / (2.0 * dist)
        h = math.sqrt(max(r0 * r0 - along * along, 0.0))
        u = ((c1[0] - c0[0]) / dist, (c1[1] - c0[1]) / dist)
        m = (c0[0] + along * u[0], c0[1] + along * u[1])
        points = [(m[0] - s * h * u[1], m[1] + s * h * u[0]) for s in (1.0, -1.0)]
    return min(points, key=lambda p: math.hypot(p[0] - near[0], p[1] - near[1]))


def _kept(original: Segment, trimmed: Segment) -> bool:
    """Whether trimming left the segment running its own way (not reversed or wrapped)."""
    if original.center is None:
        t, (da, db) = original.tangent(False), (trimmed.end[0] - trimmed.start[0], trimmed.end[1] - trimmed.start[1])
        return da * t[0] + db * t[1] > EPS
    s = trimmed.sweep()
    return original.sweep() >= 2.0 * math.pi - EPS or s <= original.sweep() + EPS and s < 2.0 * math.pi - EPS


def offset_path(path: list[Segment], d: float) -> list[Segment]:
    """The path offset by ``d`` (right of travel if positive), corners joined as LinuxCNC
    joins them: arcs about outside corners, inside corners trimmed to their crossing.

    Raises:
        ValueError: an inside arc or corner the offset cannot follow, with why.
    """
    if abs(d) < EPS:
        return list(path)
    moved = [offset_segment(s, d) for s in path]
    out: list[Segment] = [moved[0]]
    for k in range(1, len(path)):
        corner = path[k].start
        t1, t2 = path[k - 1].tangent(True), path[k].tangent(False)
        turn, ahead = _cross(t1, t2), t1[0] * t2[0] + t1[1] * t2[1]
        nxt = moved[k]
        if abs(turn) < EPS and ahead > 0.0:
            out.append(nxt)  # tangent: the offsets meet
            continue
        if abs(turn) < EPS:
            raise ValueError(f"the path turns back on itself at ({corner[0]:g}, {corner[1]:g})")
        if turn * d > 0.0:  # an outside corner: an arc about it, clockwise when offset to the left
            out += [Segment(out[-1].end, nxt.start, corner, d < 0.0), nxt]
            continue
        meet = _meets(out[-1], nxt, corner)
        prev = replace(out[-1], end=meet) if meet is not None else None
        nxt_trimmed = replace(nxt, start=meet) if meet is not None else None
        if prev is None or nxt_trimmed is None or not _kept(out[-1], prev) or not _kept(nxt, nxt_trimmed):
            raise ValueError(f"the inside corner at ({corner[0]:g}, {corner[1]:g}) is too small for the offset "
                             f"{abs(d):g} mm (the cutter would gouge it)")
        out[-1] = prev
        out.append(nxt_trimmed)
    return out
