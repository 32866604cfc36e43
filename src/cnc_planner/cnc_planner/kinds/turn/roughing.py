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

Roughing works to the profile offset by the finishing allowances (outline.offset_outline).
Rapids stop at least the clearance away from the stock left (and so from the offset profile
under it): a pass starts where its line is the clearance away from the stock, a pass that
ends against a face retracts at 45 degrees by the clearance, and a pass that has to start
against a groove's wall comes in on a short ramp from the clearance off the wall.
Tool nose radius 0.

Every direction is this one cycle: the job's stock, profile and origin are mapped onto the
cycle's own axes (cnc_msgs_py.kinds.turn.Frame: u for z, v for x above), the cycle runs there,
and the moves keep those axes (RoughingPlan.frame maps them back). Facing (passes along X),
bores and passes towards +z differ only in that map, and so do their margins and air moves.
With ``pockets`` ``leave`` (G71.1) the cycle works to the profile's hull seen from the start
(``hull``): no pass dips into a pocket and the contour pass bridges it; with ``only`` (G71.2)
the stock is that hull, so that only the pockets are cut.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.kinds.turn import Frame, frame_of

from cnc_planner.kinds.turn.moves import RoughingPlan, TurnMove
from cnc_planner.kinds.turn.outline import TurningError, allowances, check_outlines, mm_text, working_outlines
from cnc_planner.kinds.turn.stock import EPS, TOUCH, HeightField, Point, StockModel, merge_intervals

MAX_PASSES = 2000  # roughing passes: a depth of cut that needs more is a typing error, and would plan for ages


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
    return merge_intervals(out)


def _bound(frame: Frame, across: bool, value: float) -> str:
    """'x > 5.0'-like text of the job's axis for a cycle coordinate (v if across, else u) above value."""
    sign, axis = (frame.infeed if across else frame.passes)[0], (frame.infeed if across else frame.passes)[1]
    return f"{axis} > {mm_text(value)}" if sign == "-" else f"{axis} < {mm_text(-value)}"


def _check_parameters(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
                      origin: Point, finish_allowance: float, frame: Frame) -> None:
    for field, value in (("depth_of_cut", depth_of_cut), ("clearance", clearance)):
        if not (math.isfinite(value) and value > 0.0):
            raise TurningError(f"turn.{field}", f"must be a positive length (got {mm_text(value)} mm)")
    if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
        raise TurningError("turn.origin", "must be a finite [z, radius] pair")
    span = max(r for _, r in stock) - min(r for _, r in profile)
    if span / depth_of_cut > MAX_PASSES:
        raise TurningError(
            "turn.depth_of_cut",
            f"{mm_text(depth_of_cut)} mm takes {span / depth_of_cut:.4g} passes over "
            f"{mm_text(span)} mm of stock, more than the maximum {MAX_PASSES}; need >= {mm_text(span / MAX_PASSES)} mm"
        )
    top = max(max(r for _, r in stock), max(r for _, r in profile) + finish_allowance)
    right = max(stock[0][0], profile[0][0])
    if not (origin[1] > top or origin[0] > right):
        where = ("above the stock", "right of it") if frame == Frame() else ("off the stock", "ahead of it")
        raise TurningError("turn.origin", f"must lie {where[0]} ({_bound(frame, True, top)} mm) or {where[1]} "
                                          f"({_bound(frame, False, right)} mm)")


class _Cycle:
    """Builds the moves of one roughing cycle while keeping track of the stock left."""

    def __init__(self, stock: list[Point], offset: list[Point], top: float, depth_of_cut: float, clearance: float,
                 origin: Point, naive: bool, axis_side: float | None = None):
        """``axis_side``: the profile of a facing cycle reaches the spindle axis (u = 0) and the
        part lies where u * axis_side >= 0 (_axis_side)."""
        self.offset = offset
        self.axis_side = axis_side
        self.part = HeightField.from_outline(self.offset)  # the tool tip stays on or above it
        self.stock = StockModel(stock, min(0.0, min(r for _, r in offset)))  # a bore's material has no bottom
        self.r_max = top  # the stock's largest radius, where the pass levels are counted from
        self.stock_right = stock[0][0]
        self.z_end = offset[-1][0]  # the machining zone ends at the profile's left end
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
        blocked = _clear_of(self.stock.field.boundary(self.stock.floor), r, self.alpha - 0.5 * TOUCH)
        blocked = merge_intervals(blocked + self.stock.field.above(r, 0.0))  # inside the stock
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
        """Go to a pass start: a straight line from the origin for the first pass where that
        line clears the stock, else (an origin beyond the far end of the stock) the same short
        air move as between passes."""
        if self.moves or self.straight_lift(start, self.origin) > start[1] + TOUCH:
            self.connect(start)
            return
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
        if self.axis_side is not None:
            path = _from_axis(path, self.axis_side)
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


