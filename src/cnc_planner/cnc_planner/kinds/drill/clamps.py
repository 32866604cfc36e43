"""Clamps and other obstacles on the table: the level the air path between holes keeps.

An obstacle is a box [x0, y0, x1, y1, top_z] in axis coordinates (m). The tool, a disk of
the tool's radius around the tip, passes over it no lower than top_z + OBSTACLE_MARGIN.
The drill cycle moves X/Y only with the tip above the plane of that move, so each move
between two holes (and from the start to the first) gets its own plane: the R plane, or
top + margin of the highest obstacle that move passes over (DrillCycle.air_planes). A move
that passes over nothing keeps its arc at R.
"""
from __future__ import annotations

import numpy as np

OBSTACLE_MARGIN = 1e-3  # m: the tip stays this far above an obstacle's top


def _point_box(point: np.ndarray, box: np.ndarray) -> float:
    dx = max(box[0] - point[0], point[0] - box[2], 0.0)
    dy = max(box[1] - point[1], point[1] - box[3], 0.0)
    return float(np.hypot(dx, dy))


def _point_segment(point: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
    d = q - p
    s = 0.0 if not d.any() else float(np.clip(np.dot(point - p, d) / np.dot(d, d), 0.0, 1.0))
    return float(np.linalg.norm(point - (p + s * d)))


def _segment_box_distance(p: np.ndarray, q: np.ndarray, box: np.ndarray) -> float:
    """Distance (m) between the XY segment p-q and the rectangle ``box`` (x0, y0, x1, y1):
    0 if the segment enters it, else the nearest of its ends and the box's corners."""
    d = q - p
    lo, hi = 0.0, 1.0  # clip the segment to the box (Liang-Barsky)
    for k in range(2):
        if abs(d[k]) < 1e-15:
            if not box[k] <= p[k] <= box[k + 2]:
                lo, hi = 1.0, 0.0
        else:
            a, b = sorted(((box[k] - p[k]) / d[k], (box[k + 2] - p[k]) / d[k]))
            lo, hi = max(lo, a), min(hi, b)
    if lo <= hi:
        return 0.0
    corners = [np.array([box[i], box[j]]) for i in (0, 2) for j in (1, 3)]
    return min([_point_box(p, box), _point_box(q, box)] + [_point_segment(c, p, q) for c in corners])


def crossed(obstacles: list[list[float]], path: list[tuple[float, float]], radius: float) -> list[int]:
    """Indices of the obstacles that the tool passes over along ``path`` (XY points, m):
    a segment comes within the tool radius plus the margin of its box."""
    found = []
    for k, (x0, y0, x1, y1, _) in enumerate(obstacles):
        box = np.array([x0, y0, x1, y1])
        if any(_segment_box_distance(np.asarray(a, float), np.asarray(b, float), box)
               <= radius + OBSTACLE_MARGIN for a, b in zip(path, path[1:])):
            found.append(k)
    return found


def under_tool(obstacles: list[list[float]], holes: list[tuple[float, float]], radius: float) -> tuple[int, int] | None:
    """(obstacle, hole) of the first hole whose tool would touch an obstacle, else None."""
    for k, (x0, y0, x1, y1, _) in enumerate(obstacles):
        box = np.array([x0, y0, x1, y1])
        for i, hole in enumerate(holes):
            point = np.asarray(hole, float)
            if _point_box(point, box) < radius:
                return k, i
    return None
