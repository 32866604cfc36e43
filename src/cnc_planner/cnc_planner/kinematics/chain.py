"""What every layout's kinematic chain shares: the forward/inverse contract, the error of
an unreachable pose, soft limits and the continuous choice between two joint solutions.

A chain works in *table* coordinates (see the package docstring); the Kinematics API
puts the workpiece setup around it. Layout modules subclass ``Chain``.
"""
from __future__ import annotations

from typing import ClassVar, Mapping

import numpy as np

from cnc_msgs_py.machine import Axis, Machine
from cnc_msgs_py.units import to_deg, to_mm

ANGLE_TOL = 1e-9  # rad: a tool axis this close to a fixed one (mill3, lathe) matches it
LENGTH_TOL = 1e-9  # m: a lathe tip this close to the tool's plane lies on it
SINGULAR = 1e-12  # sine of the tilt below which the rotary axis is undefined: keep it
LIMIT_SLACK = 1e-12  # rounding allowed at a soft limit
TWO_PI = 2.0 * np.pi
Z = np.array([0.0, 0.0, 1.0])


class Unreachable(Exception):
    """Pose ``index`` of an array cannot be reached; the API names the job field."""

    def __init__(self, index: int, reason: str) -> None:
        super().__init__(reason)
        self.index = index
        self.reason = reason


class Chain:
    """One machine layout: joint positions <-> spindle poses (tool tip, unit tool axis)
    in table coordinates, for a tool ``length`` from the tip to the spindle nose."""

    joints: ClassVar[tuple[str, ...]]
    orients_tool: ClassVar[bool] = False  # any tool axis the rotaries reach, program +z if none given

    def __init__(self, machine: Machine, length: float) -> None:
        self.machine = machine
        self.length = length
        self.pivot = np.array(machine.kinematics.pivot)
        self.pivot_length = machine.kinematics.pivot_length

    def forward(self, xyz: np.ndarray, q: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Tips (n, 3) and tool axes (n, 3) for linear axes ``xyz`` (n, 3) and the
        layout's joints ``q`` (each (n,))."""
        raise NotImplementedError

    def inverse(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float]
                ) -> dict[str, np.ndarray]:
        """Joint arrays (in ``joints`` order) for tips (n, 3) and unit tool axes (n, 3),
        or None for the layout's own; continuous from the ``previous`` joint positions.

        Raises:
            Unreachable: no joint solution for a pose (travel is checked by the caller).
        """
        raise NotImplementedError

    def turn_in_place(self, end: dict[str, float], start: dict[str, float], tip: np.ndarray,
                      tolerance: float) -> dict[str, np.ndarray]:
        """Joints that turn the azimuth from ``end`` to ``start`` under a vertical tool at
        table point ``tip`` (1, 3); only chains that orient the tool have a free azimuth."""
        raise NotImplementedError


