"""Lathe outlines in the Z-X plane: their checks, and the profile offset by the finishing allowances.

An outline is a list of (z, radius) points run right to left (z decreasing), SI units; the
region under it is the material (the stock) or the part (the profile). Arcs are expanded
into such points when a job is parsed (cnc_msgs_py.outline.arc_points).

The finishing allowance has a radial part u (x, as U in a G71 cycle) and an axial part w (z,
as W): roughing works to the profile offset by both, the region under the profile dilated by
the rectangle [-w, w] x [-u, u] (``offset_outline``), so the tool stays u off diameters and w
off shoulder faces facing either way, and neither the setpoints nor a servo overshoot of a few
um reach the profile.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.kinds.turn import Frame
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.turn.stock import EPS, HeightField, Point


class TurningError(JobError):
    """Bad turning input: the job field (``turn.profile``, ...) and a one-line reason in mm."""


def mm_text(value_m: float) -> str:
    """A length in mm as machinists write it: at least one decimal, at most three."""
    text = f"{to_mm(value_m):.3f}".rstrip("0")
    return text + "0" if text.endswith(".") else text


def _job_u(frame: Frame, u: float) -> float:
    """The job's coordinate along the passes for a cycle u."""
    return -u if frame.passes[0] == "+" else u


def _along(frame: Frame, u: float) -> str:
    """'z=-5.0'-like text of the job's coordinate along the passes for a cycle u."""
    return f"{frame.passes[1]}={mm_text(_job_u(frame, u))}"


def _check_outline(field: str, points: list[Point], frame: Frame) -> None:
    """points in the cycle's axes (u, v); the reasons name the job's axes."""
    if len(points) < 2:
        raise TurningError(field, f"needs at least 2 points (got {len(points)})")
    along = ("z must decrease from right to left" if frame.passes == "-z"
             else f"{frame.passes[1]} must {'increase' if frame.passes[0] == '+' else 'decrease'} along the outline, "
                  f"in the passes' direction ({frame.passes})")
    for i, p in enumerate(points):
        if len(p) != 2 or not all(math.isfinite(v) for v in p):
            raise TurningError(field, f"point {i} is not a finite [z, radius] pair")
    if frame.infeed == "-x":  # outside turning: the material stands around the axis
        _check_radii(field, points)
    for i, p in enumerate(points):
        if i == 0:
            continue
        if p[0] > points[i - 1][0]:
            raise TurningError(field, f"{along} (point {i})")
        if tuple(p) == tuple(points[i - 1]):
            raise TurningError(field, f"point {i} repeats point {i - 1}")
    # With z never increasing, the outline can only cross itself by turning back on a shoulder.
    for i in range(1, len(points) - 1):
        (z0, r0), (z1, r1), (z2, r2) = points[i - 1], points[i], points[i + 1]
        if z0 == z1 == z2 and (r1 - r0) * (r2 - r1) < 0.0:
            raise TurningError(field, f"self-intersects at segment {i} (turns back at {_along(frame, z1)} mm)")
    if points[0][0] == points[-1][0]:
        raise TurningError(field, f"must span a length along {frame.passes[1]}")


def _check_radii(field: str, points: list[Point]) -> None:
    """An outside outline stays on the radius side of the spindle axis, but for its ends: a
    face cut past the axis (G71's contours start or end at X-1) runs there."""
    lead = next((i for i, p in enumerate(points) if p[1] >= 0.0), len(points))
    trail = next((i for i, p in reversed(list(enumerate(points))) if p[1] >= 0.0), -1)
    inner = next((i for i in range(lead, trail + 1) if points[i][1] < 0.0), None)
    if lead == len(points) or inner is not None:
        at = 0 if inner is None else inner
        raise TurningError(field, f"radius must not be negative (point {at}): only the outline's ends may run "
                                  "past the spindle axis")


