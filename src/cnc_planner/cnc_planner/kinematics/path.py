"""The path job's sampler: straight program lines with a turning tool axis, cut into
waypoints that linear joint interpolation follows within the chord tolerance."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cnc_msgs_py.units import to_mm

from .chain import SINGULAR, Unreachable, check_travel, unit
from .frame import KinematicsError

if TYPE_CHECKING:
    from . import Kinematics

CHECK_FRACTIONS = (0.25, 0.5, 0.75)  # where each sampled segment's chord error is measured
MAX_SAMPLES = 2_000_000
MIN_STEP = 2.0 ** -40  # of a program segment: finer halving cannot help, the axis path has a kink


@dataclass(frozen=True, eq=False)
class SampledPath:
    """Waypoints of a path in axis space, fine enough that moving the axes linearly
    between them keeps the tip within the chord tolerance of the programmed lines.

    ``param`` is the position along the program (k + u: fraction u of the way from
    point k to k + 1); ``lengths`` the tip travel of each segment (m, program
    coordinates); ``durations`` each segment's time at the feed, longer where an axis
    would otherwise exceed its max_velocity (rotary-only segments included).
    """

    joints: dict[str, np.ndarray]
    param: np.ndarray
    tips: np.ndarray
    tool_axes: np.ndarray
    lengths: np.ndarray
    durations: np.ndarray


def sample_path(kin: Kinematics, points: np.ndarray, tool_axes: np.ndarray | None, feed: float,
                chord_tolerance: float, previous: dict[str, float] | None = None,
                field: str = "path") -> SampledPath:
    """Kinematics.sample_path (documented there)."""
    pts = np.asarray(points, float).reshape(-1, 3)
    directions = None
    if tool_axes is not None:
        directions, zero = unit(np.asarray(tool_axes, float).reshape(-1, 3))
        if zero.any():
            raise KinematicsError(f"{field}.tool_axis[{int(np.argmax(zero))}]", "has no direction (zero length)")
        opposite = np.einsum("ij,ij->i", directions[:-1], directions[1:]) < -1.0 + 1e-12
        if opposite.any():
            raise KinematicsError(f"{field}.tool_axis[{int(np.argmax(opposite)) + 1}]",
                                  "turns 180 deg from the one before: the way between is undefined")
    n = len(pts)
    cuts = [0]
    if directions is not None and kin.chain.orients_tool:
        table_axes = directions @ kin.setup.rotation.T
        cuts += [i for i in range(1, n - 1) if np.hypot(*table_axes[i, :2]) < SINGULAR]
    cuts.append(n - 1)
    params, tips, joints = [], [], []
    before = previous or {}
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        param, tip, part = _sample_lines(kin, pts, directions, lo, hi, before, chord_tolerance, field)
        if joints:  # C turns at the vertical point between the parts; drop the repeated pose
            turn = kin.chain.turn_in_place(before, {j: v[0] for j, v in part.items()},
                                           kin.setup.to_table(tip[0][None]), chord_tolerance)
            try:
                check_travel(kin.machine, turn)
            except Unreachable as err:
                raise KinematicsError(f"{field}.points[{lo}]", "turning C at the vertical tool " + err.reason) from err
            part = {j: np.concatenate([turn[j], part[j][1:]]) for j in part}
            param = np.concatenate([np.full(len(turn["c"]), param[0]), param[1:]])
            tip = np.concatenate([np.repeat(tip[:1], len(turn["c"]), axis=0), tip[1:]])
        params.append(param)
        tips.append(tip)
        joints.append(part)
        before = {j: float(v[-1]) for j, v in part.items()}
    joints = {j: np.concatenate([part[j] for part in joints]) for j in joints[0]}
    tips = np.concatenate(tips)
    lengths = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    slowest = np.max([np.abs(np.diff(v)) / kin.machine.axes[j].max_velocity for j, v in joints.items()], axis=0)
    _, tool = kin.fk_many(joints)
    return SampledPath(joints=joints, param=np.concatenate(params), tips=tips, tool_axes=tool,
                       lengths=lengths, durations=np.maximum(lengths / feed, slowest))


def _sample_lines(kin: Kinematics, pts: np.ndarray, directions: np.ndarray | None, lo: int, hi: int,
                  previous: dict[str, float], tolerance: float, field: str
                  ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Halve the segments from point lo to point hi until every chord is within tolerance."""
    n = len(pts)
    param = np.arange(lo, hi + 1, dtype=float)
    while True:
        tips, axes = _program_pose(pts, directions, param)
        try:
            joints = kin.solve(tips, axes, previous, check=True)
        except Unreachable as err:
            k = int(min(np.floor(param[err.index]), n - 1))
            on_line = "on the line to the next point " if param[err.index] != k else ""
            raise KinematicsError(f"{field}.points[{k}]", on_line + err.reason) from err
        seg = np.minimum(np.floor(param[:-1]), n - 2).astype(int)
        worst = np.zeros(len(seg))
        for fraction in CHECK_FRACTIONS:
            tip, _ = kin.fk_many({j: v[:-1] + fraction * (v[1:] - v[:-1]) for j, v in joints.items()})
            worst = np.maximum(worst, _distance_to_segment(tip, pts[seg], pts[seg + 1]))
        bad = worst > tolerance
        if not bad.any():
            return param, tips, joints
        narrow = bad & (np.diff(param) < MIN_STEP)
        if narrow.any():
            raise KinematicsError(f"{field}.points[{int(seg[np.argmax(narrow)])}]",
                                  "the line to the next point cannot be followed within the chord "
                                  "tolerance: the axis path kinks there")
        if len(param) + bad.sum() > MAX_SAMPLES:
            raise KinematicsError(f"{field}.chord_tolerance",
                                  f"{to_mm(tolerance):g} mm needs more than {MAX_SAMPLES} waypoints")
        param = np.sort(np.concatenate([param, 0.5 * (param[:-1][bad] + param[1:][bad])]))


def _program_pose(pts: np.ndarray, directions: np.ndarray | None, param: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray | None]:
    """Tip (linear) and tool axis (slerp) at path parameters k + u."""
    k = np.minimum(np.floor(param), len(pts) - 2).astype(int)
    u = (param - k)[:, None]
    tips = (1 - u) * pts[k] + u * pts[k + 1]  # exact at both ends
    if directions is None:
        return tips, None
    a, b = directions[k], directions[k + 1]
    omega = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))[:, None]
    small = omega < 1e-9
    sin = np.where(small, 1.0, np.sin(omega))
    slerp = (np.sin((1 - u) * omega) * a + np.sin(u * omega) * b) / sin
    return tips, unit(np.where(small, a + u * (b - a), slerp))[0]


def _distance_to_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point to the segment a-b (a point if a == b), rowwise."""
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    u = np.clip(np.einsum("ij,ij->i", points - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * d), axis=1)
