"""Rough turning with short air moves (DESIGN method 2): an OD roughing cycle in the Z-X plane.

Points are (z, x): z along the spindle axis (face at z = 0, the tool cuts from right to
left, towards negative z), x the tool's radial position (a radius). Everything is SI (m).

Passes are laid over the virtual cylinder of the stock's largest radius, d apart in x,
down to the profile plus the finishing allowance. A pass does not start at the cylinder's
right end but where its line meets the stock left at that moment (plus the clearance), so
the tool does not feed through air in front of a cone, a step or a casting's waviness.
Between passes the tool makes the shortest Z-then-X move that stays clear of the stock.

The profile falls into machining sections where its radius stops rising or falling. A
section is monotone, so a pass line crosses it at most once, and the crossings cut the line
into free stretches: each ends where the line meets a rising section (a shoulder) and,
inside a groove, starts where it meets a falling one. The stretches of one pass line nest in
those of the line above like pockets; each pocket is roughed from the top down before the
next, so undercuts and non-monotonic profiles are cut without gouging. Where material stands
against a falling section the tool cannot come in along z: it comes down onto the material
at the section (a plunge at feed) and then cuts along the pass line. The crossings are
found per linear piece of the profile, which gives the same stretches as per section.

The finishing allowance has a radial part u (x, as U in a G71 cycle) and an axial part w (z,
as W): roughing works to the profile offset by both, the region under the profile dilated by
the rectangle [-w, w] x [-u, u] (``offset_outline``), so the tool stays u off diameters and w
off shoulder faces facing either way, and neither the setpoints nor a servo overshoot of a few
um reach the profile. Rapids stop at least the clearance away from the stock left (and so from
the offset profile under it): a pass starts where its line is the clearance away from the stock,
a pass that ends against a face retracts at 45 degrees by the clearance, and a pass that has to
start against a groove's wall comes in on a short ramp from the clearance off the wall.
Tool nose radius 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.outline import ArcError
from cnc_msgs_py.outline import arc_points as _arc_points
from cnc_msgs_py.units import to_mm

Point = tuple[float, float]  # (z, x): x is a radius, m

EPS = 1.0e-12  # m: below float noise at workpiece sizes; geometric decisions use it
TOUCH = 1.0e-9  # m: the tool touches material only where it lies deeper than this
MAX_PASSES = 2000  # roughing passes: a depth of cut that needs more is a typing error, and would plan for ages


class TurningError(ValueError):
    """Bad turning input; the message is one line starting with the job field, in mm."""


@dataclass(frozen=True)
class TurnMove:
    """One straight move of the roughing cycle to (z, x); cutting if planned to remove material."""

    kind: str  # "rapid" | "feed"
    z: float
    x: float
    cutting: bool

    @property
    def end(self) -> Point:
        return (self.z, self.x)


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
        return _merge(out)

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

    def breaks(self, lo: float, hi: float) -> np.ndarray:
        """Piece ends within [lo, hi], with lo and hi: between two of them the field is linear."""
        z0, _, z1, _ = self.clip(lo, hi)
        return np.union1d(np.concatenate([z0, z1]), [lo, hi])

    def boundary(self) -> list[tuple[Point, Point]]:
        """Segments bounding the region under the field, shoulders and ends included."""
        segs = []
        for i, (za, ra, zb, rb) in enumerate(zip(self.za, self.ra, self.zb, self.rb)):
            segs.append(((za, ra), (zb, rb)))
            before = self.rb[i - 1] if i > 0 and self.zb[i - 1] == za else 0.0
            segs.append(((za, before), (za, ra)))
            if i + 1 == len(self.za) or self.za[i + 1] != zb:
                segs.append(((zb, rb), (zb, 0.0)))
        return segs


class StockModel:
    """The stock left at each moment: the tool sweeps away all material above its tip."""

    def __init__(self, stock: list[Point]):
        self.field = HeightField.from_outline(stock)

    def cut(self, a: Point, b: Point) -> float:
        """Move the tool tip from a to b; returns the length along which it touched material."""
        touched = self.field.length_inside(a, b)
        self.field = self.field.lowered(a, b)
        return touched

    def distance(self, p: Point) -> float:
        """Distance from p to the stock left (0 if p is inside it)."""
        if p[1] < float(self.field.at(p[0])[0]):
            return 0.0
        return min(_point_segment_distance(np.array([p]), s0, s1)[0] for s0, s1 in self.field.boundary())


@dataclass
class RoughingPlan:
    """A roughing cycle as straight moves from the machining origin Q0 back to Q0.

    passes counts pass lines cut over one free stretch each (and the contour pass, if any).
    """

    moves: list[TurnMove]
    passes: int
    origin: Point
    stock: list[Point]

    def segments(self) -> list[tuple[Point, TurnMove]]:
        """Each move with the point it starts from."""
        return _with_starts(self.origin, self.moves)

    @property
    def path_length(self) -> float:
        return sum(math.dist(a, m.end) for a, m in self.segments())

    @property
    def feed_length(self) -> float:
        return sum(math.dist(a, m.end) for a, m in self.segments() if m.kind == "feed")

    def engagement(self) -> list[float]:
        """Per move, the length along which the tool touches the stock left at that moment."""
        model = StockModel(self.stock)
        return [model.cut(a, m.end) for a, m in self.segments()]

    @property
    def air_feed_length(self) -> float:
        """Feed-rate travel in which the tool touches no material: the time the method saves."""
        return sum(
            math.dist(a, m.end) - touched
            for (a, m), touched in zip(self.segments(), self.engagement())
            if m.kind == "feed"
        )

    def points(self, step: float) -> np.ndarray:
        """The tool tip sampled along the whole path at most step apart, shape (n, 2)."""
        chunks = [np.array([self.origin])]
        for a, m in self.segments():
            n = max(1, math.ceil(math.dist(a, m.end) / step))
            t = np.linspace(0.0, 1.0, n + 1)[1:, None]
            chunks.append(np.array(a) + t * (np.array(m.end) - np.array(a)))
        return np.vstack(chunks)

    def to_dict(self) -> dict:
        """Summary for reports, in mm."""
        return {
            "passes": self.passes,
            "air_feed_mm": round(float(to_mm(self.air_feed_length)), 3),
            "path_mm": round(float(to_mm(self.path_length)), 3),
            "feed_mm": round(float(to_mm(self.feed_length)), 3),
        }


def _fmt(value_m: float) -> str:
    """A length in mm as machinists write it: at least one decimal, at most three."""
    text = f"{to_mm(value_m):.3f}".rstrip("0")
    return text + "0" if text.endswith(".") else text


def _with_starts(origin: Point, moves: list[TurnMove]) -> list[tuple[Point, TurnMove]]:
    starts = [origin] + [m.end for m in moves[:-1]]
    return list(zip(starts, moves))


def _merge(intervals: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Union of intervals, touching ones joined, ascending."""
    out: list[tuple[float, float]] = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + EPS:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _point_segment_distance(p: np.ndarray, a: Point, b: Point) -> np.ndarray:
    a_, b_ = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ab = b_ - a_
    t = np.clip(((p - a_) @ ab) / max(float(ab @ ab), EPS * EPS), 0.0, 1.0)
    return np.linalg.norm(p - (a_ + t[:, None] * ab), axis=1)


