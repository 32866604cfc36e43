"""The order holes are drilled in: as given, or a short tour (``order: shortest``).

The tour is an open path from the machine's start over every hole: nearest neighbour,
then 2-opt (reverse any stretch whose reversal shortens the path) until no reversal
helps. Distances are Chebyshev (the larger of |dx| and |dy|): X and Y position at the
same time, so a move takes about as long as its longer axis needs.
"""
from __future__ import annotations

import numpy as np

MAX_TWO_OPT_HOLES = 2000  # beyond this the 2-opt passes cost more than the tour saves


def _length(points: np.ndarray, order: list[int], start: np.ndarray) -> float:
    path = np.vstack([start, points[order]])
    return float(np.sum(np.max(np.abs(np.diff(path, axis=0)), axis=1)))


def shortest_order(holes: list[tuple[float, float]], start: tuple[float, float]) -> list[int]:
    """Indices of ``holes`` in a short drilling order from ``start``."""
    points = np.asarray(holes, float).reshape(-1, 2)
    n = len(points)
    here = np.asarray(start, float)
    left = np.ones(n, bool)
    order: list[int] = []
    for _ in range(n):
        d = np.max(np.abs(points - here), axis=1)
        d[~left] = np.inf
        k = int(np.argmin(d))
        order.append(k)
        left[k] = False
        here = points[k]
    if n > MAX_TWO_OPT_HOLES:
        return order
    path = np.vstack([np.asarray(start, float), points[order]])
    improved = True
    while improved:
        improved = False
        for i in range(0, n - 1):
            a, b = path[i], path[i + 1]
            c, e = path[i + 2:], path[i + 3:]
            # reverse path[i+1 .. j]: edges (i, i+1) and (j, j+1) become (i, j) and (i+1, j+1)
            before = np.max(np.abs(b - a)) + np.concatenate(
                [np.max(np.abs(e - c[: len(e)]), axis=1), [0.0]])
            after = np.max(np.abs(c - a), axis=1) + np.concatenate(
                [np.max(np.abs(e - b), axis=1), [0.0]])
            gain = before - after
            j = int(np.argmax(gain))
            if gain[j] > 1e-12:
                j += i + 2
                path[i + 1: j + 1] = path[i + 1: j + 1][::-1].copy()
                order[i: j] = order[i: j][::-1]
                improved = True
    return order


def tour_length(holes: list[tuple[float, float]], order: list[int], start: tuple[float, float]) -> float:
    """Chebyshev length of drilling ``holes`` in ``order`` from ``start``."""
    return _length(np.asarray(holes, float).reshape(-1, 2), order, np.asarray(start, float))
