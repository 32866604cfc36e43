"""Thread cutting on the lathe: multi-pass synchronised helix, optionally with a
chip-breaking vibration along the infeed direction (design, method 4).

Coordinates are the program's, as the job writes them: radius x and z, the face at z=0.
`origin`, the axis (x, z) that puts the tip on the spindle axis at the face (setup and
tool length through the kinematic chain: jobs.thread_origin), is added to every commanded
position and travel check; depths, lengths, chips and the room before the face stay in
program coordinates.

Geometry (SI, external thread; an internal one mirrors x). Pass k cuts to the cumulative
radial depth d_k. The tool moves in along the infeed line, at infeed_angle from radial:
at depth d its tip is at x = major_radius - d and shifted d*tan(infeed_angle) along the
feed, so it slides down the trailing flank and its leading edge does the cutting. The
helix angle psi of a pass is the spindle angle counted from where that pass's helix
passes start_z; psi is the groove coordinate, the same point of the groove on every pass:

    depth(psi) = d_k - A_k * (1 - w(D_k*psi/2pi + k*phase_shift/2pi))
    x = surface(g) - depth,   z = g - depth*tan(infeed_angle),   g = start_z - pitch*psi/2pi

with surface(g) = major_radius on a straight thread; on a taper thread (`taper`, diameter
per length) the stock is a cone, major_radius at the face and growing by taper/2 per unit
of length into the part (shrinking into a bore), so x follows the cone along the groove
and both axes stay locked to the spindle angle; the depth stays radial below the cone.

with w the vibration module's waveform (0 at the return point, 1 at the turning point),
A_k = Q * (d_k - d_(k-1)) the radial amplitude and D_k = D + k*D_step. The vibration
therefore moves x and z together along the infeed line and never leaves the flank. With
phase_shift = 180 deg pass k returns where pass k-1 reached its turning point d_(k-1);
with Q > 1 its return lies above it: the tool is in air there and the chip breaks, at
least once per vibration. Spring passes run at full depth without vibration and take
off what the last returns left standing.

Every pass's helix passes start_z at the same spindle phase (the index, plus 360/starts
per start), so all passes land in one groove; z is locked to the spindle angle, not to
time. Between passes the tool does not stop (ThreadCycle): it pulls out past end_z into
the relief groove on a retreating stroke, returns in the air and lands on the next
pass's running helix before the face z=0 at the servo instant the spindle phase allows.
The whole cycle's x/z command is pre-compensated with the drive model
(motion.compensation) so the bridge's feedback, not only the command, holds lead,
depth and flank offset.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from ruckig import InputParameter, Ruckig, RuckigError, Trajectory

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import deg, to_mm
from cnc_servo_bridge.drive import DriveModel
from cnc_planner.motion.jerk_profile import TrajectorySampler
from cnc_servo_bridge.stop import velocity_trajectory
from cnc_analysis.threads import (
    CHIP_LIMIT_REVS, CUT_TOLERANCE, cuts_against_envelope, longest_runs,
)

from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import MotionError, axis_limits, calculate
from cnc_planner.motion.timeline import Piece
from cnc_planner.motion.compensation import COMPENSATION_TAIL, learned_command
from cnc_planner.vibration.waveform import waveform

TWO_PI = 2.0 * math.pi
JOINTS = ("x", "z")
RETRACT_CLEARANCE = 1e-3  # m: radial clearance above the stock between passes
SETTLE_TIME = 0.05  # s at rest before the cycle: the drives settle after the rapid to its start
SPINDLE_SETTLE = 0.2  # s after the spindle reaches speed: its following error has died out
CHECK_POINTS_PER_REV = 720  # groove grid of the chip-breaking check
Q_MAX = 20.0  # the job schema's bound: the search for a working Q stops there
WAVE_POINTS = 4096  # phase samples for the waveform's derivative maxima
RAMP_JERK_SHARE = 0.6  # of the axis jerk for ramps onto and off the helix: room for the
# compensated command, which leads each jerk step by the drive's velocity lag
WAVE_LIMIT_SHARE = 0.95  # of each axis limit for the vibration: the compensated command
# leads the motion and runs a few per cent above it
COMPENSATION_BAND = (0.05, 0.12)  # of the servo rate (50..120 Hz at 1 ms): above the vibration,
# below the encoder quantisation noise a wider band would feed into the command's jerk
LEAD_TIME = 0.06  # s at rest before the ramp: the band-limited compensation leads this far
SETTLED_COUNTS = 0.25  # encoder counts: a command correction below this has settled
MAX_AIR_S = 3.0  # s: longest the search for a pass's join looks beyond its earliest start
JOIN_ROOM_REVS = 0.25  # revolutions of helix, at least, between joining it and the face
JOIN_BATCH = 64  # candidate joins whose helix states are evaluated at once
MAX_PASS_REVS = 2000  # spindle revolutions of one pass: checks and plans sample every one
MAX_PASS_S = 600.0  # s of helix per pass: a longer pass is a mistyped pitch or speed


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

    @classmethod
    def from_job(cls, job: SimpleNamespace, origin: tuple[float, float] = (0.0, 0.0)) -> ThreadSpec:
        """From a parsed job (cnc_msgs_py.job.parse_job, already SI) and the axis position
        of its program origin."""
        t, vib = job.thread, job.vibration
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
        return self.major_radius + self.radial * self.taper / 2 * z

    @property
    def clear_radius(self) -> float:
        """Program x between passes: RETRACT_CLEARANCE outside the surface everywhere on the thread."""
        return self.major_radius - self.radial * (RETRACT_CLEARANCE - self.taper / 2 * self.end_z)

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


def _passes(spec: ThreadSpec, vib: ThreadVibration | None = None) -> list[Pass]:
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


# -- validation ---------------------------------------------------------------------------
def _rpm(omega: float) -> float:
    return omega * 60.0 / TWO_PI


def _mm(value: float) -> str:
    return f"{to_mm(value):.4g} mm"


def _ramp(speed: float, machine: Machine) -> Trajectory:
    """Time-optimal z ramp from rest to the helix speed."""
    z = machine.axis("z")
    return velocity_trajectory([0.0], [0.0], [0.0], [speed], [z.max_velocity], [z.max_acceleration],
                               [RAMP_JERK_SHARE * z.max_jerk])


def _wave_maxima() -> np.ndarray:
    """max |w'|, |w''|, |w'''| per cycle of the symmetric waveform."""
    _, *derivatives = waveform(np.arange(WAVE_POINTS) / WAVE_POINTS)
    return np.array([np.max(np.abs(d)) for d in derivatives])


def _check_fields(spec: ThreadSpec) -> None:
    def positive(field: str, value: float) -> None:
        if not (math.isfinite(value) and value > 0):
            raise ThreadError(field, f"must be > 0, got {to_mm(value):g} mm")

    positive("thread.pitch", spec.pitch)
    positive("thread.major_radius", spec.major_radius)
    if not (math.isfinite(spec.depth) and spec.depth > 0):
        raise ThreadError("thread.depth", f"must be > 0, got {to_mm(spec.depth):g} mm")
    if spec.depth >= spec.major_radius:
        raise ThreadError(
            "thread.depth", f"{_mm(spec.depth)} is not smaller than major_radius {_mm(spec.major_radius)}"
        )
    if not (math.isfinite(spec.taper) and 0.0 <= spec.taper < 1.0):
        raise ThreadError("thread.taper", f"must be >= 0 and < 1 (diameter per length), got {spec.taper!r}")
    narrowest = min(spec.surface(spec.end_z), spec.major_radius)
    if spec.depth >= narrowest:
        raise ThreadError(
            "thread.taper", f"the thread narrows to radius {_mm(narrowest)} at end_z, not more than "
            f"thread.depth {_mm(spec.depth)}"
        )
    if not 0.0 <= spec.infeed_angle < math.pi / 2:
        raise ThreadError(
            "thread.infeed_angle", f"{math.degrees(spec.infeed_angle):g} deg is outside 0..90 deg "
            "(0 = radial infeed, below 90)"
        )
    if not spec.start_z > 0.0:
        raise ThreadError(
            "thread.start_z", f"{_mm(spec.start_z)} is not in the air: each pass starts in front of the face z=0"
        )
    if not spec.end_z < 0.0:
        raise ThreadError(
            "thread.end_z", f"{_mm(spec.end_z)} is on the wrong side: the thread runs from start_z "
            f"{_mm(spec.start_z)} through the face z=0 into the stock, so end_z must be < 0"
        )
    for field, value, least in (("passes", spec.passes, 1), ("spring_passes", spec.spring_passes, 0),
                                ("starts", spec.starts, 1)):
        if not (isinstance(value, int) and value >= least):
            raise ThreadError(f"thread.{field}", f"must be a whole number >= {least}, got {value!r}")
    if spec.depths is not None:
        depths = list(spec.depths)
        if len(depths) != spec.passes:
            raise ThreadError("thread.depths", f"{len(depths)} depths for {spec.passes} passes")
        if depths[0] <= 0 or any(b <= a for a, b in zip(depths, depths[1:])):
            raise ThreadError("thread.depths", "cumulative depths must be > 0 and increase")
        if abs(depths[-1] - spec.depth) > 1e-9:
            raise ThreadError(
                "thread.depths", f"the last depth {_mm(depths[-1])} must equal thread.depth {_mm(spec.depth)}"
            )
        docs = np.diff([0.0] + depths)
        grows = np.flatnonzero(docs[1:] > docs[:-1] + 1e-12)
        if grows.size:
            k = int(grows[0]) + 1
            raise ThreadError(
                "thread.depths", f"the depth of cut grows from pass {k} ({_mm(docs[k - 1])}) "
                f"to pass {k + 1} ({_mm(docs[k])}); it must never grow"
            )


def _check_speed(spec: ThreadSpec, machine: Machine) -> None:
    omega, spindle, z = spec.spindle_speed, machine.axis(SPINDLE), machine.axis("z")
    if not (math.isfinite(omega) and omega > 0):
        raise ThreadError("spindle_rpm", f"a thread needs a turning spindle, got {_rpm(omega):g} rpm")
    if omega > spindle.max_velocity * (1 + 1e-9):
        raise ThreadError(
            "spindle_rpm", f"{_rpm(omega):.0f} rpm is more than the spindle's "
            f"{_rpm(spindle.max_velocity):.0f} rpm"
        )
    if spec.lead_speed > z.max_velocity:
        raise ThreadError(
            "thread.pitch", f"{to_mm(spec.pitch):g} mm/rev needs z speed {spec.lead_speed:.3g} m/s at "
            f"{_rpm(omega):.0f} rpm, more than the z axis's {z.max_velocity:g} m/s; "
            f"max {math.floor(_rpm(z.max_velocity * TWO_PI / spec.pitch)):.0f} rpm"
        )


def _check_room(spec: ThreadSpec, machine: Machine) -> None:
    """The ramp onto the helix must end before the face, the pull-out stay within travel.

    Estimated: ramp travel at the helix speed, one vibration of helix travel for the ramp
    to catch the waveform, and the deepest flank offset; plan_thread checks exactly.
    """
    tan, vib = math.tan(spec.infeed_angle), spec.vibration
    ramp = _ramp(spec.lead_speed, machine).duration
    catch = spec.pitch / vib.D if vib is not None else 0.0
    travel = spec.lead_speed * ramp / 2 + catch
    need = spec.depth * tan + travel
    if spec.start_z < need:
        raise ThreadError(
            "thread.start_z", f"{_mm(spec.start_z)} leaves too little room before the face to reach the "
            f"lead speed {to_mm(spec.lead_speed):.4g} mm/s: needs {_mm(need)} (ramp and flank offset)"
        )
    x_axis, z_axis = machine.axis("x"), machine.axis("z")
    x0, z0 = spec.origin
    x_clear = spec.clear_radius
    x_deep = spec.surface(spec.end_z) + spec.radial * spec.depth
    for x in (x0 + x_clear, x0 + x_deep):
        if not x_axis.within_travel(x):
            raise ThreadError(
                "thread.major_radius", f"the tool would reach axis x = {_mm(x)}, outside the x axis travel "
                f"{_mm(x_axis.min)}..{_mm(x_axis.max)}"
            )
    overrun = spec.end_z + spec.direction * (travel + spec.pitch)
    for field, z in (("thread.start_z", z0 + spec.start_z), ("thread.end_z", z0 + overrun)):
        if not z_axis.within_travel(z):
            raise ThreadError(
                field, f"the tool would reach axis z = {_mm(z)}, outside the z axis travel "
                f"{_mm(z_axis.min)}..{_mm(z_axis.max)}"
            )


def _check_length(spec: ThreadSpec) -> None:
    """A pass of bounded revolutions and time: planning and checks sample every revolution."""
    length = abs(spec.end_z - spec.start_z)
    revs = length / spec.pitch
    if revs > MAX_PASS_REVS:
        raise ThreadError(
            "thread.pitch", f"{_mm(spec.pitch)} over {_mm(length)} makes {revs:.4g} revolutions per pass, "
            f"more than the maximum {MAX_PASS_REVS}; need pitch >= {_mm(length / MAX_PASS_REVS)}"
        )
    seconds = length / spec.lead_speed
    if seconds > MAX_PASS_S:
        least = math.ceil(_rpm(TWO_PI * length / spec.pitch / MAX_PASS_S))
        raise ThreadError(
            "spindle_rpm", f"at {_rpm(spec.spindle_speed):.4g} rpm a pass takes {seconds:.4g} s, more than the "
            f"maximum {MAX_PASS_S:g} s; need >= {least} rpm"
        )


def _chip_revs(spec: ThreadSpec, vib: ThreadVibration) -> np.ndarray:
    """Longest continuous cut (revolutions) of every vibrated pass on the ideal geometry,
    judged like thread_analysis judges feedback: against the envelope of earlier passes."""
    passes = [p for p in _passes(spec, vib) if not p.spring]
    s = spec.direction
    face, end = s * -spec.start_z / spec.pitch, s * (spec.end_z - spec.start_z) / spec.pitch
    psi = np.linspace(face, end, math.ceil((end - face) * CHECK_POINTS_PER_REV) + 1)
    depth = np.array([
        p.depth - p.amplitude * (1.0 - waveform(p.per_rev * psi + p.phase)[0]) for p in passes
    ])
    cutting = cuts_against_envelope(depth) > CUT_TOLERANCE
    return longest_runs(cutting) / CHECK_POINTS_PER_REV


def _check_vibration_fields(vib: ThreadVibration) -> None:
    for field, value in (("D", vib.D), ("Q", vib.Q)):
        if not (math.isfinite(value) and value > 0):
            raise ThreadError(f"vibration.{field}", f"must be > 0, got {value:g}")
    if not (math.isfinite(vib.D_step) and vib.D_step >= 0):
        raise ThreadError("vibration.D_step", f"must be >= 0, got {vib.D_step:g}")
    if not math.isfinite(vib.phase_shift):
        raise ThreadError("vibration.phase_shift", f"expected a finite angle, got {vib.phase_shift!r}")


def _check_chips(spec: ThreadSpec, vib: ThreadVibration) -> None:
    """Every vibrated pass must break its chip within CHIP_LIMIT_REVS; else name the field
    to change: phase_shift (if 180 deg would do), Q (with the least that works), or D."""
    if vib.Q <= 1.0:
        raise ThreadError(
            "vibration.Q", f"{vib.Q:g} never lifts the tool out of the cut: the return must rise above the "
            "earlier passes by more than the depth of cut (amplitude = Q x depth of cut); need Q > 1"
        )
    if spec.spring_passes < 1:
        raise ThreadError(
            "thread.spring_passes", "0 with a vibration leaves the last pass's returns standing; need >= 1"
        )

    def worst(v: ThreadVibration) -> tuple[float, int]:
        revs = _chip_revs(spec, v)
        return float(revs.max()), int(np.argmax(revs)) + 1

    def breaks(q: float) -> bool:
        return worst(ThreadVibration(vib.D, q, vib.phase_shift, vib.D_step))[0] <= CHIP_LIMIT_REVS

    chip, k = worst(vib)
    if chip <= CHIP_LIMIT_REVS:
        return
    told = f"leaves a continuous cut of {chip:.2f} revs in pass {k}"
    if worst(ThreadVibration(vib.D, vib.Q, math.pi, vib.D_step))[0] <= CHIP_LIMIT_REVS:
        raise ThreadError(
            "vibration.phase_shift", f"{math.degrees(vib.phase_shift):g} deg {told}: its returns miss "
            "the previous pass's turning points; 180 deg puts them there"
        )
    qs = np.geomspace(vib.Q, Q_MAX, 40)
    first = next((i for i in range(1, qs.size) if breaks(qs[i])), None)
    if first is not None:
        lo, hi = qs[first - 1], qs[first]
        for _ in range(12):
            mid = (lo + hi) / 2
            lo, hi = (lo, mid) if breaks(mid) else (mid, hi)
        raise ThreadError("vibration.Q", f"{vib.Q:g} {told}; need Q >= {math.ceil(hi * 100) / 100:.2f}")
    raise ThreadError(
        "vibration.D", f"{vib.D:g} vibrations/rev (+{vib.D_step:g} per pass) {told}; the chip breaks at most "
        "once per vibration: raise D"
    )


def _check_follow(spec: ThreadSpec, machine: Machine) -> None:
    """The waveform of every pass within the x and z velocity, acceleration and jerk limits.

    Velocity grows with the spindle speed, acceleration with its square, jerk with its cube,
    so each limit gives the spindle speed at which the waveform just touches it.
    """
    omega, tan, maxima = spec.spindle_speed, math.tan(spec.infeed_angle), _wave_maxima()
    worst = None
    for p in _passes(spec):
        if p.spring:
            continue
        rate = p.per_rev * omega / TWO_PI  # vibrations per second
        radial = p.amplitude * maxima * rate ** np.arange(1, 4)  # depth: |v|, |a|, |j|
        cone = np.array([spec.taper / 2 * spec.lead_speed, 0.0, 0.0])  # x follows the taper
        for joint, need in (("x", radial + cone), ("z", tan * radial + np.array([spec.lead_speed, 0.0, 0.0]))):
            axis = machine.axis(joint)
            for order, (quantity, limit, unit) in enumerate((
                ("velocity", axis.max_velocity, "m/s"), ("acceleration", axis.max_acceleration, "m/s^2"),
                ("jerk", axis.max_jerk, "m/s^3"),
            )):
                usable = WAVE_LIMIT_SHARE * limit
                top = omega * (usable / need[order]) ** (1.0 / (order + 1)) if need[order] > 0 else math.inf
                if worst is None or top < worst[0]:
                    worst = (top, joint, quantity, need[order], limit, unit, p)
    top, joint, quantity, need, limit, unit, p = worst
    if omega > top:
        raise ThreadError(
            "vibration.D", f"the {joint} axis cannot follow {p.per_rev:g} vibrations/rev of {_mm(p.amplitude)} "
            f"(pass {p.index + 1}) at {_rpm(omega):.0f} rpm (needs {quantity} {need:.3g} {unit}, over "
            f"{WAVE_LIMIT_SHARE:.0%} of its {limit:g} {unit}: the rest is the compensated command's); "
            f"max spindle speed {math.floor(_rpm(top)):.0f} rpm"
        )


def check_thread(spec: ThreadSpec, machine: Machine) -> None:
    """Reject a thread the lathe cannot cut as asked, before anything moves.

    Raises:
        ThreadError: one line starting with the job field (thread.*, vibration.*, spindle_rpm).
    """
    _check_fields(spec)
    if spec.vibration is not None:
        _check_vibration_fields(spec.vibration)
    _check_speed(spec, machine)
    _check_length(spec)  # before the vibration checks, which sample every revolution
    if spec.vibration is not None:
        _check_chips(spec, spec.vibration)
        _check_follow(spec, machine)
    _check_room(spec, machine)


# -- motion --------------------------------------------------------------------------------
class _Ramps:
    """Jerk-limited single-axis moves between states at the ramps' share of the jerk limit,
    on one reused ruckig instance (building one costs more than its calculation)."""

    def __init__(self, machine: Machine) -> None:
        self._limits = {j: axis_limits(machine.axis(j)) for j in JOINTS}
        self._ruckig = Ruckig(1)

    def reach(self, joint: str, start: np.ndarray, target: np.ndarray,
              duration: float | None = None) -> Trajectory | None:
        """The move of ``joint`` from state start to state target (p, v, a), lasting at
        least ``duration`` if given, or None if ruckig finds none."""
        limits = self._limits[joint]
        inp = InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = ([x] for x in start)
        inp.target_position, inp.target_velocity, inp.target_acceleration = ([x] for x in target)
        inp.max_velocity, inp.max_acceleration = [limits.velocity], [limits.acceleration]
        inp.max_jerk = [RAMP_JERK_SHARE * limits.jerk]
        if duration is not None:
            inp.minimum_duration = duration
        try:
            return calculate(inp, self._ruckig)
        except (MotionError, RuckigError):
            return None


def _evaluate(trajectory: Trajectory, t: np.ndarray) -> np.ndarray:
    """(3, len(t), dofs): position, velocity, acceleration; the end state after the end."""
    return TrajectorySampler(trajectory).sample(np.minimum(t, trajectory.duration))


def _helix(spec: ThreadSpec, cut: Pass, psi: np.ndarray) -> np.ndarray:
    """(3, len(psi), 2): axis x and z, their velocity and acceleration on the helix of a
    pass with its vibration, at helix angles psi (the spindle turning at speed)."""
    omega, s, tan = spec.spindle_speed, spec.direction, math.tan(spec.infeed_angle)
    rate = cut.per_rev * omega / TWO_PI
    w, w1, w2, _ = waveform(cut.per_rev * psi / TWO_PI + cut.phase)
    depth = cut.depth - cut.amplitude * (1.0 - w)
    ddepth, dddepth = cut.amplitude * rate * w1, cut.amplitude * rate**2 * w2
    groove = spec.start_z + s * spec.pitch * psi / TWO_PI  # the groove's z under the tool
    cone = spec.radial * spec.taper / 2 * s * spec.lead_speed  # x speed of the surface along it
    out = np.empty((3, psi.size, 2))
    out[0, :, 0] = spec.origin[0] + spec.surface(groove) + spec.radial * depth
    out[0, :, 1] = spec.origin[1] + groove + s * depth * tan
    out[1] = np.stack([cone + spec.radial * ddepth, s * (spec.lead_speed + tan * ddepth)], 1)
    out[2] = np.stack([spec.radial * dddepth, s * tan * dddepth], 1)
    return out


Stretch = tuple[float, Callable[[np.ndarray], np.ndarray]]  # (cycle time it begins,
# cycle times -> (3, len(t)): one axis's position, velocity and acceleration)


def _held(position: float) -> Stretch:
    return lambda t: np.stack([np.full(t.size, position), np.zeros(t.size), np.zeros(t.size)])


def _moving(start: float, trajectory: Trajectory) -> Stretch:
    sampler = TrajectorySampler(trajectory)  # read once: a stretch is sampled many times
    return lambda t: sampler.sample(np.minimum(t - start, sampler.duration))[:, :, 0]


@dataclass
class CutTiming:
    """Where one pass of one start lies on the cycle's clock (s from the cycle start)."""

    cut: Pass
    start: int
    theta_ref: float  # absolute spindle angle at which this pass's helix passes start_z
    t_begin: float  # its air path begins (the previous pass leaves its helix)
    t_join: float  # on the helix
    t_out: float  # leaves the helix past end_z
    retract: Trajectory  # x out to the clearance radius from t_out
    stop: Trajectory  # z to rest from t_out

    @property
    def t_end(self) -> float:
        return self.t_out + max(self.retract.duration, self.stop.duration)