def check_outlines(stock: list[Point], profile: list[Point], frame: Frame = Frame()) -> None:
    """Raise TurningError unless stock and profile (in the cycle's axes) are valid outlines and
    the profile lies in the stock."""
    _check_outline("turn.stock", stock, frame)
    _check_outline("turn.profile", profile, frame)
    (s_right, _), (s_left, _) = stock[0], stock[-1]
    (p_right, _), (p_left, _) = profile[0], profile[-1]
    for z in (p_right, p_left):
        if not s_left - EPS <= z <= s_right + EPS:
            raise TurningError(
                "turn.profile",
                f"lies outside the stock at {_along(frame, z)} mm "
                f"(the stock spans {_along(frame, s_right)}..{mm_text(_job_u(frame, s_left))} mm)"
            )
    s_field, p_field = HeightField.from_outline(stock), HeightField.from_outline(profile)
    zs = np.union1d(p_field.breaks(p_left, p_right), s_field.breaks(p_left, p_right))
    for lo, hi in reversed(list(zip(zs[:-1], zs[1:]))):  # right to left, as the user reads it
        for z, side in ((hi, 0), (lo, 1)):  # each value from inside (lo, hi)
            p = p_field.limits(z)[side][0]
            if p > s_field.limits(z)[side][0] + EPS:
                raise TurningError("turn.profile", f"lies outside the stock at {_along(frame, z)} mm")


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
    there, against stock that stays), where a shoulder rising at that end (G71's contours end
    climbing to the stock) moves right by axial as any shoulder: the part goes on beyond it.
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
    (z_end, r_end), before_end = profile[-1], profile[-2]
    if before_end[0] == z_end and before_end[1] < r_end:  # a shoulder at the zone's end, the part beyond it
        swept.append((z_end - w, r_end, z_end + w, r_end))
    pieces = _envelope(swept, profile[-1][0], profile[0][0] + w)
    out: list[Point] = []
    for z0, v0, z1, v1 in reversed(pieces):  # right to left
        for q in ((z1, v1 + radial), (z0, v0 + radial)):
            if not out or q != out[-1]:
                out.append(q)
    # the profile's end faces (drops at its ends) stay where they are
    if profile[0][0] == profile[1][0]:
        out.insert(0, (profile[0][0] + w, profile[0][1] + radial))
    if profile[-1][0] == profile[-2][0] and out[-1] != (z_end, r_end + radial):
        out.append((z_end, r_end + radial))
    return out


def hull(outline: list[Point]) -> list[Point]:
    """The outline with its pockets bridged, right to left: the highest radius of the outline
    at or right of each z (a running maximum), what a pass coming from the right meets first.
    Where the outline dips below the height reached, the hull runs level across to where it
    climbs back (G71.1: no pocket is cut)."""
    out: list[Point] = [outline[0]]
    top = outline[0][1]
    for (z0, r0), (z1, r1) in zip(outline, outline[1:]):
        if r1 < top:
            continue  # under the height reached: bridged
        if r0 < top:  # climbs back out of a pocket: the bridge ends where it crosses the top
            q = (z0 + (top - r0) / (r1 - r0) * (z1 - z0), top)
            if q != out[-1]:
                out.append(q)
        if (z1, r1) != out[-1]:
            out.append((z1, r1))
        top = r1
    if out[-1][0] != outline[-1][0]:
        out.append((outline[-1][0], top))
    return out


def working_outlines(stock: list[Point], profile: list[Point], radial: float, axial: float,
                     pockets: str) -> tuple[list[Point], list[Point]]:
    """The stock a roughing cycle starts from and the outline it works to, in the cycle's own
    axes: the profile offset by the allowances; with pockets ``leave`` its hull; with ``only``
    the offset profile, from the stock a pass over the hull leaves (as G71.2 assumes G71.1 left
    it). The planner and the judge both take them from here."""
    offset = offset_outline(profile, radial, axial)
    if pockets == "cut":
        return stock, offset
    bridged = hull(offset)
    if pockets == "leave":
        return stock, bridged
    field = HeightField.from_outline(stock)
    path = [(max(stock[0][0], bridged[0][0]) + 1.0, bridged[0][1]), *bridged]
    for a, b in zip(path, path[1:]):
        field = field.lowered(a, b)
    return field.outline(), offset


def allowances(frame: Frame, finish_allowance: float, finish_allowance_z: float) -> tuple[float, float]:
    """The finishing allowances across the passes and along them (offset_outline's radial and
    axial): x's and z's when the passes run along z, z's and x's when they run along x."""
    if frame.passes[1] == "z":
        return finish_allowance, finish_allowance_z
    return finish_allowance_z, finish_allowance