def _clear_of(segments: list[tuple[Point, Point]], r: float, alpha: float) -> list[tuple[float, float]]:
    """The open z intervals of the line x = r closer than alpha to any of the segments (merged, ascending)."""
    out = []
    for (az, ax), (bz, bx) in segments:
        if min(ax, bx) - alpha >= r or max(ax, bx) + alpha <= r:
            continue
        lo, hi = math.inf, -math.inf
        for cz, cx in ((az, ax), (bz, bx)):  # the discs at the ends
            h = alpha * alpha - (r - cx) ** 2
            if h > 0.0:
                lo, hi = min(lo, cz - math.sqrt(h)), max(hi, cz + math.sqrt(h))
        length = math.hypot(bz - az, bx - ax)
        if length > EPS:  # the band along the segment: 0 <= (p-a).u <= L and |(p-a).n| < alpha
            uz, ux = (bz - az) / length, (bx - ax) / length
            b_lo, b_hi = -math.inf, math.inf
            for c, k, low, high in (((r - ax) * ux - az * uz, uz, 0.0, length),
                                    ((r - ax) * uz + az * ux, -ux, -alpha, alpha)):
                # low <= c + k z <= high
                if abs(k) < 1e-15:
                    if not low <= c <= high:
                        b_lo, b_hi = math.inf, -math.inf
                    continue
                z1, z2 = (low - c) / k, (high - c) / k
                b_lo, b_hi = max(b_lo, min(z1, z2)), min(b_hi, max(z1, z2))
            if b_lo < b_hi:
                lo, hi = min(lo, b_lo), max(hi, b_hi)
        if lo < hi:
            out.append((lo, hi))
    return _merge(out)


