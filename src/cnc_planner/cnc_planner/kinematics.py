"""Program path -> spindle path -> axis path, for every machine layout (design, method 5).

Frames, all right-handed, lengths in m, angles in rad:

- *program* coordinates: the job's (workpiece) frame.
- *table* coordinates: fixed to what carries the workpiece (table, trunnion, chuck);
  they equal machine coordinates while every rotary joint is at 0. The setup places
  the program there: ``table = R @ program + origin`` with R the rotation about X,
  then Y, then Z (``R = Rz @ Ry @ Rx``), or a named work offset of the same form.
- a *spindle pose* is the tool tip position and the tool axis: the unit vector from
  the tip towards the spindle (+z for a vertical mill). The tool length runs along it
  from the tip to the spindle nose, and the linear axes read the spindle nose, so with
  tool length 0, a zero setup and rotaries at 0 the tip equals the linear axes.

Joints per layout (``LAYOUT_JOINTS``):

- ``mill3``: x, y, z. The tool axis is +z of the table.
- ``lathe``: x (radius), z, spindle; ``lathe_y`` adds y. The workpiece turns with the
  spindle (its C axis when positioning) right-handed about +Z; the tool axis is +x
  (radial, from the tip back to the turret).
- ``5ax_table_table``: x, y, z, a, c. A turns the trunnion right-handed about +X, the
  C table on it turns right-handed about +Z, both about lines through ``pivot``
  (machine.kinematics); the tool axis is +z of the machine.
- ``5ax_head_table``: x, y, z, b, c. B swivels the head right-handed about +Y (B > 0
  leans the tool towards +X) about an axis ``pivot_length`` above the spindle nose;
  C turns the table right-handed about +Z through ``pivot``.

A 5-axis tool axis has two joint solutions, (tilt, c) and (-tilt, c + pi); each pose
takes the one within the limits closest to the pose before it, C is unwound to the
shortest way, and on the singular vertical axis C keeps its previous value (a run of
vertical poses at the start of an array takes the C of the first tilted pose after it).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Mapping

import numpy as np
import yaml

from cnc_msgs_py.machine import SPINDLE, Axis, Machine, MachineError, machine_dirs
from cnc_msgs_py.schema import JobError, List, Num, Obj
from cnc_msgs_py.units import to_deg, to_mm

LAYOUT_JOINTS = {
    "mill3": ("x", "y", "z"),
    "lathe": ("x", "z", SPINDLE),
    "lathe_y": ("x", "y", "z", SPINDLE),
    "5ax_table_table": ("x", "y", "z", "a", "c"),
    "5ax_head_table": ("x", "y", "z", "b", "c"),
}
TILT_JOINT = {"5ax_table_table": "a", "5ax_head_table": "b"}

ANGLE_TOL = 1e-9  # rad: a tool axis this close to a fixed one (mill3, lathe) matches it
LENGTH_TOL = 1e-9  # m: a lathe tip this close to the tool's plane lies on it
SINGULAR = 1e-12  # sine of the tilt below which the rotary axis is undefined: keep it
LIMIT_SLACK = 1e-12  # rounding allowed at a soft limit
CHECK_FRACTIONS = (0.25, 0.5, 0.75)  # where each sampled segment's chord error is measured
MAX_SAMPLES = 2_000_000
MIN_STEP = 2.0 ** -40  # of a program segment: finer halving cannot help, the axis path has a kink
TWO_PI = 2.0 * np.pi
Z = np.array([0.0, 0.0, 1.0])

WORK_OFFSET = Obj({
    "origin": List(Num("mm"), length=3),
    "rotation_deg": List(Num("deg"), length=3, default=[0.0, 0.0, 0.0]),
})


class KinematicsError(JobError):
    """A pose the machine cannot take (or a bad setup); names the field and the axis."""


class _Unreachable(Exception):
    """Internal: pose ``index`` of an array cannot be reached, for the caller to name."""

    def __init__(self, index: int, reason: str) -> None:
        super().__init__(reason)
        self.index = index
        self.reason = reason


def rotation(angles: list[float]) -> np.ndarray:
    """Rotation matrix of the setup: about X, then Y, then Z (angles in rad)."""
    ax, ay, az = angles
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _rot(axis: int, angle: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate each row of v (n, 3) right-handed about coordinate ``axis`` by ``angle`` (n,)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = ((1, 2), (2, 0), (0, 1))[axis]
    out = v.copy()
    out[:, i] = c * v[:, i] - s * v[:, j]
    out[:, j] = s * v[:, i] + c * v[:, j]
    return out


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles to [-pi, pi): the shortest way between two rotary positions."""
    return (angle + np.pi) % TWO_PI - np.pi


