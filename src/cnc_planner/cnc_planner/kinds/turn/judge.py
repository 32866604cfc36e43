"""Judging a turning path against the part: how deep the tool tip went into the profile plus
allowances (max_gouge) and how much material it left above them (material_left).

Both work from the outlines alone, not from the cycle that made the path, so the report and
the tests can judge recorded feedback and planned moves alike.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_planner.kinds.turn.moves import TurnMove, with_starts
from cnc_planner.kinds.turn.outline import offset_outline
from cnc_planner.kinds.turn.stock import EPS, HeightField, Point, StockModel, point_segment_distance


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
    depth = np.min([point_segment_distance(p, a, b) for a, b in boundary], axis=0)
    return float(depth.max())


def material_left(stock: list[Point], profile: list[Point], moves: list[TurnMove], origin: Point,
                  finish_allowance: float = 0.0, finish_allowance_z: float = 0.0) -> float:
    """Thickest material left above the profile after the moves (radial, m), over the profile's length.

    With allowances, above the profile offset by them (offset_outline): what the allowances do not
    explain, which a shoulder face's axial allowance would otherwise show as the face's height.
    Replays the moves against the stock, so it judges what the path cuts, not what it intends.
    """
    model = StockModel(stock)
    for a, m in with_starts(origin, moves):
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
