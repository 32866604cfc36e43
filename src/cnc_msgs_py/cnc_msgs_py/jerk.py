"""How jerk is measured on an axis's positions: the planner's limit and the judge's figure.

``max_jerk`` binds an axis's motion, i.e. its feedback (docs/machines.md). Feedback is
sampled every servo period and quantised to encoder counts, so its third difference over
one period is mostly counts (one 1 urad count in 1 ms reads as 1000 rad/s^3): jerk is
the third difference over JERK_WINDOW_S, i.e. the jerk averaged by a spline of that width,
where a count weighs 1/125 of what it does over one period.
"""
from __future__ import annotations

import numpy as np

JERK_WINDOW_S = 0.005  # s: the spacing of the third difference


def windowed_jerk(positions: np.ndarray, period: float) -> np.ndarray:
    """Jerk (rows - 3w, ...) of positions (rows, ...) sampled every ``period``, from their
    third difference at a spacing of w = JERK_WINDOW_S / period samples (at least one)."""
    w = max(1, round(JERK_WINDOW_S / period))
    x = np.asarray(positions, dtype=float)
    return (x[3 * w:] - 3 * x[2 * w:-w] + 3 * x[w:-2 * w] - x[:-3 * w]) / (w * period) ** 3
