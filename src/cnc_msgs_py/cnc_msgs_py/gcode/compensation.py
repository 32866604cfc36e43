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
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from . import arcs
from .lexer import Block, GcodeError, word_text
from .modal import ROUGHING_CYCLES

if TYPE_CHECKING:
    from .translate import Translator

Point2 = tuple[float, float]
EPS = 1.0e-9
SMALL_CORNER_RAD = 0.05  # LinuxCNC's compensation takes a corner turning less as tangent
COMP_PLANES = (17.0, 18.0)  # LinuxCNC compensates in XY and XZ


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


class OffsetError(ValueError):
    """An offset the path cannot follow; ``index`` is the segment it is about."""

    def __init__(self, index: int, reason: str) -> None:
        super().__init__(reason)
        self.index = index


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


def _entry(start: Point2, offset: Segment) -> Segment:
    """LinuxCNC's entry move: from where the tool stands (uncompensated) to the end of the
    first segment's offset (as the next corner left it); an arc gets the center that makes it
    an arc from the start, on the end's radius (tangent to the offset path there)."""
    end = offset.end
    if offset.center is None:
        return Segment(start, end)
    c, (sa, sb) = offset.center, start
    m = ((sa + end[0]) / 2.0, (sb + end[1]) / 2.0)
    chord = (end[0] - sa, end[1] - sb)
    radial = (end[0] - c[0], end[1] - c[1])
    den = chord[0] * radial[0] + chord[1] * radial[1]
    if abs(den) < EPS:
        raise OffsetError(0, "the entry arc cannot reach its compensated end")
    u = ((m[0] - c[0]) * chord[0] + (m[1] - c[1]) * chord[1]) / den  # c + u * radial lies on the bisector
    return Segment(start, end, (c[0] + u * radial[0], c[1] + u * radial[1]), offset.clockwise)


def offset_pieces(path: list[Segment], d: float, entry: bool = False, small_corner: float = 0.0
                  ) -> list[tuple[int, Segment]]:
    """The path offset by ``d`` (right of travel if positive), corners joined as LinuxCNC
    joins them: arcs about outside corners, inside corners trimmed to their crossing. Each
    piece comes with the index of the segment it belongs to (a corner's arc to the segment
    after it). ``entry``: the first segment is LinuxCNC's entry move (``_entry``): its offset
    meets the next as any other, then starts where the tool stood. A corner turning by less
    than ``small_corner`` (rad) is taken as tangent, as LinuxCNC's compensation takes one below
    0.05 rad: no arc, no trim, the next offset piece starts where the last ended.

    Raises:
        OffsetError: an inside arc or corner the offset cannot follow, with why and where.
    """
    if abs(d) < EPS:
        return list(enumerate(path))
    moved = []
    for k, seg in enumerate(path):
        try:
            moved.append(offset_segment(seg, d))
        except ValueError as err:
            raise OffsetError(k, str(err)) from None
    out: list[tuple[int, Segment]] = [(0, moved[0])]
    for k in range(1, len(path)):
        corner = path[k].start
        t1, t2 = path[k - 1].tangent(True), path[k].tangent(False)
        turn, ahead = _cross(t1, t2), t1[0] * t2[0] + t1[1] * t2[1]
        nxt, (owner, last) = moved[k], out[-1]
        if ahead > 0.0 and (abs(turn) < EPS or math.atan2(abs(turn), ahead) < small_corner):
            out.append((k, nxt if abs(turn) < EPS else replace(nxt, start=last.end)))  # tangent: the offsets meet
            continue
        if abs(turn) < EPS:
            raise OffsetError(k, f"the path turns back on itself at ({corner[0]:g}, {corner[1]:g})")
        if turn * d > 0.0:  # an outside corner: an arc about it, clockwise when offset to the left
            out += [(k, Segment(last.end, nxt.start, corner, d < 0.0)), (k, nxt)]
            continue
        meet = _meets(last, nxt, corner)
        # both moves must keep their direction (the cutter would gouge the contour otherwise); the
        # entry may end anywhere its corner puts it, as LinuxCNC's does
        entering = entry and owner == 0
        if meet is None or not (entering or _kept(last, replace(last, end=meet))) or \
                not _kept(nxt, replace(nxt, start=meet)):
            raise OffsetError(k, f"the inside corner at ({corner[0]:g}, {corner[1]:g}) is too small for the offset "
                             f"{abs(d):g} mm (the cutter would gouge it)")
        out[-1] = (owner, replace(last, end=meet))
        out.append((k, replace(nxt, start=meet)))
    if entry:  # the first offset, as its corner left it, from the uncompensated start
        out[0] = (0, _entry(path[0].start, out[0][1]))
    return out