def _check_outline(field: str, points: list[Point]) -> None:
    if len(points) < 2:
        raise TurningError(f"{field}: needs at least 2 points (got {len(points)})")
    for i, p in enumerate(points):
        if len(p) != 2 or not all(math.isfinite(v) for v in p):
            raise TurningError(f"{field}: point {i} is not a finite [z, radius] pair")
        if p[1] < 0.0:
            raise TurningError(f"{field}: radius must not be negative (point {i})")
        if i == 0:
            continue
        if p[0] > points[i - 1][0]:
            raise TurningError(f"{field}: z must decrease from right to left (point {i})")
        if tuple(p) == tuple(points[i - 1]):
            raise TurningError(f"{field}: point {i} repeats point {i - 1}")
    # With z never increasing, the outline can only cross itself by turning back on a shoulder.
    for i in range(1, len(points) - 1):
        (z0, r0), (z1, r1), (z2, r2) = points[i - 1], points[i], points[i + 1]
        if z0 == z1 == z2 and (r1 - r0) * (r2 - r1) < 0.0:
            raise TurningError(f"{field}: self-intersects at segment {i} (turns back at z={_fmt(z1)} mm)")
    if points[0][0] == points[-1][0]:
        raise TurningError(f"{field}: must span a length along z")


def check_outlines(stock: list[Point], profile: list[Point]) -> None:
    """Raise TurningError unless stock and profile are valid outlines and the profile lies in the stock."""
    _check_outline("turn.stock", stock)
    _check_outline("turn.profile", profile)
    (s_right, _), (s_left, _) = stock[0], stock[-1]
    (p_right, _), (p_left, _) = profile[0], profile[-1]
    for z in (p_right, p_left):
        if not s_left - EPS <= z <= s_right + EPS:
            raise TurningError(
                f"turn.profile: lies outside the stock at z={_fmt(z)} mm "
                f"(the stock spans z={_fmt(s_right)}..{_fmt(s_left)} mm)"
            )
    s_field, p_field = HeightField.from_outline(stock), HeightField.from_outline(profile)
    zs = np.union1d(p_field.breaks(p_left, p_right), s_field.breaks(p_left, p_right))
    for lo, hi in reversed(list(zip(zs[:-1], zs[1:]))):  # right to left, as the user reads it
        for z, side in ((hi, 0), (lo, 1)):  # each value from inside (lo, hi)
            p = p_field.limits(z)[side][0]
            if p > s_field.limits(z)[side][0] + EPS:
                raise TurningError(f"turn.profile: lies outside the stock at z={_fmt(z)} mm")


def _check_parameters(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
                      origin: Point, finish_allowance: float) -> None:
    for field, value in (("depth_of_cut", depth_of_cut), ("clearance", clearance)):
        if not (math.isfinite(value) and value > 0.0):
            raise TurningError(f"turn.{field}: must be a positive length (got {_fmt(value)} mm)")
    if not (math.isfinite(finish_allowance) and finish_allowance >= 0.0):
        raise TurningError(f"turn.finish_allowance: must not be negative (got {_fmt(finish_allowance)} mm)")
    if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
        raise TurningError("turn.origin: must be a finite [z, radius] pair")
    span = max(r for _, r in stock) - min(r for _, r in profile)
    if span / depth_of_cut > MAX_PASSES:
        raise TurningError(
            f"turn.depth_of_cut: {_fmt(depth_of_cut)} mm takes {span / depth_of_cut:.4g} passes over "
            f"{_fmt(span)} mm of stock, more than the maximum {MAX_PASSES}; need >= {_fmt(span / MAX_PASSES)} mm"
        )
    top = max(max(r for _, r in stock), max(r for _, r in profile) + finish_allowance)
    right = max(stock[0][0], profile[0][0])
    if not (origin[1] > top or origin[0] > right):
        raise TurningError(
            f"turn.origin: must lie above the stock (x > {_fmt(top)} mm) or right of it "
            f"(z > {_fmt(right)} mm)"
        )


