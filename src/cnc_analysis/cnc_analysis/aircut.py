"""Air-cut analysis of a vibration-cut feed: where does the chip break?

At every spindle phase the workpiece keeps the surface of the revolution that got furthest:
the maximum feed progress reached at that phase in all earlier revolutions. The tool cuts
air wherever it is not ahead of that surface. The same analysis runs on the planner's
setpoints and on the bridge's feedback, where servo lag shows.

Revolutions are counted on the absolute spindle angle (revolution n spans
[2*pi*n, 2*pi*(n+1)), phase 0 is the spindle index), so intervals read as spindle phases
and line up between setpoints, feedback and passes. A revolution is analysed when it is
complete and every phase of it has been cut once before; before that there is no
surface to compare with.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * math.pi
MIN_PHASE_POINTS = 1440  # phase grid per revolution: 0.25 deg, finer if the samples are
ROUNDING = 1e-12  # m: a depth this small is floating-point rounding, not material
CHIP_LIMIT_REVS = 1.0  # a chip is broken within one spindle revolution per vibration window


def chip_limit_revs(vibration: dict | None) -> float:
    """The longest chip (revolutions) a waveform may leave on feedback: CHIP_LIMIT_REVS per
    window, the window being one revolution for D vibrations per revolution and E
    revolutions for one vibration every E revolutions (``vibration``: the waveform as a
    vibration_feed event records it, {D, Q} or {E, R, Q}; none recorded: one revolution)."""
    window = float((vibration or {}).get("E") or 1.0)
    return CHIP_LIMIT_REVS * max(1.0, window)


@dataclass(frozen=True)
class AircutReport:
    """Air-cuts per analysed revolution: complete, and every phase of it cut once before.

    aircut_fraction is the share of the analysed spindle angle spent in air; max_chip_revs
    the longest stretch of uninterrupted cutting inside the analysed revolutions; intervals
    holds, per analysed revolution, the air-cut phases (start, end) in rad.
    """

    revolutions: int
    revolutions_with_aircut: int
    max_chip_revs: float
    aircut_fraction: float
    intervals: list[list[tuple[float, float]]]

    def to_dict(self) -> dict:
        return {
            "revolutions": self.revolutions,
            "revolutions_with_aircut": self.revolutions_with_aircut,
            "max_chip_revs": float(self.max_chip_revs),
            "aircut_fraction": float(self.aircut_fraction),
            "intervals": [[[float(a), float(b)] for a, b in rev] for rev in self.intervals],
        }


def analyze_aircut(
    spindle_angle: np.ndarray,
    feed_position: np.ndarray,
    direction: float = 1.0,
    tolerance: float = 0.0,
) -> AircutReport:
    """Find the air-cuts in samples taken in time order.

    spindle_angle is unwrapped and non-decreasing (rad; negate it for a spindle turning
    backwards); feed_position the feed axis (m); direction +1 if the feed advances towards
    +position, -1 otherwise. A phase is an air-cut where the depth below the earlier
    revolutions' surface is <= tolerance (m).
    Each revolution is resampled onto a common phase grid; the surface is a running
    maximum over revolutions; interval ends are interpolated between grid points.
    """
    theta = np.asarray(spindle_angle, dtype=float)
    progress = direction * np.asarray(feed_position, dtype=float)
    if theta.shape != progress.shape or theta.ndim != 1 or theta.size < 2:
        raise ValueError("spindle_angle and feed_position: equal-length 1-d samples (>= 2) needed")
    if np.any(np.diff(theta) < 0):
        raise ValueError("spindle_angle: must be unwrapped and non-decreasing")
    span = (theta[-1] - theta[0]) / TWO_PI
    points = max(MIN_PHASE_POINTS, math.ceil(theta.size / max(span, 1e-12)))
    first, last = math.floor(theta[0] / TWO_PI), math.floor(theta[-1] / TWO_PI)
    revs = np.arange(first, last + 1)
    # one row per revolution, phases 0..2pi inclusive: the closing point is the next row's first
    angles = TWO_PI * (revs[:, None] + np.arange(points + 1)[None, :] / points)
    grid = np.interp(angles, theta, progress, left=np.nan, right=np.nan)
    surface = np.fmax.accumulate(grid, axis=0)
    depth = grid[1:] - surface[:-1]  # row i: revolution first + 1 + i
    # complete, and every phase already cut once: the first revolution has no earlier surface
    rows = np.flatnonzero(
        (angles[1:, 0] >= theta[0] + TWO_PI - 1e-9) & (angles[1:, -1] <= theta[-1] + 1e-9)
    )
    intervals = [_air_intervals(depth[i], tolerance, points) for i in rows]

    air = sum(b - a for rev in intervals for a, b in rev)
    return AircutReport(
        revolutions=len(rows),
        revolutions_with_aircut=sum(1 for rev in intervals if rev),
        max_chip_revs=float(_longest_cut(intervals) / TWO_PI),
        aircut_fraction=float(air / (TWO_PI * len(rows))) if len(rows) else 0.0,
        intervals=intervals,
    )


def _air_intervals(depth: np.ndarray, tolerance: float, points: int) -> list[tuple[float, float]]:
    """Air-cut phase intervals of one revolution (positive length), ends interpolated where
    the depth crosses the tolerance."""
    air = depth <= tolerance + ROUNDING
    change = np.diff(np.concatenate(([False], air, [False])).astype(int))
    starts, ends = np.flatnonzero(change == 1), np.flatnonzero(change == -1) - 1

    def edge(inside: int, outside: int) -> float:
        d0, d1 = depth[inside], depth[outside]
        return inside + (outside - inside) * float(np.clip((tolerance - d0) / (d1 - d0), 0.0, 1.0))

    scale = TWO_PI / points
    intervals = [
        (scale * (edge(s, s - 1) if s > 0 else 0.0), scale * (edge(e, e + 1) if e < points else points))
        for s, e in zip(starts, ends)
    ]
    # merely touching the surface breaks no chip
    return [(float(a), float(b)) for a, b in intervals if b > a]


def _longest_cut(intervals: list[list[tuple[float, float]]]) -> float:
    """Longest spindle angle between air-cuts (or to the ends of the analysed revolutions)."""
    position, longest = 0.0, 0.0
    for n, rev in enumerate(intervals):
        for a, b in rev:
            longest = max(longest, TWO_PI * n + a - position)
            position = TWO_PI * n + b
    return max(longest, TWO_PI * len(intervals) - position)