def _unit(vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows normalised to unit length, and the mask of rows too short to have a direction."""
    norm = np.linalg.norm(vectors, axis=1)
    zero = norm < 1e-12
    return vectors / np.where(zero, 1.0, norm)[:, None], zero


# --- workpiece setup and tool data ---------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Setup:
    """Where the program sits on the table: table = rotation @ program + origin (m)."""

    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def to_table(self, points: np.ndarray) -> np.ndarray:
        return points @ self.rotation.T + self.origin

    def to_program(self, points: np.ndarray) -> np.ndarray:
        return (points - self.origin) @ self.rotation


@dataclass(frozen=True)
class Tool:
    """Tool data (m). Length: tip to spindle nose along the tool axis (compensated here).
    Radius and nose radius are the cutter and insert radii, for the path generators that
    offset a contour; the program point is the tool's control point (imaginary tip)."""

    length: float = 0.0
    radius: float = 0.0
    nose_radius: float = 0.0


def work_offsets_path() -> Path:
    """``work_offsets.yaml`` beside the machine descriptions (config/), first match wins."""
    for directory in machine_dirs():
        candidate = directory.parent / "work_offsets.yaml"
        if candidate.is_file():
            return candidate
    raise KinematicsError("setup.work_offset", f"no work_offsets.yaml beside {[str(d) for d in machine_dirs()]}")


def load_work_offsets(path: str | Path | None = None) -> dict[str, Setup]:
    """Named work offsets (mm, deg in the file; converted by the job schema's units)."""
    path = Path(path) if path is not None else work_offsets_path()
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise KinematicsError("setup.work_offset", f"cannot read {path}: {err}") from err
    if not isinstance(doc, dict):
        raise KinematicsError("setup.work_offset", f"{path} must hold a mapping of names to offsets")
    offsets = {}
    for name, spec in doc.items():
        try:
            offset = WORK_OFFSET.check(spec, str(name))
        except JobError as err:
            raise KinematicsError("setup.work_offset", f"{path}: {err}") from err
        offsets[str(name)] = Setup(np.array(offset.origin), rotation(offset.rotation_deg))
    return offsets


def make_setup(spec: Setup | SimpleNamespace | None) -> Setup:
    """A Setup from a validated job's ``setup`` (SI units), which may name a work offset."""
    if spec is None or isinstance(spec, Setup):
        return spec or Setup()
    origin = np.zeros(3) if getattr(spec, "origin", None) is None else np.asarray(spec.origin, dtype=float)
    angles = [0.0, 0.0, 0.0] if getattr(spec, "rotation_deg", None) is None else spec.rotation_deg
    name = getattr(spec, "work_offset", None)
    if name is None:
        return Setup(origin, rotation(angles))
    if np.any(origin) or np.any(angles):
        raise KinematicsError("setup.work_offset", "names a work offset: leave origin and rotation_deg out")
    path = work_offsets_path()
    offsets = load_work_offsets(path)
    if name not in offsets:
        raise KinematicsError("setup.work_offset", f"no work offset '{name}' in {path} (known: {', '.join(offsets)})")
    return offsets[name]


def make_tool(spec: Tool | SimpleNamespace | None) -> Tool:
    """Tool data from a validated job's ``tool`` (SI units; diameter becomes radius)."""
    if spec is None or isinstance(spec, Tool):
        return spec or Tool()
    diameter = getattr(spec, "diameter", None)
    return Tool(length=spec.length, radius=0.0 if diameter is None else diameter / 2.0,
                nose_radius=getattr(spec, "nose_radius", None) or 0.0)


# --- the sampled path ----------------------------------------------------------------------

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


def _choose(tilt: np.ndarray, angle: np.ndarray, feasible: np.ndarray, singular: np.ndarray,
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
    cost = np.abs(tilt[None] - ref_tilt[:, None]) + np.abs(_wrap(angle[None] - ref_angle[:, None]))
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
    approx = prev_angle + np.cumsum(_wrap(np.diff(np.concatenate(([prev_angle], chosen)))))
    return chosen_tilt, chosen + TWO_PI * np.round((approx - chosen) / TWO_PI)


def _excess(axis: Axis, value: float) -> float:
    """How far a position lies beyond the soft limits (0 inside or without limits)."""
    return 0.0 if axis.min is None else max(axis.min - value, value - axis.max, 0.0)


def _reach_reason(axis: Axis, value: float) -> str:
    """``needs axis b at 112.0 deg, beyond its limit 90 deg`` (more digits if it rounds onto the limit)."""
    limit = axis.max if value > axis.max else axis.min
    unit, convert, digits = ("mm", to_mm, 3) if axis.type == "linear" else ("deg", to_deg, 1)
    if round(convert(value), digits) == round(convert(limit), digits):
        digits += 3
    return f"needs axis {axis.name} at {convert(value):.{digits}f} {unit}, beyond its limit {convert(limit):g} {unit}"


class Kinematics:
    """The machine's kinematic chain: spindle poses in program coordinates <-> joints.

    ``setup`` and ``tool`` take a validated job's blocks (SI units) or Setup / Tool.
    """

    def __init__(self, machine: Machine, setup: Setup | SimpleNamespace | None = None,
                 tool: Tool | SimpleNamespace | None = None):
        if machine.layout not in LAYOUT_JOINTS:
            raise MachineError(f"machine '{machine.name}': no kinematics for layout '{machine.layout}'")
        self.machine = machine
        self.layout = machine.layout
        self.joints = LAYOUT_JOINTS[machine.layout]
        missing = [j for j in self.joints if j not in machine.axes]
        if missing:
            raise MachineError(f"machine '{machine.name}': layout {self.layout} needs axis '{missing[0]}'")
        self.setup = make_setup(setup)
        self.tool = make_tool(tool)
        self.pivot = np.array(machine.kinematics.pivot)
        self.pivot_length = machine.kinematics.pivot_length

    # --- single points, as the move, drill and turn planners use them ----------------------

    def to_axes(self, point: dict[str, float], tool_axis: list[float] | None = None,
                previous: dict[str, float] | None = None) -> dict[str, float]:
        """Joint positions for a tip {x, y, z} (missing coordinates 0), all but the spindle.

        Travel is not checked here (the caller names the field); see ik_many.
        """
        tip = [[point.get("x", 0.0), point.get("y", 0.0), point.get("z", 0.0)]]
        try:
            joints = self._ik(np.array(tip), None if tool_axis is None else np.array([tool_axis], float),
                              previous or {}, check=False)
        except _Unreachable as err:
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
            return self._ik(np.asarray(tips, float).reshape(-1, 3),
                            None if axes is None else np.asarray(axes, float).reshape(-1, 3),
                            previous or {}, check)
        except _Unreachable as err:
            raise KinematicsError(f"{field}[{err.index}]", err.reason) from err

    def fk_many(self, joints: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Tool tips (n, 3) and unit tool axes (n, 3) in program coordinates; missing joints 0."""
        values = np.broadcast_arrays(*[np.atleast_1d(np.asarray(v, float)) for v in joints.values()])
        q = dict(zip(joints, values))
        n = len(values[0]) if values else 1
        get = lambda j: q.get(j, np.zeros(n))  # noqa: E731
        xyz = np.stack([get("x"), get("y"), get("z")], axis=1)
        length = self.tool.length
        if self.layout == "mill3":
            tips, axes = xyz - length * Z, np.tile(Z, (n, 1))
        elif self.layout in ("lathe", "lathe_y"):
            turn = -get(SPINDLE)
            tips = _rot(2, turn, xyz - [length, 0.0, 0.0])
            axes = _rot(2, turn, np.tile([1.0, 0.0, 0.0], (n, 1)))
        elif self.layout == "5ax_table_table":
            a, c = get("a"), get("c")
            tips = self.pivot + _rot(2, -c, _rot(0, -a, xyz - length * Z - self.pivot))
            axes = _rot(2, -c, _rot(0, -a, np.tile(Z, (n, 1))))
        else:
            b, c = get("b"), get("c")
            head = np.stack([np.sin(b), np.zeros(n), np.cos(b)], axis=1)
            nose = xyz + self.pivot_length * Z - (self.pivot_length + length) * head
            tips = self.pivot + _rot(2, -c, nose - self.pivot)
            axes = _rot(2, -c, head)
        return self.setup.to_program(tips), axes @ self.setup.rotation

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
        pts = np.asarray(points, float).reshape(-1, 3)
        unit = None
        if tool_axes is not None:
            unit, zero = _unit(np.asarray(tool_axes, float).reshape(-1, 3))
            if zero.any():
                raise KinematicsError(f"{field}.tool_axis[{int(np.argmax(zero))}]", "has no direction (zero length)")
            opposite = np.einsum("ij,ij->i", unit[:-1], unit[1:]) < -1.0 + 1e-12
            if opposite.any():
                raise KinematicsError(f"{field}.tool_axis[{int(np.argmax(opposite)) + 1}]",
                                      "turns 180 deg from the one before: the way between is undefined")
        n = len(pts)
        cuts = [0]
        if unit is not None and self.layout in TILT_JOINT:
            table_axes = unit @ self.setup.rotation.T
            cuts += [i for i in range(1, n - 1) if np.hypot(*table_axes[i, :2]) < SINGULAR]
        cuts.append(n - 1)
        params, tips, joints = [], [], []
        before = previous or {}
        for lo, hi in zip(cuts[:-1], cuts[1:]):
            param, tip, part = self._sample_lines(pts, unit, lo, hi, before, chord_tolerance, field)
            if joints:  # C turns at the vertical point between the parts; drop the repeated pose
                turn = self._turn_in_place(before, {j: v[0] for j, v in part.items()}, tip[0], chord_tolerance)
                try:
                    self._check(turn)
                except _Unreachable as err:
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
        slowest = np.max([np.abs(np.diff(v)) / self.machine.axes[j].max_velocity for j, v in joints.items()], axis=0)
        _, tool = self.fk_many(joints)
        return SampledPath(joints=joints, param=np.concatenate(params), tips=tips, tool_axes=tool,
                           lengths=lengths, durations=np.maximum(lengths / feed, slowest))

    def _sample_lines(self, pts: np.ndarray, unit: np.ndarray | None, lo: int, hi: int,
                      previous: dict[str, float], tolerance: float, field: str
                      ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Halve the segments from point lo to point hi until every chord is within tolerance."""
        n = len(pts)
        param = np.arange(lo, hi + 1, dtype=float)
        while True:
            tips, axes = self._program_pose(pts, unit, param)
            try:
                joints = self._ik(tips, axes, previous, check=True)
            except _Unreachable as err:
                k = int(min(np.floor(param[err.index]), n - 1))
                on_line = "on the line to the next point " if param[err.index] != k else ""
                raise KinematicsError(f"{field}.points[{k}]", on_line + err.reason) from err
            seg = np.minimum(np.floor(param[:-1]), n - 2).astype(int)
            worst = np.zeros(len(seg))
            for fraction in CHECK_FRACTIONS:
                tip, _ = self.fk_many({j: v[:-1] + fraction * (v[1:] - v[:-1]) for j, v in joints.items()})
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

    def _turn_in_place(self, end: dict[str, float], start: dict[str, float], tip: np.ndarray,
                       tolerance: float) -> dict[str, np.ndarray]:
        """Joints that turn C from ``end`` to ``start`` with the vertical tool's tip at ``tip``
        (program), in steps whose chord sagitta r (1 - cos(step / 2)) stays within tolerance."""
        tip_t = self.setup.to_table(tip[None])
        radius = float(np.hypot(*(tip_t[0, :2] - self.pivot[:2])))
        step = 2.0 * np.arccos(max(1.0 - 0.9 * tolerance / radius, -1.0)) if radius > 0 else np.pi
        count = max(1, int(np.ceil(abs(start["c"] - end["c"]) / min(step, np.pi))))
        c = end["c"] + (start["c"] - end["c"]) * np.arange(1, count + 1) / count
        tilt_joint = TILT_JOINT[self.layout]
        tilt = np.full(count, start[tilt_joint])
        xyz = self._place(np.repeat(tip_t, count, axis=0), tilt, c)
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], tilt_joint: tilt, "c": c}

    # --- internals -------------------------------------------------------------------------

    @staticmethod
    def _program_pose(pts: np.ndarray, unit: np.ndarray | None, param: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray | None]:
        """Tip (linear) and tool axis (slerp) at path parameters k + u."""
        k = np.minimum(np.floor(param), len(pts) - 2).astype(int)
        u = (param - k)[:, None]
        tips = (1 - u) * pts[k] + u * pts[k + 1]  # exact at both ends
        if unit is None:
            return tips, None
        a, b = unit[k], unit[k + 1]
        omega = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))[:, None]
        small = omega < 1e-9
        sin = np.where(small, 1.0, np.sin(omega))
        slerp = (np.sin((1 - u) * omega) * a + np.sin(u * omega) * b) / sin
        return tips, _unit(np.where(small, a + u * (b - a), slerp))[0]

    def _ik(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float],
            check: bool) -> dict[str, np.ndarray]:
        tips_t = self.setup.to_table(tips)
        if axes is not None:
            axes, zero = _unit(axes)
            if zero.any():
                raise _Unreachable(int(np.argmax(zero)), "the tool axis has no direction (zero length)")
            axes = axes @ self.setup.rotation.T
        if self.layout == "mill3":
            joints = self._ik_mill(tips_t, axes)
        elif self.layout in ("lathe", "lathe_y"):
            joints = self._ik_lathe(tips_t, axes, previous)
        else:
            if axes is None:
                axes = np.tile(self.setup.rotation @ Z, (len(tips_t), 1))
            joints = self._ik_5ax(tips_t, axes, previous)
        if check:
            self._check(joints)
        return joints

    def _ik_mill(self, tips: np.ndarray, axes: np.ndarray | None) -> dict[str, np.ndarray]:
        if axes is not None:
            tilt = np.arctan2(np.hypot(axes[:, 0], axes[:, 1]), axes[:, 2])
            if (tilt > ANGLE_TOL).any():
                i = int(np.argmax(tilt > ANGLE_TOL))
                raise _Unreachable(i, f"needs the tool tilted {to_deg(tilt[i]):.3f} deg from Z; "
                                      f"layout {self.layout} cannot tilt the tool")
        xyz = tips + self.tool.length * Z
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}

    def _ik_lathe(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float]
                  ) -> dict[str, np.ndarray]:
        """The spindle turns the tip onto the tool's plane (lathe) or the tool axis onto +x."""
        n = len(tips)
        length = self.tool.length
        feasible = np.ones((2, n), dtype=bool)
        if axes is not None:
            off = np.arcsin(np.clip(np.abs(axes[:, 2]), 0.0, 1.0))
            if (off > ANGLE_TOL).any():
                i = int(np.argmax(off > ANGLE_TOL))
                raise _Unreachable(i, f"needs the tool axis {to_deg(off[i]):.3f} deg out of the plane "
                                      "normal to the spindle; the lathe's tool axis is radial (+x)")
            turn = -np.arctan2(axes[:, 1], axes[:, 0])
            angle, singular = np.stack([turn, turn]), np.zeros(n, dtype=bool)
        elif self.layout == "lathe":
            radius = np.hypot(tips[:, 0], tips[:, 1])
            turn = -np.arctan2(tips[:, 1], tips[:, 0])
            angle, singular = np.stack([turn, turn + np.pi]), radius < SINGULAR
            x = self.machine.axes["x"]
            for k, sign in enumerate((1.0, -1.0)):
                feasible[k] = (sign * radius + length >= x.min - LIMIT_SLACK) & (sign * radius + length <= x.max + LIMIT_SLACK)
            feasible |= singular
            stuck = ~feasible.any(axis=0)
            if stuck.any():
                i = int(np.argmax(stuck))
                raise _Unreachable(i, _reach_reason(x, radius[i] + length))
        else:
            angle, singular = np.zeros((2, n)), np.ones(n, dtype=bool)
        _, turn = _choose(np.zeros((2, n)), angle, feasible, singular, 0.0, previous.get(SPINDLE, 0.0))
        q = _rot(2, turn, tips)
        joints = {"x": q[:, 0] + length, "y": q[:, 1], "z": q[:, 2], SPINDLE: turn}
        if self.layout == "lathe":
            off = np.abs(joints.pop("y"))
            if (off > LENGTH_TOL).any():
                i = int(np.argmax(off > LENGTH_TOL))
                raise _Unreachable(i, f"needs axis y at {to_mm(off[i]):.3f} mm off the tool's plane; "
                                      "the lathe has no y axis")
        return {j: joints[j] for j in self.joints}

    def _place(self, tips: np.ndarray, tilt: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Linear axes (n, 3) that put the tool tip on table point ``tips`` at rotaries (tilt, c)."""
        if self.layout == "5ax_table_table":
            return self.pivot + _rot(0, tilt, _rot(2, c, tips - self.pivot)) + self.tool.length * Z
        head = np.stack([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)], axis=1)
        tip = self.pivot + _rot(2, c, tips - self.pivot)
        return tip - self.pivot_length * Z + (self.pivot_length + self.tool.length) * head

    def _ik_5ax(self, tips: np.ndarray, axes: np.ndarray, previous: dict[str, float]) -> dict[str, np.ndarray]:
        """Table-table: axis = (sin a sin c, sin a cos c, cos a); head-table: axis =
        (cos c sin b, -sin c sin b, cos b), both in table coordinates."""
        tilt_joint = TILT_JOINT[self.layout]
        kx, ky, kz = axes.T
        spread = np.hypot(kx, ky)
        tilt1 = np.arctan2(spread, kz)
        c1 = np.arctan2(kx, ky) if self.layout == "5ax_table_table" else np.arctan2(-ky, kx)
        singular = spread < SINGULAR
        tilt = np.stack([tilt1, np.where(singular, tilt1, -tilt1)])
        angle = np.stack([c1, c1 + np.pi])
        tilt_axis = self.machine.axes[tilt_joint]
        feasible = np.ones((2, len(tips)), dtype=bool)
        places = [self._place(tips, tilt[k], angle[k]) for k in (0, 1)]
        for k in (0, 1):
            feasible[k] = self._within(tilt_axis, tilt[k])
            for i, name in enumerate("xyz"):
                feasible[k] &= singular | self._within(self.machine.axes[name], places[k][:, i])
        stuck = ~feasible.any(axis=0)
        if stuck.any():
            i = int(np.argmax(stuck))
            k = int(np.argmin([_excess(tilt_axis, t) for t in tilt[:, i]]))
            bad = [(tilt_axis, tilt[k, i])] + [(self.machine.axes[a], places[k][i, j]) for j, a in enumerate("xyz")]
            raise _Unreachable(i, next(_reach_reason(ax, v) for ax, v in bad if _excess(ax, v) > LIMIT_SLACK))
        tilt, c = _choose(tilt, angle, feasible, singular, previous.get(tilt_joint, 0.0), previous.get("c", 0.0))
        c = self._fit_turns(self.machine.axes["c"], c)
        xyz = self._place(tips, tilt, c)
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], tilt_joint: tilt, "c": c}

    @staticmethod
    def _within(axis: Axis, values: np.ndarray) -> np.ndarray:
        if axis.min is None:
            return np.ones(np.shape(values), dtype=bool)
        return (values >= axis.min - LIMIT_SLACK) & (values <= axis.max + LIMIT_SLACK)

    def _fit_turns(self, axis: Axis, c: np.ndarray) -> np.ndarray:
        """A C axis with end stops: shift the whole unwound run by whole turns if that fits it."""
        if self._within(axis, c).all():
            return c
        for turns in (1, -1, 2, -2):
            if self._within(axis, c + turns * TWO_PI).all():
                return c + turns * TWO_PI
        return c

    def _check(self, joints: dict[str, np.ndarray]) -> None:
        """Raise _Unreachable at the first pose with a joint beyond its soft limits."""
        first = None
        for name, values in joints.items():
            axis = self.machine.axes[name]
            bad = ~self._within(axis, values)
            if bad.any():
                i = int(np.argmax(bad))
                if first is None or i < first[0]:
                    first = (i, axis, float(values[i]))
        if first is not None:
            raise _Unreachable(first[0], _reach_reason(first[1], first[2]))


def _distance_to_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point to the segment a-b (a point if a == b), rowwise."""
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    u = np.clip(np.einsum("ij,ij->i", points - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * d), axis=1)
