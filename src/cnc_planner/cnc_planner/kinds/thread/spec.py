"""What a thread job asks for, in SI units: the thread (ThreadSpec), its chip-breaking
vibration (ThreadVibration) and the passes that cut it, each with its depth and vibration.

Coordinates are the program's, as the job writes them: radius x and z, the face at z=0.
`origin`, the axis (x, z) that puts the tip on the spindle axis at the face (setup and
tool length through the kinematic chain: planning.thread_origin), is added to every
commanded position and travel check; depths, lengths, chips and the room before the face
stay in program coordinates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.kinds.thread import tapered_ends
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import deg

TWO_PI = 2.0 * math.pi
JOINTS = ("x", "z")  # the axes that cut the thread, locked to the spindle angle
RETRACT_CLEARANCE = 1e-3  # m: radial clearance above the stock before and after the cycle
AIR_CLEARANCE = 5e-3  # m: radial clearance the retract heads for between passes on an external
# thread; x turns back on its way out in time for the next pass, so this is room, not a stop


class ThreadError(JobError):
    """A thread job that cannot be cut as asked: the job field to change (thread.*,
    vibration.*, spindle_rpm) and why, so it reaches the job's rejection as it is."""


@dataclass(frozen=True)
class ThreadVibration:
    """Chip-breaking vibration of a thread: D vibrations per revolution on the first pass,
    D_step more per pass, radial amplitude Q x the pass's depth of cut, phase advanced by
    phase_shift (rad) per pass against the spindle phase."""

    D: float
    Q: float
    phase_shift: float = math.pi
    D_step: float = 0.0


@dataclass(frozen=True)
class EndTaper:
    """G76's tapered thread ends (E, L), as LinuxCNC cuts them: over ``length`` of the
    groove at each end asked for, every pass ramps x out by the thread's depth (the last
    pass from full depth to the crest, earlier ones past it at the same angle), z still on
    the lead. ``blend``: half-width (m of groove) of the rounded corner where a ramp leaves
    the pass's depth, fitted to x's limits by ends.fit_end_taper (0: a sharp corner)."""

    length: float
    entry: bool
    exit: bool
    blend: float = 0.0


@dataclass(frozen=True)
class ThreadSpec:
    """A thread job in SI units (m, rad, rad/s) and program coordinates; pitch is the lead
    per spindle revolution, origin the axis (x, z) that puts the tip on the spindle axis at
    the face."""

    start_z: float
    end_z: float
    major_radius: float
    pitch: float
    depth: float
    spindle_speed: float
    passes: int = 6
    depths: tuple[float, ...] | None = None
    infeed_angle: float = deg(29.5)
    spring_passes: int = 1
    starts: int = 1
    internal: bool = False
    taper: float = 0.0  # diameter change per length into the part: external widens, internal narrows
    vibration: ThreadVibration | None = None
    origin: tuple[float, float] = (0.0, 0.0)
    end_taper: EndTaper | None = None

    @classmethod
    def from_job(cls, job: SimpleNamespace, origin: tuple[float, float] = (0.0, 0.0)) -> ThreadSpec:
        """From a parsed job (cnc_msgs_py.job.parse_job, already SI) and the axis position
        of its program origin."""
        t, vib, ends = job.thread, job.vibration, job.thread.end_taper
        if vib is not None and vib.D is None:
            raise ThreadError(
                "vibration.E", "a thread vibration takes D (vibrations per revolution), not E and R"
            )
        return cls(
            start_z=t.start_z, end_z=t.end_z, major_radius=t.major_radius, pitch=t.pitch,
            depth=t.depth, spindle_speed=job.spindle_rpm,
            passes=len(t.depths) if t.depths else t.passes,
            depths=tuple(t.depths) if t.depths else None, infeed_angle=t.infeed_angle,
            spring_passes=t.spring_passes, starts=t.starts, internal=t.internal, taper=t.taper,
            vibration=None if vib is None else ThreadVibration(vib.D, vib.Q, vib.phase_shift, vib.D_step),
            origin=origin,
            end_taper=None if ends is None else EndTaper(ends.length, *tapered_ends(ends.ends)),
        )

    @property
    def direction(self) -> float:
        """+1 or -1: the way z feeds from start_z to end_z."""
        return math.copysign(1.0, self.end_z - self.start_z)

    @property
    def radial(self) -> float:
        """x per unit of depth: -1 external, +1 internal (the bore grows)."""
        return 1.0 if self.internal else -1.0

    def surface(self, z: np.ndarray | float) -> np.ndarray | float:
        """Radius of the stock's surface (the major radius, a cone on a taper thread) at
        program z: major_radius at the face, growing into an external part, shrinking into
        a bore, by taper/2 per unit of length."""
        return self.major_radius + self.surface_slope * z

    @property
    def surface_slope(self) -> float:
        """Radius of the stock's surface per unit of program z (0 on a straight thread)."""
        return self.radial * self.taper / 2

    @property
    def clear_radius(self) -> float:
        """Program x before and after the cycle: RETRACT_CLEARANCE outside the surface
        everywhere on the thread."""
        return self.clear_radius_by(RETRACT_CLEARANCE)

    @property
    def air_radius(self) -> float:
        """Program x the retract heads for between passes: AIR_CLEARANCE outside an external
        thread, so that x leaves the groove at full speed; inside a bore only the clearance
        radius (its far wall is near)."""
        return self.clear_radius if self.internal else self.clear_radius_by(AIR_CLEARANCE)

    def clear_radius_by(self, clearance: float) -> float:
        """Program x ``clearance`` outside the surface everywhere on the thread."""
        return self.major_radius - self.radial * (clearance - self.taper / 2 * self.end_z)

    @property
    def lead_speed(self) -> float:
        """z speed of the helix (m/s)."""
        return self.pitch * self.spindle_speed / TWO_PI