class _Cycle:
    """Builds the moves of one roughing cycle while keeping track of the stock left."""

    def __init__(self, stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
                 origin: Point, finish_allowance: float, finish_allowance_z: float, naive: bool):
        self.offset = offset_outline(profile, finish_allowance, finish_allowance_z)
        self.part = HeightField.from_outline(self.offset)  # the tool tip stays on or above it
        self.stock = StockModel(stock)
        self.r_max = max(r for _, r in stock)
        self.stock_right = stock[0][0]
        self.z_end = profile[-1][0]  # the machining zone ends at the profile's left end
        self.d, self.alpha, self.origin, self.naive = depth_of_cut, clearance, origin, naive
        self.moves: list[TurnMove] = []
        self.at = origin
        self.passes = 0

    def levels(self) -> list[float]:
        """Pass radii: r_max - k*d on the virtual cylinder, the last one on the lowest offset profile."""
        floor = float(min(self.part.ra.min(), self.part.rb.min()))  # a drop at the zone's end is no floor
        levels = [self.r_max - k * self.d for k in range(1, math.ceil((self.r_max - floor) / self.d))]
        return [r for r in levels if r > floor] + ([floor] if floor < self.r_max else [])

    def free(self, r: float) -> list[tuple[float, float]]:
        """Stretches of the pass line r (ascending) where the tool tip clears the offset profile."""
        out, lo = [], self.z_end
        for f_lo, f_hi in self.part.above(r, EPS):
            if f_lo > lo + EPS:
                out.append((lo, f_lo))
            lo = max(lo, f_hi)
        return out + [(lo, math.inf)]

    def move(self, kind: str, p: Point, cutting: bool) -> None:
        """Append a move to p and sweep the stock with it, so later passes see what is left."""
        if math.dist(self.at, p) <= EPS:
            return
        self.stock.cut(self.at, p)
        self.moves.append(TurnMove(kind, p[0], p[1], cutting))
        self.at = p

    def straight_lift(self, a: Point, b: Point) -> float:
        """Lowest x at a's z from which a straight move to b clears the stock and the offset profile."""
        (za, xa), (zb, xb) = a, b
        need = xa
        if za == zb:
            return need
        for field in (self.stock.field, self.part):
            z0, r0, z1, r1 = field.clip(min(za, zb), max(za, zb))
            for z, r in zip(np.concatenate([z0, z1]), np.concatenate([r0, r1])):
                t = (z - za) / (zb - za)
                if t < 1.0 - EPS:
                    need = max(need, (r - xb * t) / (1.0 - t))
        return need

    def clear_start(self, r: float, z: float) -> float:
        """The smallest z' >= z on the line x = r at least the clearance away from the stock left."""
        blocked = _clear_of(self.stock.field.boundary(), r, self.alpha - 0.5 * TOUCH)
        blocked = _merge(blocked + self.stock.field.above(r, 0.0))  # inside the stock
        for lo, hi in blocked:
            if lo < z < hi:
                z = hi
        return z

    def retract(self) -> None:
        """After a feed: 45 degrees up and right by the clearance, off the face and the surface just cut."""
        if not self.moves or self.moves[-1].kind != "feed":
            return
        a = self.at
        b = (a[0] + self.alpha, a[1] + self.alpha)
        if (self.stock.field.length_inside(a, b) > EPS or self.part.length_inside(a, b, EPS) > EPS
                or self.stock.distance(b) < self.alpha - TOUCH):
            return  # no room (a stretch narrower than the clearance): lift straight up
        self.move("rapid", b, False)

    def connect(self, target: Point) -> None:
        """Shortest Z-then-X move to target: retract, X to the lowest safe height, Z, then X."""
        self.retract()
        (za, xa), (zb, xb) = self.at, target
        lo, hi = min(za, zb), max(za, zb)
        h = max(xa, xb)
        if hi > lo:
            h = max(h, self.stock.field.max_between(lo, hi) + self.alpha, self.part.max_between(lo, hi))
        if h - xa <= TOUCH:
            h = xa  # no lift for float noise: the Z leg stays one-axis
        for p in ((za, h), (zb, h), target):
            self.move("rapid", p, False)

    def cut_pass(self, r: float, stretch: tuple[float, float]) -> None:
        """Cut the pass line r over one free stretch, from the stock it meets to where it leaves it."""
        lo, hi = stretch
        runs = [(max(a, lo), min(b, hi)) for a, b in self.stock.field.above(r, TOUCH) if b > lo and a < hi]
        runs = [run for run in reversed(runs) if run[1] - run[0] > EPS]  # right to left
        if not runs:
            return  # the pass lies in air
        self.passes += 1
        first = runs[0][1]
        if self.naive:
            z_start = max(self.stock_right, first) + self.alpha
        else:
            z_start = self.clear_start(r, first + self.alpha)
        if z_start <= hi - self.alpha:
            self.arrive((z_start, r))
        else:  # material stands against a falling section (a groove's wall): ramp down onto it
            z_ramp = max(lo, hi - self.alpha)
            top = max(self.stock.field.max_between(z_ramp - self.alpha, hi), r)
            self.arrive((z_ramp, top + self.alpha))
            self.move("feed", (hi, r), True)
        for (a, _), (_, b_next) in zip(runs, runs[1:]):
            if not self.naive:  # rapid over a dip in the stock, to the clearance before the next bump
                z_next = self.clear_start(r, b_next + self.alpha)
                if a - z_next > self.alpha:
                    self.move("feed", (a, r), True)
                    self.move("rapid", (z_next, r), False)
        self.move("feed", (runs[-1][0], r), True)

    def arrive(self, start: Point) -> None:
        """Go to a pass start: a straight line from the origin for the first pass."""
        if self.moves:
            self.connect(start)
            return
        if self.straight_lift(start, self.origin) > start[1] + TOUCH:
            raise TurningError(
                f"turn.origin: the straight move to the first pass start (z={_fmt(start[0])}, "
                f"x={_fmt(start[1])} mm) would cut the stock"
            )
        self.move("rapid", start, False)

    def rough(self) -> None:
        """Pockets depth first: each stretch at level k, then the stretches it holds at level k+1."""
        levels = self.levels()
        if not levels:
            return
        stack = [(0, s) for s in self.free(levels[0])]
        while stack:
            k, (lo, hi) = stack.pop()
            self.cut_pass(levels[k], (lo, hi))
            if k + 1 < len(levels):
                inside = [s for s in self.free(levels[k + 1]) if s[0] >= lo - EPS and s[1] <= hi + EPS]
                stack.extend((k + 1, s) for s in inside)

    def contour(self) -> None:
        """One pass along profile + allowance, removing the steps the passes leave on the sections.

        A drop at the profile's left end is the end face of the zone, against stock that stays:
        following it would cut a slot, so the pass ends above it.
        """
        path = list(self.offset)
        while path[-2][0] == path[-1][0] and path[-2][1] > path[-1][1]:
            path.pop()
        z0, x0 = path[0]
        ahead = [b for _, b in self.stock.field.above(x0, TOUCH) if b > z0]  # stock left in front of the face
        self.arrive((self.clear_start(x0, max(ahead, default=z0) + self.alpha), x0))
        self.passes += 1
        for p in path:
            self.move("feed", p, True)

    def home(self) -> None:
        """Back to the origin in a straight line, lifting first only if that line would hit something."""
        if not self.moves:
            return
        self.retract()
        need = self.straight_lift(self.at, self.origin)
        if need > self.at[1] + TOUCH:
            self.move("rapid", (self.at[0], need + self.alpha), False)
        self.move("rapid", self.origin, False)