class ThreadCycle:
    """Every pass of every start as one continuous motion of x and z, on a clock from the
    cycle start (at rest at the clearance radius and start_z, the spindle at speed).

    Between passes the tool never stops to wait. As a pass leaves its helix past end_z, x
    pulls out to the clearance radius and z stops; z turns back as soon as x is out of the
    stock (the rest of the retract overlaps the return) and runs one jerk-limited path
    straight onto the next pass's running helix, timed to arrive there at the servo
    instant the spindle phase allows: the wait for the phase is spent in the return.
    x plunges to the pass depth in front of the face, on a path that ends on the helix.
    Which helix revolution a pass joins is the earliest whose join lies before the face by
    JOIN_ROOM_REVS and that the axes can reach with the tool never inside the stock over
    the thread. With a drive model the whole cycle is compensated at once
    (motion.compensation): the command's lead-in of each pass runs while the tool is
    still in the air, and only the cycle's start needs LEAD_TIME at rest.
    """

    def __init__(self, spec: ThreadSpec, machine: Machine, period: float, theta0: float,
                 drive: DriveModel | None = None) -> None:
        self.spec, self.machine, self.period, self.theta0 = spec, machine, period, theta0
        self._ramps = _Ramps(machine)
        self.t_lead = round(LEAD_TIME / period) * period
        self.x_clear = spec.origin[0] + spec.clear_radius
        self.tracks: list[list[Stretch]] = [[(0.0, _held(self.x_clear))],
                                            [(0.0, _held(spec.origin[1] + spec.start_z))]]
        self.cuts: list[CutTiming] = []
        for cut in _passes(spec):
            for start in range(spec.starts):
                self._add(cut, start)
        self.end = np.array([self.cuts[-1].retract.at_time(self.cuts[-1].retract.duration)[0][0],
                             self.cuts[-1].stop.at_time(self.cuts[-1].stop.duration)[0][0]])
        self.duration = math.ceil(self.cuts[-1].t_end / period - 1e-9) * period
        self._correction: np.ndarray | None = None
        self._cache: tuple[tuple[int, float, float], np.ndarray] | None = None
        if drive is not None:
            self._compensate(drive)

    def psi(self, theta_ref: float, t: np.ndarray | float) -> np.ndarray | float:
        """Helix angle at cycle time t of the helix that passes start_z at theta_ref."""
        return self.theta0 + self.spec.spindle_speed * t - theta_ref

    def _state(self, cut: Pass, theta_ref: float, t: float) -> np.ndarray:
        return _helix(self.spec, cut, np.array([self.psi(theta_ref, t)]))[:, 0, :].T  # rows x, z

    def _add(self, cut: Pass, start: int) -> None:
        spec, period = self.spec, self.period
        s, x0, z0 = spec.direction, spec.origin[0], spec.origin[1]
        if self.cuts:
            last = self.cuts[-1]
            t_begin, x_free = last.t_out, last.t_out + last.retract.duration
            out = np.arange(math.ceil(last.retract.duration / period) + 1) * period
            depth = spec.radial * (_evaluate(last.retract, out)[0, :, 0] - x0 - spec.surface(spec.end_z))
            t_clear = last.t_out + float(out[np.flatnonzero(depth <= 0.0)[0]])
            t_go = math.ceil(max(t_clear, last.t_out + last.stop.duration) / period - 1e-9) * period
            z_from = last.stop.at_time(last.stop.duration)[0][0]
        else:
            t_begin, x_free = 0.0, self.t_lead
            t_go, z_from = self.t_lead, z0 + spec.start_z
        phase = TWO_PI * start / spec.starts
        psi_room = TWO_PI * (spec.start_z / spec.pitch - JOIN_ROOM_REVS)  # the latest join before the face
        z_rest, x_rest = [z_from, 0.0, 0.0], [self.x_clear, 0.0, 0.0]
        first = math.ceil(t_go / period - 1e-9) + 1
        for k, t_join, theta_ref, target in self._joins(cut, phase, psi_room, first,
                                                        first + math.ceil(MAX_AIR_S / period)):
            z_target = target[1].tolist()
            fastest = self._ramps.reach("z", z_rest, z_target)
            if fastest is None or fastest.duration > t_join - t_go + 1e-12:
                continue
            back = self._ramps.reach("z", z_rest, z_target, duration=t_join - t_go)
            plunge = self._ramps.reach("x", x_rest, target[0].tolist())
            if (back is None or abs(back.duration - (t_join - t_go)) > 1e-9 or plunge is None
                    or t_join - plunge.duration < x_free - 1e-12):
                continue
            tried = [[(t_join - plunge.duration, _moving(t_join - plunge.duration, plunge))],
                     [(t_go, _moving(t_go, back))]]
            grid = np.arange(math.floor(t_begin / period), k) * period
            x, z = (self._sample(track + extra, grid)[0] for track, extra in zip(self.tracks, tried))
            depth = spec.radial * (x - x0 - spec.surface(z - z0))
            over_stock = (s * (z - z0) >= 0.0) & (s * (z - z0) <= s * spec.end_z)
            if np.any(over_stock & (depth > 0.0)):
                continue
            on_helix = self._on_helix(cut, theta_ref)
            for j in range(2):
                self.tracks[j] += tried[j] + [(t_join, lambda t, j=j: on_helix(t)[:, :, j])]
            t_out, retract, stop = self._exit(cut, theta_ref, t_join)
            self.tracks[0].append((t_out, _moving(t_out, retract)))
            self.tracks[1].append((t_out, _moving(t_out, stop)))
            self.cuts.append(CutTiming(cut, start, theta_ref, t_begin, t_join, t_out, retract, stop))
            return
        raise ThreadError(
            "thread.start_z", f"the axes cannot reach the helix of pass {cut.index + 1} in front of the "
            f"face within {MAX_AIR_S:g} s"
        )

    def _on_helix(self, cut: Pass, theta_ref: float) -> Callable[[np.ndarray], np.ndarray]:
        """Cycle times -> _helix of the pass joined at theta_ref; x and z ask for the same
        instants one after the other, so the last answer is kept (for exactly those instants:
        grids that differ by rounding only must not share it)."""
        last = [np.empty(0), _helix(self.spec, cut, np.empty(0))]  # instants, helix there

        def on_helix(t: np.ndarray) -> np.ndarray:
            if not np.array_equal(last[0], t):
                last[:] = t.copy(), _helix(self.spec, cut, self.psi(theta_ref, t))
            return last[1]

        return on_helix

    def _joins(self, cut: Pass, phase: float, psi_room: float, first: int, stop: int):
        """Candidate joins k in [first, stop) in order: (k, t_join, theta_ref of the latest
        helix revolution joined before psi_room, the helix state there (rows x, z; columns
        p, v, a)), evaluated JOIN_BATCH at a time: most are rejected on ruckig's fastest
        time alone."""
        spec = self.spec
        for lo in range(first, stop, JOIN_BATCH):
            t_joins = np.arange(lo, min(stop, lo + JOIN_BATCH)) * self.period
            theta_refs = phase + TWO_PI * np.ceil(
                (self.theta0 + spec.spindle_speed * t_joins - psi_room - phase) / TWO_PI)
            targets = _helix(spec, cut, self.psi(theta_refs, t_joins)).transpose(1, 2, 0)
            yield from zip(range(lo, lo + len(t_joins)), t_joins.tolist(), theta_refs.tolist(), targets)

    def _exit(self, cut: Pass, theta_ref: float, t_join: float) -> tuple[float, Trajectory, Trajectory]:
        """Leave the helix past end_z when the vibration retreats: x out to the clearance
        radius, z to a time-optimal stop."""
        spec, period = self.spec, self.period
        psi_end = TWO_PI * spec.direction * (spec.end_z - spec.start_z) / spec.pitch
        t_end = (psi_end + theta_ref - self.theta0) / spec.spindle_speed
        first = max(math.ceil(t_end / period - 1e-9), round(t_join / period) + 1)
        cycle = TWO_PI / (spec.spindle_speed * cut.per_rev) if cut.per_rev else period
        t = (first + np.arange(math.ceil(cycle / period) + 1)) * period
        depth_rate = spec.radial * _helix(spec, cut, self.psi(theta_ref, t))[1][:, 0]
        t_out = float(t[np.flatnonzero(depth_rate <= 1e-12)[0]])
        state = self._state(cut, theta_ref, t_out)
        retract = self._ramps.reach("x", state[0].tolist(), [self.x_clear, 0.0, 0.0])
        z = self.machine.axis("z")
        stop = velocity_trajectory(list(state[1, :1]), list(state[1, 1:2]), list(state[1, 2:]), [0.0],
                                   [z.max_velocity], [z.max_acceleration], [RAMP_JERK_SHARE * z.max_jerk])
        return t_out, retract, stop

    @staticmethod
    def _sample(track: list[Stretch], t: np.ndarray) -> np.ndarray:
        """(3, len(t)) of one axis at sorted t: each stretch from its start until the next
        begins (the first one before its start too)."""
        out = np.empty((3, t.size))
        bounds = np.searchsorted(t, [begin for begin, _ in track[1:]], side="left").tolist()
        for (_, stretch), lo, hi in zip(track, [0] + bounds, bounds + [t.size]):
            if hi > lo:
                out[:, lo:hi] = stretch(t[lo:hi])
        return out

    def ideal(self, t: np.ndarray) -> np.ndarray:
        """(3, len(t), 2): the motion itself (what the feedback should do)."""
        return np.stack([self._sample(track, t) for track in self.tracks], 2)

    def _compensate(self, drive: DriveModel) -> None:
        n = math.ceil((self.duration + COMPENSATION_TAIL) / self.period) + 1
        p, v, a = self.ideal(np.arange(n) * self.period)
        # settled within a fraction of an encoder count: below that it is quantisation the
        # learning picked up from the simulated encoder, not lag
        tolerance = SETTLED_COUNTS * float(np.min(drive.resolution))
        self._correction = learned_command(drive, p, v, a, round(LEAD_TIME / self.period) // 2,
                                           round(self.duration / self.period), self.period, COMPENSATION_BAND,
                                           tolerance)
        self.duration = (self._correction.shape[1] - 1) * self.period

    def sample_all(self, t: np.ndarray) -> np.ndarray:
        """(3, len(t), 2): the command at cycle times t (cached: x and z ask alike)."""
        key = (t.size, float(t[0]), float(t[-1])) if t.size else (0, 0.0, 0.0)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = self.ideal(t)
        if self._correction is not None:
            grid = np.arange(self._correction.shape[1]) * self.period
            for k in range(3):
                for j in range(2):
                    out[k, :, j] += np.interp(t, grid, self._correction[k, :, j], right=0.0)
        self._cache = (key, out)
        return out

    def sampler(self, joint: int):
        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            out = self.sample_all(t)
            return out[0][:, joint], out[1][:, joint], out[2][:, joint]

        return sample


