"""``lathe_y``: the lathe with a y axis, so the tool reaches off the spindle's plane.

Without a tool axis the spindle keeps its angle and y reaches the point.
"""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE

from .lathe import Lathe


class LatheY(Lathe):
    joints = ("x", "y", "z", SPINDLE)

    def _free_turn(self, tips: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = len(tips)
        return np.zeros((2, n)), np.ones(n, dtype=bool), np.ones((2, n), dtype=bool)

    def _onto_plane(self, joints: dict[str, np.ndarray]) -> None:
        """y reaches off the plane."""