def rot(axis: int, angle: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate each row of v (n, 3) right-handed about coordinate ``axis`` by ``angle`` (n,)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = ((1, 2), (2, 0), (0, 1))[axis]
    out = v.copy()
    out[:, i] = c * v[:, i] - s * v[:, j]
    out[:, j] = s * v[:, i] + c * v[:, j]
    return out


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles to [-pi, pi): the shortest way between two rotary positions."""
    return (angle + np.pi) % TWO_PI - np.pi


def unit(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows normalised to unit length, and the mask of rows too short to have a direction."""
    norm = np.linalg.norm(vectors, axis=1)
    zero = norm < 1e-12
    return vectors / np.where(zero, 1.0, norm)[:, None], zero


def choose(tilt: np.ndarray, angle: np.ndarray, feasible: np.ndarray, singular: np.ndarray,
           prev_tilt: float, prev_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Pick one of two candidate (tilt, angle) solutions per pose, continuously.

    Each pose takes the feasible candidate closest to the one chosen before it (equal
    cost: keep the branch). Singular poses keep the angle chosen before them; those
    that lead the run take the angle of the first regular pose after them instead, so a
    path that starts vertical does not turn C at its first step. The greedy chain is a
    composition of maps {0, 1} -> {0, 1}, evaluated without a Python loop: the state
    is the last constant map's value, flipped once per swap since. The angle is then
    unwound from ``prev_angle`` by the shortest step each time. Every pose must have
    a feasible candidate.
    """
    n = tilt.shape[1]
    idx = np.arange(n)
    last_free = np.maximum.accumulate(np.where(singular, -1, idx))
    ref = np.concatenate(([-1], last_free[:-1]))
    ref_tilt = np.where(idx > 0, tilt[:, idx - 1], prev_tilt)
    ref_angle = np.where(ref >= 0, angle[:, np.maximum(ref, 0)], prev_angle)
    cost = np.abs(tilt[None] - ref_tilt[:, None]) + np.abs(wrap(angle[None] - ref_angle[:, None]))
    cost = np.where(feasible[None], cost, np.inf)  # cost[j, k]: from branch j to candidate k
    stay = np.array([cost[0, 0] <= cost[0, 1], cost[1, 1] <= cost[1, 0]])
    nxt = np.where(stay, [[0], [1]], [[1], [0]])
    nxt[:, singular] = [[0], [1]]
    constant = nxt[0] == nxt[1]
    swaps = np.cumsum((nxt[0] == 1) & (nxt[1] == 0))
    last_const = np.maximum.accumulate(np.where(constant, idx, -1))
    at = np.maximum(last_const, 0)
    state = (np.where(last_const >= 0, nxt[0, at], 0) + swaps - np.where(last_const >= 0, swaps[at], 0)) % 2
    chosen_tilt = tilt[state, idx]
    chosen = angle[state, idx]
    lead = chosen[np.argmin(singular)] if not singular.all() else prev_angle
    chosen = np.where(singular, np.where(last_free >= 0, chosen[np.maximum(last_free, 0)], lead), chosen)
    approx = prev_angle + np.cumsum(wrap(np.diff(np.concatenate(([prev_angle], chosen)))))
    return chosen_tilt, chosen + TWO_PI * np.round((approx - chosen) / TWO_PI)


def within(axis: Axis, values: np.ndarray) -> np.ndarray:
    """Which positions lie within the soft limits (all of them without limits)."""
    if axis.min is None:
        return np.ones(np.shape(values), dtype=bool)
    return (values >= axis.min - LIMIT_SLACK) & (values <= axis.max + LIMIT_SLACK)


def excess(axis: Axis, value: float) -> float:
    """How far a position lies beyond the soft limits (0 inside or without limits)."""
    return 0.0 if axis.min is None else max(axis.min - value, value - axis.max, 0.0)


def reach_reason(axis: Axis, value: float) -> str:
    """``needs axis b at 112.0 deg, beyond its limit 90 deg`` (more digits if it rounds onto the limit)."""
    limit = axis.max if value > axis.max else axis.min
    symbol, convert, digits = ("mm", to_mm, 3) if axis.type == "linear" else ("deg", to_deg, 1)
    if round(convert(value), digits) == round(convert(limit), digits):
        digits += 3
    return (f"needs axis {axis.name} at {convert(value):.{digits}f} {symbol}, "
            f"beyond its limit {convert(limit):g} {symbol}")


def check_travel(machine: Machine, joints: dict[str, np.ndarray]) -> None:
    """Raise Unreachable at the first pose with a joint beyond its soft limits."""
    first = None
    for name, values in joints.items():
        axis = machine.axes[name]
        bad = ~within(axis, values)
        if bad.any():
            i = int(np.argmax(bad))
            if first is None or i < first[0]:
                first = (i, axis, float(values[i]))
    if first is not None:
        raise Unreachable(first[0], reach_reason(first[1], first[2]))
