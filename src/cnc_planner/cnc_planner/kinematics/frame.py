"""The workpiece setup (program -> table coordinates, or a named work offset) and the tool data.

They are the same on every layout, so the Kinematics API applies them around a layout's chain.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import yaml

from cnc_msgs_py.machine import machine_dirs
from cnc_msgs_py.schema import JobError, List, Num, Obj
from cnc_msgs_py.yaml_text import load_yaml

WORK_OFFSET = Obj({
    "origin": List(Num("mm"), length=3),
    "rotation_deg": List(Num("deg"), length=3, default=[0.0, 0.0, 0.0]),
})


class KinematicsError(JobError):
    """A pose the machine cannot take (or a bad setup); names the field and the axis."""


def rotation(angles: list[float]) -> np.ndarray:
    """Rotation matrix of the setup: about X, then Y, then Z (angles in rad)."""
    ax, ay, az = angles
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


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
        doc = load_yaml(path.read_text())
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