def offset_path(path: list[Segment], d: float) -> list[Segment]:
    """offset_pieces without the owners."""
    return [seg for _, seg in offset_pieces(path, d)]


# ---- G40/G41/G42/G41.1/G42.1 in the interpreter ----------------------------------------------
@dataclass
class Move:
    """A G0/G1/G2/G3 programmed while compensation is on (program coordinates, mm), with
    the operation it belongs to as it stood then (its key and its job document's header); or
    a dwell (``other``), kept in its place among them."""

    line: int
    rapid: bool
    feed: dict | None  # {"feed": mm/min} or {"feed_per_rev": mm/rev} (G95 at a surface speed)
    start: dict[str, float]
    end: dict[str, float]
    key: tuple
    common: dict
    center: Point2 | None = None
    clockwise: bool = False
    other: dict | None = None


@dataclass
class State:
    """Compensation in force: the offset (mm, > 0 right of travel: G42) in the plane's axes,
    and the moves programmed since it came on, offset when it goes off (G40, the end)."""

    offset: float = 0.0
    plane: tuple[str, str] | None = None  # None: off
    moves: list[Move] = field(default_factory=list)
    exiting: bool = False  # the move after G40 must be straight

    @property
    def on(self) -> bool:
        return self.plane is not None


def words(tr: "Translator", b: Block, used: set[str], g: list[float]) -> None:
    """G40 (the moves so far offset and emitted), G41/G42 [D<tool>], G41.1/G42.1 D<diameter> [L]."""
    st = tr.comp
    if 40.0 in g and st.on:
        finish(tr)
        st.exiting = True
    code = next((c for c in g if c in (41.0, 42.0, 41.1, 42.1)), None)
    if code is None:
        return
    name = word_text("G", code)
    if st.on:
        raise GcodeError(b.line, name, "cannot turn cutter radius compensation on when it is on (G40 first)")
    if tr.state.plane not in COMP_PLANES:
        raise GcodeError(b.line, name, "cutter radius compensation is allowed only in the XY and XZ planes (G17, G18)")
    if code in (41.1, 42.1):
        if "D" not in b.words or b.words["D"] < 0.0:
            raise GcodeError(b.line, name, "needs D, the cutter's diameter (>= 0)")
        used.update(k for k in "DL" if k in b.words)  # L: a lathe tool's orientation, the side is G41/G42's
        radius = tr.state.length(b.words["D"]) / 2.0
    else:
        tool = tr._tool_number(b, "D") if "D" in b.words else tr.state.tool
        used.update("D" if "D" in b.words else "")
        radius = (tr.tool_entry(tool).get("diameter") or 0.0) / 2.0
    st.offset = radius if code in (42.0, 42.1) else -radius
    from .translate import PLANES  # the translator imports this module: read when compensation comes on
    st.plane = PLANES[tr.state.plane][0]
    st.moves = []


def check_line(tr: "Translator", b: Block, g: list[float], m: list[float]) -> None:
    """What LinuxCNC refuses while compensation is on: tool changes, G53, G28/G30, splines,
    offset changes, canned cycles but G70 (their moves are not compensated)."""
    if not tr.comp.on:
        return
    refused = [(m, (6.0, 61.0), "M", "change tools"), (g, (53.0,), "G", "use G53"),
               (g, (28.0, 30.0), "G", "use G28 or G30"), (g, (5.1,), "G", "convert a spline (G5.1)"),
               (g, (10.0,), "G", "set offsets or tool data (G10)"),
               (g, (52.0, 92.0, 92.1, 92.2, 92.3), "G", "change axis offsets"),
               (g, (54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 59.1, 59.2, 59.3), "G", "change coordinate systems"),
               (g, (*ROUGHING_CYCLES, 73.0, 76.0, 81.0, 82.0, 83.0), "G",
                "use canned cycles")]  # G70 runs compensated, as in LinuxCNC (finishing.py)
    for codes, which, letter, what in refused:
        code = next((c for c in codes if c in which), None)
        if code is not None:
            raise GcodeError(b.line, word_text(letter, code), f"cannot {what} with cutter radius compensation on "
                                                               "(G40 first)")
    if tr.state.motion in (73.0, 81.0, 82.0, 83.0) and b.has_axes() and not any(c in (0.0, 1.0, 2.0, 3.0) for c in g):
        raise GcodeError(b.line, word_text("G", tr.state.motion), "cannot use canned cycles with cutter radius "
                                                                  "compensation on (G40 first)")


