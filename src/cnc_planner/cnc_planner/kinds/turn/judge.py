"""Judging a turning path against the part: how deep the tool tip went into the profile plus
allowances (max_gouge) and how much material it left above them (material_left).

Both work from the outlines alone, not from the cycle that made the path, so the report and
the tests can judge recorded feedback and planned moves alike. Points, moves and outlines
are the job's (z, x); both judge in the roughing cycle's own axes (the job's Frame), so a
facing or a bore is judged as outside turning is: depth into the part across the passes
and along them, material left across them.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.kinds.turn import Frame

from cnc_planner.kinds.turn.moves import TurnMove, with_starts
from cnc_planner.kinds.turn.outline import allowances, offset_outline, working_outlines
from cnc_planner.kinds.turn.stock import EPS, HeightField, Point, StockModel, point_segment_distance


def _to_cycle(frame: Frame, points: list[Point]) -> list[Point]:
    return [frame.to_cycle(float(z), float(x)) for z, x in points]


def max_gouge(points_zx: np.ndarray, profile: list[Point], finish_allowance: float,
              finish_allowance_z: float = 0.0, frame: Frame = Frame()) -> float:
    """How far any tool tip sample lies inside the profile offset by the allowances (m, 0 if none does)."""
    pts = np.atleast_2d(np.asarray(points_zx, dtype=float))
    if frame != Frame():
        pts = np.array(_to_cycle(frame, [tuple(p) for p in pts]))
        profile = _to_cycle(frame, profile)
    offset = offset_outline(profile, *allowances(frame, finish_allowance, finish_allowance_z))
    inside = pts[:, 1] < HeightField.from_outline(offset).at(pts[:, 0]) - EPS
    if not inside.any():
        return 0.0
    p = pts[inside]
    (z_right, x_right), (z_left, x_left) = offset[0], offset[-1]
    floor = min(0.0, float(p[:, 1].min()))  # the axis, or below the deepest sample of a bore or a face
    face, end = ((z_right, floor), (z_right, x_right)), ((z_left, x_left), (z_left, floor))
    boundary = [face, *zip(offset, offset[1:]), end]
    depth = np.min([point_segment_distance(p, a, b) for a, b in boundary], axis=0)
    return float(depth.max())


def material_left(stock: list[Point], profile: list[Point], moves: list[TurnMove], origin: Point,
                  finish_allowance: float = 0.0, finish_allowance_z: float = 0.0, frame: Frame = Frame(),
                  pockets: str = "cut") -> float:
    """Thickest material left above the profile after the moves (across the passes, m), over the profile's length.

    With allowances, above the profile offset by them (offset_outline): what the allowances do not
    explain, which a shoulder face's axial allowance would otherwise show as the face's height.
    With pockets ``leave`` above the profile's hull, with ``only`` from the stock its hull left
    (outline.working_outlines). Replays the moves against the stock, so it judges what the path
    cuts, not what it intends.
    """
    stock, profile = _to_cycle(frame, stock), _to_cycle(frame, profile)
    work, target = working_outlines(stock, profile, *allowances(frame, finish_allowance, finish_allowance_z), pockets)
    model = StockModel(work)
    for a, m in with_starts(frame.to_cycle(*origin), [TurnMove(m.kind, *frame.to_cycle(m.z, m.x), m.cutting)
                                                       for m in moves]):
        model.cut(a, m.end)
    part = HeightField.from_outline(target)
    lo, hi = profile[-1][0], profile[0][0]
    zs = np.union1d(part.breaks(lo, hi), model.field.breaks(lo, hi))
    worst = 0.0
    for z0, z1 in zip(zs[:-1], zs[1:]):
        for z, side in ((z0, 1), (z1, 0)):  # each value from inside (z0, z1)
            left = model.field.limits(z)[side][0] - part.limits(z)[side][0]
            if math.isfinite(left):
                worst = max(worst, float(left))
    return worst
