"""The drill cycle the planner drills: holes, planes, feed and options in axis coordinates,
and the error that names the job field a cycle cannot be drilled for."""
from __future__ import annotations

from dataclasses import dataclass

from cnc_msgs_py.schema import JobError

from cnc_planner.kinds.drill.peck import Peck
from cnc_planner.vibration.waveform import Vibration

# Conventional cycle: X/Y travel at R + 1 mm (G99 returns to R; the 1 mm keeps the tip
# above R on feedback too, where Z reads up to ~0.3 mm below its command while braking).
# The overlapped cycle ends at this level as well after its last hole (mode 3).
RETURN_CLEARANCE = 1e-3


class DrillError(JobError):
    """A cycle this machine cannot drill; ``field`` is the job's field path ("drill.feed",
    "drill.holes[3]", "drill.mode", "drill.depth", "vibration.D", or "drill" itself)."""


@dataclass(frozen=True)
class DrillCycle:
    """One drilling job in axis coordinates (m, m/s, z up): holes, planes, feed, options.

    mode None lets the planner choose the retract law per hole; 1/2/3 force it.
    xy_tolerance: X/Y must be this close to the hole, on feedback, whenever the tip is
    below R. servo_period: the bridge's period, for the drive model the timing uses.
    compensate_xy: pre-compensate the overlapped cycle's X/Y commands with the drive
    model, so that the X/Y feedback is in position when the ruckig move ends.

    Its own checks raise a plain ValueError: the job's drill block is checked before a
    cycle is built (block.py), so a cycle that fails them is the planner's mistake.
    """

    holes: list[tuple[float, float]]
    surface_z: float
    bottom_z: float
    r_z: float
    feed: float
    overlap: bool = True
    mode: int | None = None
    gentle_air_accel: bool = False
    xy_tolerance: float = 1e-5
    servo_period: float = 1e-3
    compensate_xy: bool = True
    vibration: Vibration | None = None
    spindle_speed: float = 0.0
    vibration_choice: dict | None = None  # the waveform's parameters as events record them (auto or given)
    dwell: float = 0.0
    hole_planes: tuple[tuple[float, float, float], ...] | None = None
    peck: Peck | None = None
    order: tuple[int, ...] | None = None  # the job's index of each hole, in drilling order
    air_planes: tuple[float, ...] | None = None  # per hole: the plane X/Y moves above into it

    def __post_init__(self) -> None:
        if not self.holes:
            raise ValueError("holes: at least one hole is needed")
        if not self.bottom_z < self.surface_z <= self.r_z:
            raise ValueError("planes: need bottom_z < surface_z <= r_z")
        if self.feed <= 0:
            raise ValueError("feed: must be > 0")
        if self.mode not in (None, 1, 2, 3):
            raise ValueError(f"mode: expected None, 1, 2 or 3, got {self.mode!r}")
        if self.xy_tolerance <= 0 or self.servo_period <= 0:
            raise ValueError("xy_tolerance and servo_period must be > 0")
        if self.vibration is not None and not self.spindle_speed > 0:
            raise ValueError("spindle_speed: a vibrated feed needs a turning spindle")
        if self.dwell < 0:
            raise ValueError("dwell: must be >= 0")
        if self.hole_planes is not None:
            if len(self.hole_planes) != len(self.holes):
                raise ValueError("hole_planes: one (surface, R, bottom) per hole")
            if not all(self.bottom_z <= b < s <= r <= self.r_z for s, r, b in self.hole_planes):
                raise ValueError("hole_planes: need bottom_z <= bottom < surface <= R <= r_z per hole")
        if self.air_planes is not None and (len(self.air_planes) != len(self.holes)
                                            or min(self.air_planes) < self.r_z):
            raise ValueError("air_planes: one per hole, none below r_z")

    def planes(self, i: int) -> tuple[float, float, float]:
        """Hole i's surface, its R plane (where the feed starts) and its bottom. r_z is the
        plane X/Y moves above: the highest R, or higher (clearance_z)."""
        return self.hole_planes[i] if self.hole_planes is not None else (self.surface_z, self.r_z, self.bottom_z)

    def air_plane(self, i: int) -> float:
        """The plane X/Y moves above into hole i (i = 0: from the start; i = len(holes):
        after the last hole): r_z, or higher where the move passes over clamps (obstacles)."""
        return self.air_planes[i] if self.air_planes is not None and i < len(self.holes) else self.r_z

    @property
    def entry_velocity(self) -> float:
        """Z velocity at R going down: the cutting feed, or rest where a vibrated feed starts
        (its waveform ramps up from rest, locked to the spindle angle)."""
        return 0.0 if self.vibration is not None else -self.feed
