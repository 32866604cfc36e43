"""Where material is: a radius over z (HeightField) and the stock left as the tool cuts (StockModel).

Points are (z, x): z along the spindle axis (face at z = 0, the tool cuts from right to
left, towards negative z), x the tool's radial position (a radius). Everything is SI (m).
Stock, profile and offset profile are each the region under such a field; the roughing
cycle sweeps the stock's field down move by move, so that each pass sees what is left.
"""
from __future__ import annotations

import math

import numpy as np

Point = tuple[float, float]  # (z, x): x is a radius, m

EPS = 1.0e-12  # m: below float noise at workpiece sizes; geometric decisions use it
TOUCH = 1.0e-9  # m: the tool touches material only where it lies deeper than this


class HeightField:
    """A radius over z made of linear pieces (ascending z), with jumps and gaps.

    Stock and profile outlines have shoulders (vertical segments) and ends, so their radius
    jumps. At a jump the lower side counts: "below the field" then means strictly inside.
    """

    def __init__(self, za: np.ndarray, ra: np.ndarray, zb: np.ndarray, rb: np.ndarray):
        self.za, self.ra, self.zb, self.rb = za, ra, zb, rb

    @classmethod
    def from_outline(cls, points: list[Point]) -> HeightField:
        """From an outline given right to left; vertical segments become jumps."""
        pieces = [(z1, r1, z0, r0) for (z0, r0), (z1, r1) in zip(points, points[1:]) if z0 > z1]
        za, ra, zb, rb = (np.array(c, dtype=float) for c in zip(*reversed(pieces)))
        return cls(za, ra, zb, rb)

    def _value(self, i: np.ndarray, z: np.ndarray) -> np.ndarray:
        t = (z - self.za[i]) / (self.zb[i] - self.za[i])
        return self.ra[i] + (self.rb[i] - self.ra[i]) * t

    def limits(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The radius just left and just right of each z (-inf where nothing is there)."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        n = len(self.za)
        right = np.full(z.shape, -np.inf)
        left = np.full(z.shape, -np.inf)
        if n == 0:
            return left, right
        i = np.clip(np.searchsorted(self.za, z, side="right") - 1, 0, n - 1)
        ok = (self.za[i] <= z) & (z < self.zb[i])
        right[ok] = self._value(i[ok], z[ok])
        j = np.clip(np.searchsorted(self.zb, z, side="left"), 0, n - 1)
        ok = (self.za[j] < z) & (z <= self.zb[j])
        left[ok] = self._value(j[ok], z[ok])
        return left, right

    def at(self, z: np.ndarray) -> np.ndarray:
        """The radius at z, the lower side at a jump (so that x < at(z) is strictly inside)."""
        return np.minimum(*self.limits(z))

    def clip(self, lo: float, hi: float) -> tuple[np.ndarray, ...]:
        """The pieces overlapping the open range (lo, hi), cut to it: z0, r0, z1, r1."""
        keep = (self.za < hi) & (self.zb > lo)
        i = np.flatnonzero(keep)
        z0 = np.maximum(self.za[i], lo)
        z1 = np.minimum(self.zb[i], hi)
        return z0, self._value(i, z0), z1, self._value(i, z1)

    def max_between(self, lo: float, hi: float) -> float:
        """Highest radius over the open range (lo, hi); -inf if nothing is there."""
        _, r0, _, r1 = self.clip(lo, hi)
        return float(max(r0.max(initial=-np.inf), r1.max(initial=-np.inf)))

    def above(self, level: float, tol: float) -> list[tuple[float, float]]:
        """The z intervals (ascending) where the field lies more than tol above level."""
        out = []
        for za, ra, zb, rb in zip(self.za, self.ra, self.zb, self.rb):
            ea, eb = ra - level - tol, rb - level - tol
            if ea <= 0.0 and eb <= 0.0:
                continue
            if ea > 0.0 and eb > 0.0:
                out.append((za, zb))
                continue
            zc = za + (zb - za) * ea / (ea - eb)
            out.append((zc, zb) if eb > 0.0 else (za, zc))
        return merge_intervals(out)

    def _over_segment(self, a: Point, b: Point) -> tuple[np.ndarray, ...]:
        """Pieces under a non-vertical segment: z0, z1 and field minus segment at both."""
        (za, xa), (zb, xb) = a, b
        z0, r0, z1, r1 = self.clip(min(za, zb), max(za, zb))
        slope = (xb - xa) / (zb - za)
        return z0, z1, r0 - (xa + slope * (z0 - za)), r1 - (xa + slope * (z1 - za))

    def length_inside(self, a: Point, b: Point, tol: float = TOUCH) -> float:
        """Length of the segment a-b that runs more than tol below the field."""
        if a[0] == b[0]:
            top = float(self.at(a[0])[0]) - tol
            return max(0.0, min(max(a[1], b[1]), top) - min(a[1], b[1]))
        z0, z1, e0, e1 = self._over_segment(a, b)
        e0, e1 = e0 - tol, e1 - tol
        pos, neg = np.maximum(e0, e1), np.minimum(e0, e1)
        frac = np.where(neg > 0.0, 1.0, np.where(pos <= 0.0, 0.0, pos / np.maximum(pos - neg, EPS)))
        dz = float(np.sum(frac * (z1 - z0)))
        return dz * math.dist(a, b) / abs(b[0] - a[0])

    def lowered(self, a: Point, b: Point) -> HeightField:
        """The field cut down to the segment a-b where it lies above it (the tool sweeps it away)."""
        if a[0] == b[0]:
            return self
        (za, xa), (zb, xb) = a, b
        lo, hi = min(za, zb), max(za, zb)
        slope = (xb - xa) / (zb - za)
        pieces: list[tuple[float, float, float, float]] = []
        for p0, q0, p1, q1 in zip(self.za, self.ra, self.zb, self.rb):
            if p1 <= lo or p0 >= hi:
                pieces.append((p0, q0, p1, q1))
                continue
            k = (q1 - q0) / (p1 - p0)

            def field(z: float) -> float:
                return q0 + k * (z - p0)

            def line(z: float) -> float:  # the tool's path
                return xa + slope * (z - za)

            if p0 < lo:
                pieces.append((p0, q0, lo, field(lo)))
            m0, m1 = max(p0, lo), min(p1, hi)
            d0, d1 = field(m0) - line(m0), field(m1) - line(m1)
            if d0 > 0.0 and d1 < 0.0 or d0 < 0.0 and d1 > 0.0:  # the path crosses the piece
                mc = m0 + (m1 - m0) * d0 / (d0 - d1)
                f0, f1 = (line, field) if d0 > 0.0 else (field, line)
                pieces += [(m0, f0(m0), mc, f0(mc)), (mc, f1(mc), m1, f1(m1))]
            else:
                lower = line if d0 > 0.0 or d1 > 0.0 else field
                pieces.append((m0, lower(m0), m1, lower(m1)))
            if p1 > hi:
                pieces.append((hi, field(hi), p1, q1))
        za_, ra_, zb_, rb_ = (np.array(c, dtype=float) for c in zip(*(p for p in pieces if p[2] > p[0])))
        return HeightField(za_, ra_, zb_, rb_)

    def outline(self) -> list[Point]:
        """The field as an outline, right to left (a jump a shoulder), without repeated points."""
        out: list[Point] = []
        for za, ra, zb, rb in zip(self.za[::-1], self.ra[::-1], self.zb[::-1], self.rb[::-1]):
            for q in ((float(zb), float(rb)), (float(za), float(ra))):
                if not out or q != out[-1]:
                    out.append(q)
        return out

    def breaks(self, lo: float, hi: float) -> np.ndarray:
        """Piece ends within [lo, hi], with lo and hi: between two of them the field is linear."""
        z0, _, z1, _ = self.clip(lo, hi)
        return np.union1d(np.concatenate([z0, z1]), [lo, hi])

    def boundary(self, floor: float = 0.0) -> list[tuple[Point, Point]]:
        """Segments bounding the region under the field, shoulders and ends included; the ends
        reach down to floor (the spindle axis, or below the deepest pass of a bore or a face in
        the roughing cycle's own axes, where the material has no bottom)."""
        segs = []
        for i, (za, ra, zb, rb) in enumerate(zip(self.za, self.ra, self.zb, self.rb)):
            segs.append(((za, ra), (zb, rb)))
            before = self.rb[i - 1] if i > 0 and self.zb[i - 1] == za else floor
            segs.append(((za, before), (za, ra)))
            if i + 1 == len(self.za) or self.za[i + 1] != zb:
                segs.append(((zb, rb), (zb, floor)))
        return segs


class StockModel:
    """The stock left at each moment: the tool sweeps away all material above its tip. Its
    end faces reach down to floor (HeightField.boundary)."""

    def __init__(self, stock: list[Point], floor: float = 0.0):
        self.field = HeightField.from_outline(stock)
        self.floor = floor

    def cut(self, a: Point, b: Point) -> float:
        """Move the tool tip from a to b; returns the length along which it touched material."""
        touched = self.field.length_inside(a, b)
        self.field = self.field.lowered(a, b)
        return touched

    def distance(self, p: Point) -> float:
        """Distance from p to the stock left (0 if p is inside it)."""
        if p[1] < float(self.field.at(p[0])[0]):
            return 0.0
        return min(point_segment_distance(np.array([p]), s0, s1)[0] for s0, s1 in self.field.boundary(self.floor))


def merge_intervals(intervals: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Union of intervals, touching ones joined, ascending."""
    out: list[tuple[float, float]] = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + EPS:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def point_segment_distance(p: np.ndarray, a: Point, b: Point) -> np.ndarray:
    """Distance of each point of p (n, 2) to the segment a-b."""
    a_, b_ = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ab = b_ - a_
    t = np.clip(((p - a_) @ ab) / max(float(ab @ ab), EPS * EPS), 0.0, 1.0)
    return np.linalg.norm(p - (a_ + t[:, None] * ab), axis=1)
