"""Machine descriptions: axes, limits, kinematic layout and servo drive models.

One YAML file per machine in ``config/machines/`` (SI units) feeds both the planner
and the servo bridge, so no limit or joint name is written twice.

The optional ``kinematics:`` block holds the rotary geometry of the 5-axis layouts
(lengths in m, machine coordinates with every rotary axis at 0):

- ``pivot: [x, y, z]``: on ``5ax_table_table`` the point where the A axis (parallel
  to X) meets the C axis (parallel to Z); on ``5ax_head_table`` a point on the C
  table's axis (its z does not matter). Default [0, 0, 0].
- ``pivot_length``: on ``5ax_head_table`` the distance from the B swivel axis down to
  the spindle nose along the tool axis; the linear axes read the spindle nose
  position at B = 0. Default 0.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

from cnc_msgs_py.yaml_text import load_yaml

LAYOUTS = ("mill3", "lathe", "lathe_y", "5ax_table_table", "5ax_head_table")
AXIS_TYPES = ("linear", "rotary", "continuous")
SPINDLE = "spindle"
# Joint names on the topics, in this order whenever a machine has them.
JOINT_ORDER = ("x", "y", "z", "a", "b", "c", SPINDLE)


class MachineError(ValueError):
    """A machine description is missing or malformed."""


@dataclass(frozen=True)
class Axis:
    """One joint: its travel (None for continuous joints) and its kinematic limits."""

    name: str
    type: str
    min: float | None
    max: float | None
    max_velocity: float
    max_acceleration: float
    max_jerk: float

    def within_travel(self, position: float, tolerance: float = 0.0) -> bool:
        """Whether a position lies inside the soft limits."""
        if self.min is None or self.max is None:
            return True
        return self.min - tolerance <= position <= self.max + tolerance


@dataclass(frozen=True)
class Tolerance:
    """How far the real drive may differ from its description and the plan must still be
    safe: factor ranges [lo, hi] on kp, velocity_ff, accel_ff and velocity_lag, a range of
    transport delay added to the described one (s), and the most backlash and friction
    (m or rad, m/s or rad/s) the real axis may have beyond the described."""

    kp: tuple[float, float] = (0.7, 1.3)
    velocity_ff: tuple[float, float] = (0.95, 1.0)
    accel_ff: tuple[float, float] = (1.0, 1.0)
    velocity_lag: tuple[float, float] = (1.0, 3.0)
    delay: tuple[float, float] = (0.0, 0.002)
    backlash: float = 0.0
    friction: float = 0.0


EXACT = Tolerance(kp=(1.0, 1.0), velocity_ff=(1.0, 1.0), velocity_lag=(1.0, 1.0), delay=(0.0, 0.0))


TOLERANCE_FACTORS = ("kp", "velocity_ff", "accel_ff", "velocity_lag")  # ranges of factors
TOLERANCE_KEYS = (*TOLERANCE_FACTORS, "delay", "backlash", "friction")


@dataclass(frozen=True)
class Drive:
    """Servo drive model of one axis, as the bridge runs it and the planner compensates it.

    delay: transport delay of the command (s, whole servo periods); backlash: lost motion
    between motor and load at a reversal (m or rad); friction: Coulomb friction in the
    velocity loop, as the velocity command it takes to break the axis away (m/s or rad/s);
    noise: encoder noise, standard deviation (m or rad; a plant's, never the planner's).
    The equations are in docs/machines.md."""

    kp: float
    velocity_ff: float
    accel_ff: float
    velocity_lag: float
    resolution: float
    following_error_limit: float
    delay: float = 0.0
    backlash: float = 0.0
    friction: float = 0.0
    noise: float = 0.0
    tolerance: Tolerance = Tolerance()

    def steady_error(self, velocity: float, acceleration: float) -> float:
        """The following error (against the command as sent) of this drive moving steadily
        at ``velocity`` with ``acceleration``: what feed-forward leaves, over the gain, plus
        the distance covered while the command is in transit."""
        return ((1.0 - self.velocity_ff) * velocity + (1.0 - self.accel_ff) * self.velocity_lag * acceleration) \
            / self.kp + self.delay * velocity


@dataclass(frozen=True)
class KinematicParams:
    """Rotary-axis geometry of the 5-axis layouts (m); see the module docstring."""

    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    pivot_length: float = 0.0


@dataclass(frozen=True)
class Machine:
    """A machine: ordered axes (joint names on the topics) and one drive per axis."""

    name: str
    layout: str
    axes: dict[str, Axis]
    drives: dict[str, Drive]
    kinematics: KinematicParams = KinematicParams()
    home: tuple[float, ...] = ()  # where the axes stand at power-up, in joint order (0 if empty)
    # The machine as described, when this one is a derated copy the planner plans motion
    # on (cnc_planner.motion.derating): the drives still clamp at the described limits.
    nominal: Machine | None = None

    @property
    def drive_axes(self) -> dict[str, Axis]:
        """The axis limits the servo drives clamp at: the described ones."""
        return (self.nominal or self).axes

    @property
    def home_position(self) -> tuple[float, ...]:
        return self.home or tuple(0.0 for _ in self.axes)

    @property
    def home_joints(self) -> dict[str, float]:
        """The power-up position by joint (SI): where the simulated drives start, and so where
        an offline plan starts (cnc-plan), as cnc-run's would."""
        return dict(zip(self.joint_names, self.home_position))

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.axes)

    @property
    def linear_axes(self) -> tuple[str, ...]:
        return tuple(n for n, a in self.axes.items() if a.type == "linear")

    def axis(self, name: str) -> Axis:
        try:
            return self.axes[name]
        except KeyError as err:
            raise MachineError(f"machine '{self.name}' has no axis '{name}'") from err