def _plan(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float, origin: Point,
          finish_allowance: float, finishing_pass: bool, finish_allowance_z: float, naive: bool) -> RoughingPlan:
    check_outlines(stock, profile)
    _check_parameters(stock, profile, depth_of_cut, clearance, origin, finish_allowance)
    if not (math.isfinite(finish_allowance_z) and finish_allowance_z >= 0.0):
        raise TurningError(f"turn.finish_allowance_z: must not be negative (got {_fmt(finish_allowance_z)} mm)")
    stock = [(float(z), float(r)) for z, r in stock]
    profile = [(float(z), float(r)) for z, r in profile]
    origin = (float(origin[0]), float(origin[1]))
    cycle = _Cycle(stock, profile, depth_of_cut, clearance, origin, finish_allowance, finish_allowance_z, naive)
    cycle.rough()
    if finishing_pass:
        cycle.contour()
    cycle.home()
    return RoughingPlan(cycle.moves, cycle.passes, origin, stock)


def plan_roughing(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
                  origin: Point, finish_allowance: float = 0.0, finishing_pass: bool = False,
                  finish_allowance_z: float = 0.0) -> RoughingPlan:
    """The roughing cycle whose passes start at the stock left, not at the virtual cylinder.

    stock and profile run right to left as (z, radius); depth_of_cut is radial; clearance is
    the air in front of each pass start; origin is Q0. With finishing_pass, one more pass
    follows the offset profile so that only the allowances are left. finish_allowance is radial
    (U), finish_allowance_z axial (W): see offset_outline.
    """
    return _plan(stock, profile, depth_of_cut, clearance, origin, finish_allowance, finishing_pass,
                 finish_allowance_z, False)


