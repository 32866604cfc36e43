"""Program (workpiece) coordinates to axis positions, for the machine's layout.

The workpiece setup places the program origin on the table (translation, then rotation
about X, Y, Z in that order); the tool length offsets the spindle nose above the tip
along the tool axis. On the lathe, program x is the radius and z runs along the spindle.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine


def rotation(angles: list[float]) -> np.ndarray:
    """Rotation matrix of the setup: about X, then Y, then Z (angles in rad)."""
    ax, ay, az = angles
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


class Kinematics:
    """Maps tool-tip points in program coordinates to axis positions (and back)."""

    def __init__(self, machine: Machine, setup: SimpleNamespace, tool: SimpleNamespace):
        self.machine = machine
        self.origin = np.asarray(setup.origin, dtype=float)
        self.rotation = rotation(setup.rotation_deg)
        self.tool_length = tool.length
        self.linear = machine.linear_axes

    def to_axes(self, point: dict[str, float]) -> dict[str, float]:
        """Axis positions for a program point {x, y, z} (missing coordinates are 0)."""
        p = np.array([point.get("x", 0.0), point.get("y", 0.0), point.get("z", 0.0)])
        table = self.rotation @ p + self.origin
        if self.machine.layout == "mill3":
            table = table + np.array([0.0, 0.0, self.tool_length])
        axes = dict(zip(("x", "y", "z"), table))
        return {name: float(axes[name]) for name in self.linear}

    def to_program(self, axes: dict[str, float]) -> dict[str, float]:
        """Inverse of to_axes: the tool tip in program coordinates (for analysis)."""
        table = np.array([axes.get("x", 0.0), axes.get("y", 0.0), axes.get("z", 0.0)])
        if self.machine.layout == "mill3":
            table = table - np.array([0.0, 0.0, self.tool_length])
        p = self.rotation.T @ (table - self.origin)
        return {name: float(v) for name, v in zip(("x", "y", "z"), p) if name in self.linear}