def plan_thread(builder: PlanBuilder, spec: ThreadSpec, servo_period: float = 1e-3,
                compensate: bool = True) -> list[dict]:
    """Append the whole thread cycle to the builder; returns one JSON-ready dict per pass.

    Spindle to speed; the tool to the cycle start (clearance radius, start_z; from wherever
    it is, clear of the stock); every pass and start as one ThreadCycle (drive-compensated
    unless `compensate` is False); finally back to the cycle start. Events: "thread_pass"
    as each pass's air path begins, "sync" where it is on its helix.

    Raises:
        ThreadError: check_thread's rejections (before anything is added), or a pass whose
            helix cannot be reached before the face (the builder is then half-built: discard it).
    """
    machine = builder.machine
    check_thread(spec, machine)
    x_origin, z_origin = spec.origin
    drive = DriveModel(machine, servo_period, joints=JOINTS) if compensate else None
    spindle = builder.timelines[SPINDLE]
    builder.spindle(spec.spindle_speed)
    builder.rapid({"x": x_origin + spec.clear_radius, "z": z_origin + spec.start_z})
    t_ready = max(builder.end_time(list(JOINTS)) + SETTLE_TIME, builder.spindle_ready + SPINDLE_SETTLE)
    t0 = math.ceil(t_ready / servo_period - 1e-9) * servo_period
    cycle = ThreadCycle(spec, machine, servo_period, spindle.position_at(t0), drive)
    for j, joint in enumerate(JOINTS):
        builder.timelines[joint].add(Piece(t0, cycle.duration, cycle.sampler(j)), cycle.end[j])
    report = []
    for c in cycle.cuts:
        cut = c.cut
        info = {
            "index": cut.index, "start": c.start, "spring": cut.spring,
            "depth_mm": to_mm(cut.depth), "doc_mm": to_mm(cut.doc),
            "amplitude_mm": to_mm(cut.amplitude),
            "vibration_per_rev": cut.per_rev or None,
            "vibration_phase_deg": cut.phase * 360.0 if cut.amplitude else None,
            "spindle_phase_deg": math.degrees(TWO_PI * c.start / spec.starts),
            "t_start": t0 + c.t_begin, "t_sync": t0 + c.t_join, "t_end": t0 + c.t_end,
        }
        builder.event(info["t_start"], "thread_pass", **{k: info[k] for k in (
            "index", "start", "spring", "depth_mm", "doc_mm", "amplitude_mm",
            "vibration_per_rev", "vibration_phase_deg")})
        builder.event(info["t_sync"], "sync", index=cut.index, start=c.start,
                      spindle_phase_deg=info["spindle_phase_deg"])
        report.append(info)
    builder.rapid({"z": z_origin + spec.start_z})
    return report