@dataclass(frozen=True)
class Pass:
    """One pass: cumulative depth, its depth of cut, and its vibration (amplitude 0: none)."""

    index: int
    depth: float
    doc: float
    amplitude: float
    per_rev: float
    phase: float  # vibration phase at psi = 0, in cycles

    @property
    def spring(self) -> bool:
        return self.doc == 0.0


def pass_depths(spec: ThreadSpec) -> list[float]:
    """Cumulative radial depth of every pass, spring passes (full depth) included.

    Without `depths`: d_k = depth*sqrt(k/passes). The chip of a V thread is a triangle whose
    area grows with the square of the depth, so this keeps the chip area of every pass
    equal (depth*depth/passes*tan(flank)), which makes the depth of cut decrease.
    """
    cuts = list(spec.depths) if spec.depths else [
        spec.depth * math.sqrt(k / spec.passes) for k in range(1, spec.passes + 1)
    ]
    return cuts + [spec.depth] * spec.spring_passes


def passes_of(spec: ThreadSpec, vib: ThreadVibration | None = None) -> list[Pass]:
    """Every pass in order, spring passes last; with ``vib`` instead of the spec's vibration
    (the chip check tries other settings)."""
    vib = spec.vibration if vib is None else vib
    out, previous = [], 0.0
    for k, depth in enumerate(pass_depths(spec)):
        doc = depth - previous if k < spec.passes else 0.0
        vibrating = vib is not None and doc > 0.0
        out.append(Pass(
            index=k, depth=depth, doc=doc,
            amplitude=vib.Q * doc if vibrating else 0.0,
            per_rev=vib.D + k * vib.D_step if vibrating else 0.0,
            phase=(k * vib.phase_shift / TWO_PI) % 1.0 if vibrating else 0.0,
        ))
        previous = depth
    return out


def left_standing(cuts: list[Pass], pulls: dict[int, float]) -> list[Pass]:
    """The passes with pass k's depth raised by pulls[k] (m): material left on the part where
    a drive inside the tolerance would cut deeper than the thread (kinds/thread/tolerance.py).
    Depths of cut follow the raised depths; a pass's vibration stays as planned, so its
    returns lie no lower than before and its chips break as they did; spring passes stay
    spring passes."""
    out, previous = [], 0.0
    for cut in cuts:
        depth = cut.depth - pulls.get(cut.index, 0.0)
        out.append(replace(cut, depth=depth, doc=0.0 if cut.spring else depth - previous))
        previous = depth
    return out