def _axis_side(profile: list[Point], frame: Frame) -> float | None:
    """For passes along x over a profile (job points) that reaches the spindle axis, the sign
    of u on the part's side; else None."""
    if frame.passes[1] != "x" or min(abs(x) for _, x in profile) > EPS or min(x for _, x in profile) < -EPS:
        return None
    return 1.0 if frame.to_cycle(0.0, 1.0)[0] > 0 else -1.0


def _from_axis(path: list[Point], side: float) -> list[Point]:
    """The contour from where it reaches the spindle axis: the allowance offset of a face that
    ends on the axis starts beyond it, and there, at radius r, the part is the profile's
    mirror image at r (a revolved part), not air: lathe_g7x_face_boring.ngc's contour came
    within 0.02 mm of it 0.8 mm past the axis."""
    for k, ((u0, v0), (u1, v1)) in enumerate(zip(path, path[1:])):
        if u0 * side < 0.0 <= u1 * side:
            return [(0.0, v0 + u0 / (u0 - u1) * (v1 - v0))] + path[k + 1:]
    return path


def _plan(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float, origin: Point,
          finish_allowance: float, finishing_pass: bool, finish_allowance_z: float, naive: bool,
          frame: Frame, pockets: str) -> RoughingPlan:
    axis_side = _axis_side(profile, frame)
    stock = [frame.to_cycle(float(z), float(r)) for z, r in stock]
    profile = [frame.to_cycle(float(z), float(r)) for z, r in profile]
    origin = frame.to_cycle(float(origin[0]), float(origin[1]))
    check_outlines(stock, profile, frame)
    for field, value in (("finish_allowance", finish_allowance), ("finish_allowance_z", finish_allowance_z)):
        if not (math.isfinite(value) and value >= 0.0):
            raise TurningError(f"turn.{field}", f"must not be negative (got {mm_text(value)} mm)")
    across, along = allowances(frame, finish_allowance, finish_allowance_z)
    _check_parameters(stock, profile, depth_of_cut, clearance, origin, across, frame)
    work, offset = working_outlines(stock, profile, across, along, pockets)
    cycle = _Cycle(work, offset, max(r for _, r in stock), depth_of_cut, clearance, origin, naive, axis_side)
    cycle.rough()
    if finishing_pass:
        cycle.contour()
    cycle.home()
    return RoughingPlan(cycle.moves, cycle.passes, origin, work, frame)


def plan_roughing(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
                  origin: Point, finish_allowance: float = 0.0, finishing_pass: bool = False,
                  finish_allowance_z: float = 0.0, frame: Frame = Frame(), pockets: str = "cut") -> RoughingPlan:
    """The roughing cycle whose passes start at the stock left, not at the virtual cylinder.

    stock and profile run in the passes' direction as (z, x) (right to left for the default
    frame, passes along -z with the infeed towards -x); depth_of_cut is along the infeed;
    clearance is the air in front of each pass start; origin is Q0. With finishing_pass, one
    more pass follows the offset profile so that only the allowances are left. finish_allowance
    is along x (U), finish_allowance_z along z (W): see offset_outline. pockets: ``cut``,
    ``leave`` or ``only`` (working_outlines). The plan's moves are in the frame's axes.
    """
    return _plan(stock, profile, depth_of_cut, clearance, origin, finish_allowance, finishing_pass,
                 finish_allowance_z, False, frame, pockets)


def plan_naive(stock: list[Point], profile: list[Point], depth_of_cut: float, clearance: float,
               origin: Point, finish_allowance: float = 0.0, finishing_pass: bool = False,
               finish_allowance_z: float = 0.0, frame: Frame = Frame(), pockets: str = "cut") -> RoughingPlan:
    """The same passes, each started at the virtual cylinder's right end: the baseline to beat."""
    return _plan(stock, profile, depth_of_cut, clearance, origin, finish_allowance, finishing_pass,
                 finish_allowance_z, True, frame, pockets)


def plan_of(turn: SimpleNamespace, naive: bool = False) -> RoughingPlan:
    """The roughing plan of a parsed turn block (plan_naive's with naive)."""
    return (plan_naive if naive else plan_roughing)(
        [tuple(p) for p in turn.stock], [tuple(p) for p in turn.profile], turn.depth_of_cut, turn.clearance,
        tuple(turn.origin), turn.finish_allowance, turn.finishing_pass, turn.finish_allowance_z, frame_of(turn),
        turn.pockets)