def exactly_as_described(machine: Machine) -> Machine:
    """The machine with every drive's tolerance closed (EXACT): the plan trusts the
    description to the last digit, as after identification on a machine that holds it."""
    drives = {j: replace(d, tolerance=EXACT) for j, d in machine.drives.items()}
    return replace(machine, drives=drives)


def machine_dirs() -> list[Path]:
    """Where machine descriptions are looked up, first match wins.

    ``CNC_MACHINE_PATH`` (os.pathsep separated) first, then the source tree's
    ``config/machines`` (a checkout or ``pip install -e``), then the ament share
    directory of an installed workspace.
    """
    dirs = [Path(p) for p in os.environ.get("CNC_MACHINE_PATH", "").split(os.pathsep) if p]
    for parent in Path(__file__).resolve().parents:
        candidate = parent / "config" / "machines"
        if candidate.is_dir():
            dirs.append(candidate)
            break
    prefix = Path(__file__).resolve()
    for parent in prefix.parents:
        share = parent / "share" / "cnc_msgs_py" / "config" / "machines"
        if share.is_dir():
            dirs.append(share)
            break
    return dirs


def _number(value: object, where: str, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MachineError(f"{where}: expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise MachineError(f"{where}: must be > 0, got {value!r}")
    return float(value)


def _parse_axis(name: str, spec: object, where: str) -> Axis:
    if not isinstance(spec, dict):
        raise MachineError(f"{where}: expected a mapping")
    kind = spec.get("type")
    if kind not in AXIS_TYPES:
        raise MachineError(f"{where}.type: expected one of {AXIS_TYPES}, got {kind!r}")
    lo = hi = None
    if kind != "continuous":
        lo = _number(spec.get("min"), f"{where}.min", positive=False)
        hi = _number(spec.get("max"), f"{where}.max", positive=False)
        if lo >= hi:
            raise MachineError(f"{where}: min {lo} must be below max {hi}")
    return Axis(
        name=name,
        type=kind,
        min=lo,
        max=hi,
        max_velocity=_number(spec.get("max_velocity"), f"{where}.max_velocity"),
        max_acceleration=_number(spec.get("max_acceleration"), f"{where}.max_acceleration"),
        max_jerk=_number(spec.get("max_jerk"), f"{where}.max_jerk"),
    )


DRIVE_KEYS = ("kp", "velocity_ff", "accel_ff", "velocity_lag", "resolution", "following_error_limit")
DRIVE_EXTRA_KEYS = ("delay", "backlash", "friction")  # zero unless given
PLANT_ONLY_KEYS = ("noise",)  # a plant's (cnc_msgs_py.plant), never a description's


def parse_drive(spec: object, where: str, base: Drive | None = None, plant: bool = False) -> Drive:
    """A drive block; keys missing from it come from ``base`` (a plant over its description)."""
    if not isinstance(spec, dict):
        raise MachineError(f"{where}: expected a mapping")
    allowed = (*DRIVE_KEYS, *DRIVE_EXTRA_KEYS, *(PLANT_ONLY_KEYS if plant else ("tolerance",)))
    unknown = [k for k in spec if k not in allowed]
    if unknown:
        raise MachineError(f"{where}.{unknown[0]}: unknown key ({', '.join(allowed)})")

    def get(key: str, positive: bool = True) -> float:
        if key not in spec and base is not None:
            return getattr(base, key)
        if key not in spec and key in (*DRIVE_EXTRA_KEYS, *PLANT_ONLY_KEYS):
            return 0.0
        number = _number(spec.get(key), f"{where}.{key}", positive)
        if not positive and number < 0 and key not in ("velocity_ff", "accel_ff"):
            raise MachineError(f"{where}.{key}: must be >= 0, got {number!r}")
        return number

    return Drive(
        kp=get("kp"), velocity_ff=get("velocity_ff", False), accel_ff=get("accel_ff", False),
        velocity_lag=get("velocity_lag"), resolution=get("resolution"),
        following_error_limit=get("following_error_limit"),
        delay=get("delay", False), backlash=get("backlash", False), friction=get("friction", False),
        noise=get("noise", False),
        tolerance=base.tolerance if base is not None else _parse_tolerance(spec.get("tolerance"), f"{where}.tolerance"),
    )


def _parse_tolerance(spec: object, where: str) -> Tolerance:
    """A drive's tolerance; keys not given keep Tolerance's defaults."""
    if spec is None:
        return Tolerance()
    if not isinstance(spec, dict):
        raise MachineError(f"{where}: expected a mapping")
    unknown = [k for k in spec if k not in TOLERANCE_KEYS]
    if unknown:
        raise MachineError(f"{where}.{unknown[0]}: unknown key ({', '.join(TOLERANCE_KEYS)})")
    values = {}
    for key, given in spec.items():
        if key in ("backlash", "friction"):
            values[key] = _number(given, f"{where}.{key}", positive=False)
            if values[key] < 0:
                raise MachineError(f"{where}.{key}: must be >= 0, got {given!r}")
            continue
        if not isinstance(given, list) or len(given) != 2:
            raise MachineError(f"{where}.{key}: expected [low, high], got {given!r}")
        lo, hi = (_number(v, f"{where}.{key}", positive=key in TOLERANCE_FACTORS) for v in given)
        if lo > hi or (key == "delay" and lo < 0):
            raise MachineError(f"{where}.{key}: expected 0 <= low <= high, got {given!r}"
                               if key == "delay" else f"{where}.{key}: expected low <= high, got {given!r}")
        values[key] = (lo, hi)
    return Tolerance(**values)


def _parse_kinematics(spec: object, where: str) -> KinematicParams:
    if spec is None:
        return KinematicParams()
    if not isinstance(spec, dict):
        raise MachineError(f"{where}: expected a mapping")
    unknown = [k for k in spec if k not in ("pivot", "pivot_length")]
    if unknown:
        raise MachineError(f"{where}.{unknown[0]}: unknown key (pivot, pivot_length)")
    pivot = spec.get("pivot", [0.0, 0.0, 0.0])
    if not isinstance(pivot, list) or len(pivot) != 3:
        raise MachineError(f"{where}.pivot: expected [x, y, z] in m, got {pivot!r}")
    length = _number(spec.get("pivot_length", 0.0), f"{where}.pivot_length", positive=False)
    if length < 0:
        raise MachineError(f"{where}.pivot_length: must be >= 0, got {length!r}")
    return KinematicParams(
        pivot=tuple(_number(v, f"{where}.pivot[{i}]", positive=False) for i, v in enumerate(pivot)),
        pivot_length=length,
    )


def parse_machine(doc: object, source: str = "machine") -> Machine:
    """Build a Machine from a parsed YAML document; errors name the offending field."""
    if not isinstance(doc, dict):
        raise MachineError(f"{source}: expected a mapping at the top level")
    layout = doc.get("layout")
    if layout not in LAYOUTS:
        raise MachineError(f"{source}: layout: expected one of {LAYOUTS}, got {layout!r}")
    axes_spec = doc.get("axes")
    drive_spec = doc.get("drive")
    if not isinstance(axes_spec, dict) or not axes_spec:
        raise MachineError(f"{source}: axes: expected a non-empty mapping")
    if not isinstance(drive_spec, dict):
        raise MachineError(f"{source}: drive: expected a mapping")
    unknown = [n for n in axes_spec if n not in JOINT_ORDER]
    if unknown:
        raise MachineError(f"{source}: axes.{unknown[0]}: joint names are {JOINT_ORDER}")
    names = [n for n in JOINT_ORDER if n in axes_spec]
    axes = {n: _parse_axis(n, axes_spec[n], f"{source}: axes.{n}") for n in names}
    missing = [n for n in names if n not in drive_spec]
    if missing:
        raise MachineError(f"{source}: drive.{missing[0]}: every axis needs a drive model")
    drives = {n: parse_drive(drive_spec[n], f"{source}: drive.{n}") for n in names}
    kinematics = _parse_kinematics(doc.get("kinematics"), f"{source}: kinematics")
    return Machine(name=str(doc.get("name", source)), layout=layout, axes=axes, drives=drives,
                   kinematics=kinematics, home=_parse_home(doc.get("home"), axes, f"{source}: home"))


def _parse_home(spec: object, axes: dict[str, Axis], where: str) -> tuple[float, ...]:
    """Optional power-up position {joint: value}; joints not named start at 0."""
    if spec is None:
        return ()
    if not isinstance(spec, dict):
        raise MachineError(f"{where}: expected a mapping of joint to position")
    unknown = [k for k in spec if k not in axes]
    if unknown:
        raise MachineError(f"{where}.{unknown[0]}: not an axis of this machine")
    home = tuple(_number(spec.get(n, 0.0), f"{where}.{n}", positive=False) for n in axes)
    for name, value in zip(axes, home):
        if not axes[name].within_travel(value):
            raise MachineError(f"{where}.{name}: {value} lies outside the axis travel")
    return home


def load_machine(name_or_path: str) -> Machine:
    """Load a machine by name (looked up in machine_dirs()) or by path to a YAML file.

    Raises:
        MachineError: the file is missing or malformed.
    """
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        found = [d / f"{name_or_path}.yaml" for d in machine_dirs()]
        found = [p for p in found if p.is_file()]
        if not found:
            raise MachineError(
                f"machine '{name_or_path}': no {name_or_path}.yaml in "
                f"{[str(d) for d in machine_dirs()]} (set CNC_MACHINE_PATH)"
            )
        path = found[0]
    try:
        doc = load_yaml(path.read_text())
    except OSError as err:
        raise MachineError(f"machine file {path}: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise MachineError(f"machine file {path}: not valid YAML ({err})") from err
    return parse_machine(doc, source=path.stem)
