"""``mill3``: a vertical 3-axis mill (LinuxCNC's trivkins plus the tool length).

Joints x, y, z read the spindle nose; the tool axis is always +z of the table.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from cnc_msgs_py.units import to_deg

from .chain import ANGLE_TOL, Z, Chain, Unreachable


class Mill3(Chain):
    joints = ("x", "y", "z")

    def forward(self, xyz: np.ndarray, q: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        return xyz - self.length * Z, np.tile(Z, (len(xyz), 1))

    def inverse(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float]
                ) -> dict[str, np.ndarray]:
        """A tool axis, if given, must be +z."""
        if axes is not None:
            tilt = np.arctan2(np.hypot(axes[:, 0], axes[:, 1]), axes[:, 2])
            if (tilt > ANGLE_TOL).any():
                i = int(np.argmax(tilt > ANGLE_TOL))
                raise Unreachable(i, f"needs the tool tilted {to_deg(tilt[i]):.3f} deg from Z; "
                                     f"layout {self.machine.layout} cannot tilt the tool")
        xyz = tips + self.length * Z
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}
