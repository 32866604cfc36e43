"""Program path -> spindle path -> axis path, for every machine layout (design, method 5).

Frames, all right-handed, lengths in m, angles in rad:

- *program* coordinates: the job's (workpiece) frame.
- *table* coordinates: fixed to what carries the workpiece (table, trunnion, chuck);
  they equal machine coordinates while every rotary joint is at 0. The setup places
  the program there: ``table = R @ program + origin`` with R the rotation about X,
  then Y, then Z (``R = Rz @ Ry @ Rx``), or a named work offset of the same form
  (``frame``).
- a *spindle pose* is the tool tip position and the tool axis: the unit vector from
  the tip towards the spindle (+z for a vertical mill). The tool length runs along it
  from the tip to the spindle nose, and the linear axes read the spindle nose, so with
  tool length 0, a zero setup and rotaries at 0 the tip equals the linear axes.

Each layout is a module of its own with a forward/inverse pair in table coordinates
(as LinuxCNC keeps trivkins, xyzac-trt-kins, ...), found through ``CHAINS``: a new
layout is a new module and a line there. ``Kinematics`` puts the setup and the tool
around the layout's chain, checks travel and names the job field of a bad pose.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Mapping

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine, MachineError

from .chain import Z, Chain, Unreachable, check_travel, unit
from .frame import KinematicsError, Setup, Tool, load_work_offsets, make_setup, make_tool, rotation
from .head_table import HeadTable
from .lathe import Lathe
from .lathe_y import LatheY
from .mill3 import Mill3
from .path import SampledPath, sample_path
from .table_table import TableTable

CHAINS: dict[str, type[Chain]] = {
    "mill3": Mill3,
    "lathe": Lathe,
    "lathe_y": LatheY,
    "5ax_table_table": TableTable,
    "5ax_head_table": HeadTable,
}
LAYOUT_JOINTS = {layout: chain.joints for layout, chain in CHAINS.items()}

__all__ = ["CHAINS", "LAYOUT_JOINTS", "Kinematics", "KinematicsError", "SampledPath", "Setup", "Tool",
           "load_work_offsets", "rotation"]


class Kinematics:
    """The machine's kinematic chain: spindle poses in program coordinates <-> joints.

    ``setup`` and ``tool`` take a validated job's blocks (SI units) or Setup / Tool.
    """

    def __init__(self, machine: Machine, setup: Setup | SimpleNamespace | None = None,
                 tool: Tool | SimpleNamespace | None = None):
        if machine.layout not in CHAINS:
            raise MachineError(f"machine '{machine.name}': no kinematics for layout '{machine.layout}'")
        self.machine = machine
        self.layout = machine.layout
        self.joints = LAYOUT_JOINTS[machine.layout]
        missing = [j for j in self.joints if j not in machine.axes]
        if missing:
            raise MachineError(f"machine '{machine.name}': layout {self.layout} needs axis '{missing[0]}'")
        self.setup = make_setup(setup)
        self.tool = make_tool(tool)
        self.chain = CHAINS[machine.layout](machine, self.tool.length)

    # --- single points, as the move, drill and turn planners use them ----------------------

    def to_axes(self, point: dict[str, float], tool_axis: list[float] | None = None,
                previous: dict[str, float] | None = None) -> dict[str, float]:
        """Joint positions for a tip {x, y, z} (missing coordinates 0), all but the spindle.

        Travel is not checked here (the caller names the field); see ik_many.
        """
        tip = [[point.get("x", 0.0), point.get("y", 0.0), point.get("z", 0.0)]]
        try:
            joints = self.solve(np.array(tip), None if tool_axis is None else np.array([tool_axis], float),
                                previous or {}, check=False)
        except Unreachable as err:
            raise KinematicsError("", err.reason) from err
        return {j: float(v[0]) for j, v in joints.items() if j != SPINDLE}

    def to_program(self, axes: dict[str, float]) -> dict[str, float]:
        """The tip in program coordinates for joint positions (missing ones 0), linear names only."""
        tips, _ = self.fk_many({j: [v] for j, v in axes.items()})
        return {name: float(v) for name, v in zip("xyz", tips[0]) if name in self.machine.linear_axes}

    def tip_radius_z(self, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Program radius and z of the tip for lathe joint arrays x and z, what turned parts
        are judged in. The spindle is taken at 0: it turns the part, not the tip's radius."""
        tips, _ = self.fk_many({"x": x, "z": z})
        return np.hypot(tips[:, 0], tips[:, 1]), tips[:, 2]

    # --- arrays of poses -------------------------------------------------------------------

    def ik_many(self, tips: np.ndarray, axes: np.ndarray | None = None,
                previous: dict[str, float] | None = None, field: str = "points",
                check: bool = True) -> dict[str, np.ndarray]:
        """Joint arrays for n spindle poses (program coordinates), chosen continuously.

        Args:
            tips: (n, 3) tool tip positions, m.
            axes: (n, 3) tool axis vectors (normalised here), or None for the layout's
                natural one: +z of the table on mill3, +z of the program on 5-axis (a
                tilted setup tilts the tool with it), radial on the lathe.
            previous: joint positions before the first pose (default 0): continuity start.
            field: job field of the poses; errors name ``field[i]``.
            check: raise if a joint leaves its soft limits.

        Raises:
            KinematicsError: a pose is unreachable, naming the axis and the limit.
        """
        try:
            return self.solve(np.asarray(tips, float).reshape(-1, 3),
                              None if axes is None else np.asarray(axes, float).reshape(-1, 3),
                              previous or {}, check)
        except Unreachable as err:
            raise KinematicsError(f"{field}[{err.index}]", err.reason) from err

    def fk_many(self, joints: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Tool tips (n, 3) and unit tool axes (n, 3) in program coordinates; missing joints 0."""
        values = np.broadcast_arrays(*[np.atleast_1d(np.asarray(v, float)) for v in joints.values()])
        q = dict(zip(joints, values))
        n = len(values[0]) if values else 1
        get = lambda j: q.get(j, np.zeros(n))  # noqa: E731
        xyz = np.stack([get("x"), get("y"), get("z")], axis=1)
        tips, axes = self.chain.forward(xyz, {j: get(j) for j in self.joints if j not in ("x", "y", "z")})
        return self.setup.to_program(tips), axes @ self.setup.rotation

    def solve(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float],
              check: bool) -> dict[str, np.ndarray]:
        """ik_many without naming the field: raises Unreachable with the index of the pose,
        for the caller (ik_many, to_axes, the path sampler) to name it."""
        tips_t = self.setup.to_table(tips)
        if axes is not None:
            axes, zero = unit(axes)
            if zero.any():
                raise Unreachable(int(np.argmax(zero)), "the tool axis has no direction (zero length)")
            axes = axes @ self.setup.rotation.T
        elif self.chain.orients_tool:
            axes = np.tile(self.setup.rotation @ Z, (len(tips_t), 1))
        joints = self.chain.inverse(tips_t, axes, previous)
        if check:
            check_travel(self.machine, joints)
        return joints

    # --- the path job ----------------------------------------------------------------------

    def sample_path(self, points: np.ndarray, tool_axes: np.ndarray | None, feed: float,
                    chord_tolerance: float, previous: dict[str, float] | None = None,
                    field: str = "path") -> SampledPath:
        """Straight lines through program points, the tool axis turning by slerp, sampled
        so that linear interpolation of the joints keeps the tip (by forward kinematics)
        within ``chord_tolerance`` of each line: segments are halved where it does not.

        At an inner point with a vertical (singular) tool axis the azimuth may change:
        C turns there while the tip stands still, in steps that keep the tip within the
        tolerance too.

        Raises:
            KinematicsError: a pose on the way is unreachable, or the tolerance needs
                more than MAX_SAMPLES waypoints.
        """
        return sample_path(self, points, tool_axes, feed, chord_tolerance, previous, field)