def add(tr: "Translator", line: int, rapid: bool, feed: dict | None, start: dict, end: dict,
        center: Point2 | None = None, clockwise: bool = False) -> bool:
    """A move while compensation is on, kept to be offset (True), or the move just after G40
    checked (False: the caller moves as usual)."""
    st = tr.comp
    if not st.on:
        if st.exiting and center is not None:
            raise GcodeError(line, "G2" if clockwise else "G3", "the move just after cutter compensation goes off "
                                                               "(G40) must be straight, not an arc")
        st.exiting = False
        return False
    a, c = st.plane
    if a not in start or c not in start:
        raise GcodeError(line, "G41/G42", "compensation needs the tool's position in its plane: move "
                                          f"{a.upper()} and {c.upper()} first")
    st.moves.append(Move(line, rapid, feed, dict(start), dict(end), tr._key(), tr._common("move"), center, clockwise))
    return True


def finish(tr: "Translator") -> None:
    """Offset the moves programmed since compensation came on and emit them: LinuxCNC's entry
    (the first move in the plane ends offset perpendicular to it, from where the tool
    stood), corners joined by offset_pieces, moves out of the plane (Z alone) where the
    path stands. Compensation is off afterwards."""
    st = tr.comp
    a, c = st.plane
    moves, st.plane, st.moves = st.moves, None, []
    planar = [k for k, mv in enumerate(moves)
              if mv.center is not None or (mv.start[a], mv.start[c]) != (mv.end[a], mv.end[c])]  # a full circle too
    if not planar:
        for mv in moves:
            _emit(tr, mv, mv.end)
        return
    first = moves[planar[0]]
    radius = abs(st.offset)
    if first.center is None and math.hypot(first.end[a] - first.start[a], first.end[c] - first.start[c]) <= radius:
        raise GcodeError(first.line, "G41/G42", f"the entry move is not longer than the tool radius ({radius:g} mm)")
    path = [Segment((moves[k].start[a], moves[k].start[c]), (moves[k].end[a], moves[k].end[c]),
                    moves[k].center, moves[k].clockwise) for k in planar]
    try:
        pieces = offset_pieces(path, st.offset, entry=True, small_corner=SMALL_CORNER_RAD)
    except OffsetError as err:
        raise GcodeError(moves[planar[err.index]].line, "G41/G42", str(err)) from None
    at = dict(first.start)
    for k, mv in enumerate(moves):
        if k not in planar:
            at = {**at, **{axis: v for axis, v in mv.end.items() if axis not in (a, c)}}
            _emit(tr, mv, at)
            continue
        i = planar.index(k)
        own = [seg for owner, seg in pieces if owner == i]
        for n, seg in enumerate(own):
            rest = {axis: v for axis, v in at.items() if axis not in (a, c)}
            along = n == len(own) - 1  # the segment itself; before it, the arc about its corner keeps Z
            points = [(seg.end[0], seg.end[1], 1.0)] if seg.center is None else \
                arcs.chords(seg.start, seg.end, seg.center, seg.clockwise)
            for pa, pc, share in points:
                third = {axis: v + share * (mv.end[axis] - v) if along and axis in mv.end else v
                         for axis, v in rest.items()}
                at = {**at, **third, a: pa, c: pc}
                _emit(tr, mv, at)


def hold(tr: "Translator", line: int, entry: dict) -> bool:
    """A dwell while compensation is on, kept in its place among the moves (True), or False."""
    if not tr.comp.on:
        return False
    here = dict(tr.state.position)
    tr.comp.moves.append(Move(line, False, None, here, here, tr._key(), tr._common("move"), other=entry))
    return True


def _emit(tr: "Translator", mv: Move, target: dict) -> None:
    entry = mv.other if mv.other is not None else \
        {"rapid": dict(target)} if mv.rapid else {"linear": dict(target), **(mv.feed or {})}
    tr._move(mv.line, entry, mv.key, mv.common)