def plan_naive(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
               origin: Point, finish_allowance: float = 0.0, finishing_pass: bool = False,
               finish_allowance_z: float = 0.0) -> RoughingPlan:
    """The same passes, each started at the virtual cylinder's right end: the baseline to beat."""
    return _plan(stock, profile, depth_of_cut, clearance, origin, finish_allowance, finishing_pass,
                 finish_allowance_z, True)


def arc_points(start: Point, end: Point, center: Point | None = None, radius: float | None = None,
               max_chord_error: float = 1.0e-6) -> list[Point]:
    """Points of an arc of an outline, chords within max_chord_error of the arc, start and end included.

    Give the center, the signed radius, or both. A positive radius turns counter-clockwise in
    the Z-X plane (z right, x up): run right to left, as outlines are, that arc bulges away from
    the axis (convex, a rounded corner); negative is clockwise (concave, a fillet or groove).
    With the radius alone the arc is the shorter one; with the center alone it is the shorter
    one too, and a half circle needs the radius's sign to pick its side. Job files expand their
    arcs with the same function when they are parsed (cnc_msgs_py.job).
    """
    try:
        return _arc_points(start, end, center, radius, max_chord_error)
    except ArcError as err:
        raise TurningError(str(err)) from err


def _envelope(pieces: list[tuple[float, float, float, float]], lo: float, hi: float) -> list[tuple[float, ...]]:
    """Upper envelope over [lo, hi] of linear pieces (z0, r0, z1, r1), as contiguous pieces, ascending."""
    p = np.array(pieces, dtype=float)
    za, ra, zb, rb = p.T
    cuts = np.unique(np.clip(np.concatenate([za, zb, [lo, hi]]), lo, hi))
    out: list[list[float]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a <= EPS * 1e-3:
            continue
        m = 0.5 * (a + b)
        act = p[(za < m) & (zb > m)]
        if len(act) == 0:
            continue
        k = (act[:, 3] - act[:, 1]) / (act[:, 2] - act[:, 0])
        def at(z: float) -> float:
            return float(np.max(act[:, 1] + k * (z - act[:, 0])))
        zs = {a, b}
        for i in range(len(act)):
            for j in range(i + 1, len(act)):
                dk = k[i] - k[j]
                if dk != 0.0:
                    # r_i(z) = r_j(z)
                    zc = (act[j, 1] - k[j] * act[j, 0] - act[i, 1] + k[i] * act[i, 0]) / dk
                    if a < zc < b:
                        zs.add(float(zc))
        zs_sorted = sorted(zs)
        for z0, z1 in zip(zs_sorted[:-1], zs_sorted[1:]):
            v0, v1 = at(z0), at(z1)
            if out and abs(out[-1][2] - z0) < 1e-15 and abs(out[-1][3] - v0) < 1e-15:
                # collinear with the previous piece: extend it
                pz0, pv0, pz1, pv1 = out[-1]
                if abs((pv1 - pv0) * (z1 - pz0) - (v1 - pv0) * (pz1 - pz0)) <= 1e-18:
                    out[-1] = [pz0, pv0, z1, v1]
                    continue
            if out:
                z0 = out[-1][2]  # snap to the previous end: no gaps, jumps only
            out.append([z0, v0, z1, v1])
    return [tuple(o) for o in out]


def offset_outline(profile: list[Point], radial: float, axial: float) -> list[Point]:
    """The profile offset by the finishing allowances, right to left: the outline roughing works to.

    The region under the profile dilated by the rectangle [-axial, axial] x [-radial, radial]
    (a Minkowski sum): diameters move up by radial, shoulder faces move away from the part by
    axial whichever way they face, slopes by the rectangle's corner. The part's right end face
    moves right by axial too; on the left the outline ends at the profile's end (the zone ends
    there, against stock that stays).
    """
    profile = [(float(z), float(r)) for z, r in profile]
    if axial <= 0.0:
        return [(z, r + radial) for z, r in profile]
    field = HeightField.from_outline(profile)
    w = axial
    swept = []
    for za, ra, zb, rb in zip(field.za, field.ra, field.zb, field.rb):
        if ra < rb:
            swept += [(za - w, ra, zb - w, rb), (zb - w, rb, zb + w, rb)]
        elif ra > rb:
            swept += [(za - w, ra, za + w, ra), (za + w, ra, zb + w, rb)]
        else:
            swept.append((za - w, ra, zb + w, rb))
    pieces = _envelope(swept, profile[-1][0], profile[0][0] + w)
    out: list[Point] = []
    for z0, v0, z1, v1 in reversed(pieces):  # right to left
        for q in ((z1, v1 + radial), (z0, v0 + radial)):
            if not out or q != out[-1]:
                out.append(q)
    # the profile's end faces (drops at its ends) stay where they are
    if profile[0][0] == profile[1][0]:
        out.insert(0, (profile[0][0] + w, profile[0][1] + radial))
    if profile[-1][0] == profile[-2][0]:
        out.append((profile[-1][0], profile[-1][1] + radial))
    return out


def max_gouge(points_zx: np.ndarray, profile: list[Point], finish_allowance: float,
              finish_allowance_z: float = 0.0) -> float:
    """How far any tool tip sample lies inside the profile offset by the allowances (m, 0 if none does)."""
    pts = np.atleast_2d(np.asarray(points_zx, dtype=float))
    offset = offset_outline(profile, finish_allowance, finish_allowance_z)
    inside = pts[:, 1] < HeightField.from_outline(offset).at(pts[:, 0]) - EPS
    if not inside.any():
        return 0.0
    p = pts[inside]
    (z_right, x_right), (z_left, x_left) = offset[0], offset[-1]
    face, end = ((z_right, 0.0), (z_right, x_right)), ((z_left, x_left), (z_left, 0.0))
    boundary = [face, *zip(offset, offset[1:]), end]
    depth = np.min([_point_segment_distance(p, a, b) for a, b in boundary], axis=0)
    return float(depth.max())


def material_left(stock: list[Point], profile: list[Point], moves: list[TurnMove], origin: Point,
                  finish_allowance: float = 0.0, finish_allowance_z: float = 0.0) -> float:
    """Thickest material left above the profile after the moves (radial, m), over the profile's length.

    With allowances, above the profile offset by them (offset_outline): what the allowances do not
    explain, which a shoulder face's axial allowance would otherwise show as the face's height.
    Replays the moves against the stock, so it judges what the path cuts, not what it intends.
    """
    model = StockModel(stock)
    for a, m in _with_starts(origin, moves):
        model.cut(a, m.end)
    part = HeightField.from_outline(offset_outline(profile, finish_allowance, finish_allowance_z))
    lo, hi = profile[-1][0], profile[0][0]
    zs = np.union1d(part.breaks(lo, hi), model.field.breaks(lo, hi))
    worst = 0.0
    for z0, z1 in zip(zs[:-1], zs[1:]):
        for z, side in ((z0, 1), (z1, 0)):  # each value from inside (z0, z1)
            left = model.field.limits(z)[side][0] - part.limits(z)[side][0]
            if math.isfinite(left):
                worst = max(worst, float(left))
    return worst
