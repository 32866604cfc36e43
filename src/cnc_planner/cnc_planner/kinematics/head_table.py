"""``5ax_head_table``: the head swivels (B), the workpiece sits on a rotary table (C).

B swivels the head right-handed about +Y (B > 0 leans the tool towards +X) about an axis
``pivot_length`` above the spindle nose; C turns the table right-handed about +Z through
``pivot``. In table coordinates the tool axis is (cos c sin b, -sin c sin b, cos b).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .chain import Z, rot
from .five_axis import FiveAxis


class HeadTable(FiveAxis):
    joints = ("x", "y", "z", "b", "c")
    tilt_joint = "b"

    def forward(self, xyz: np.ndarray, q: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        b, c = q["b"], q["c"]
        head = np.stack([np.sin(b), np.zeros(len(xyz)), np.cos(b)], axis=1)
        nose = xyz + self.pivot_length * Z - (self.pivot_length + self.length) * head
        tips = self.pivot + rot(2, -c, nose - self.pivot)
        return tips, rot(2, -c, head)

    def azimuth(self, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
        return np.arctan2(-ky, kx)

    def place(self, tips: np.ndarray, tilt: np.ndarray, c: np.ndarray) -> np.ndarray:
        head = np.stack([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)], axis=1)
        tip = self.pivot + rot(2, c, tips - self.pivot)
        return tip - self.pivot_length * Z + (self.pivot_length + self.length) * head
