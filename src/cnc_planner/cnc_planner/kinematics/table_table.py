"""``5ax_table_table``: a trunnion (A) carries a rotary table (C); the head moves in x, y, z.

A turns the trunnion right-handed about +X, the C table on it turns right-handed about
+Z, both about lines through ``pivot`` (machine.kinematics); the tool axis is +z of the
machine. In table coordinates the tool axis is (sin a sin c, sin a cos c, cos a).
(LinuxCNC's xyzac-trt-kins.)
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .chain import Z, rot
from .five_axis import FiveAxis


class TableTable(FiveAxis):
    joints = ("x", "y", "z", "a", "c")
    tilt_joint = "a"

    def forward(self, xyz: np.ndarray, q: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        a, c = q["a"], q["c"]
        tips = self.pivot + rot(2, -c, rot(0, -a, xyz - self.length * Z - self.pivot))
        axes = rot(2, -c, rot(0, -a, np.tile(Z, (len(xyz), 1))))
        return tips, axes

    def azimuth(self, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
        return np.arctan2(kx, ky)

    def place(self, tips: np.ndarray, tilt: np.ndarray, c: np.ndarray) -> np.ndarray:
        return self.pivot + rot(0, tilt, rot(2, c, tips - self.pivot)) + self.length * Z
