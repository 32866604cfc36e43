"""``lathe``: x (radius) and z carry the tool; the workpiece turns with the spindle.

The spindle (the C axis when positioning) turns the part right-handed about +Z; the tool
axis is +x (radial, from the tip back to the turret). Without a y axis the tool stays in
the plane y = 0 of the spindle, so the spindle turns a point onto it (either way round,
whichever keeps x within its travel).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from cnc_msgs_py.machine import SPINDLE
from cnc_msgs_py.units import to_deg, to_mm

from .chain import ANGLE_TOL, LENGTH_TOL, LIMIT_SLACK, SINGULAR, Chain, Unreachable, choose, reach_reason, rot


class Lathe(Chain):
    joints = ("x", "z", SPINDLE)

    def forward(self, xyz: np.ndarray, q: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        turn = -q[SPINDLE]
        tips = rot(2, turn, xyz - [self.length, 0.0, 0.0])
        axes = rot(2, turn, np.tile([1.0, 0.0, 0.0], (len(xyz), 1)))
        return tips, axes

    def inverse(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float]
                ) -> dict[str, np.ndarray]:
        """The spindle turns the tool axis onto +x if one is given, otherwise see _free_turn."""
        n = len(tips)
        if axes is not None:
            off = np.arcsin(np.clip(np.abs(axes[:, 2]), 0.0, 1.0))
            if (off > ANGLE_TOL).any():
                i = int(np.argmax(off > ANGLE_TOL))
                raise Unreachable(i, f"needs the tool axis {to_deg(off[i]):.3f} deg out of the plane "
                                     "normal to the spindle; the lathe's tool axis is radial (+x)")
            turn = -np.arctan2(axes[:, 1], axes[:, 0])
            angle, singular, feasible = np.stack([turn, turn]), np.zeros(n, dtype=bool), np.ones((2, n), dtype=bool)
        else:
            angle, singular, feasible = self._free_turn(tips)
        _, turn = choose(np.zeros((2, n)), angle, feasible, singular, 0.0, previous.get(SPINDLE, 0.0))
        q = rot(2, turn, tips)
        joints = {"x": q[:, 0] + self.length, "y": q[:, 1], "z": q[:, 2], SPINDLE: turn}
        self._onto_plane(joints)
        return {j: joints[j] for j in self.joints}

    def _free_turn(self, tips: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Candidate spindle angles (2, n) that turn each tip onto +x or -x, which poses
        leave the spindle free (on its axis) and which candidates keep x within travel."""
        radius = np.hypot(tips[:, 0], tips[:, 1])
        turn = -np.arctan2(tips[:, 1], tips[:, 0])
        angle, singular = np.stack([turn, turn + np.pi]), radius < SINGULAR
        x = self.machine.axes["x"]
        feasible = np.ones((2, len(tips)), dtype=bool)
        for k, sign in enumerate((1.0, -1.0)):
            reach = sign * radius + self.length
            feasible[k] = (reach >= x.min - LIMIT_SLACK) & (reach <= x.max + LIMIT_SLACK)
        feasible |= singular
        stuck = ~feasible.any(axis=0)
        if stuck.any():
            i = int(np.argmax(stuck))
            raise Unreachable(i, reach_reason(x, radius[i] + self.length))
        return angle, singular, feasible

    def _onto_plane(self, joints: dict[str, np.ndarray]) -> None:
        """Without a y axis the tip must lie in the tool's plane: drop y, which must be 0."""
        off = np.abs(joints.pop("y"))
        if (off > LENGTH_TOL).any():
            i = int(np.argmax(off > LENGTH_TOL))
            raise Unreachable(i, f"needs axis y at {to_mm(off[i]):.3f} mm off the tool's plane; "
                                 "the lathe has no y axis")
