"""The checks a thread job passes before anything moves: its fields, the spindle and lead
speed, the length of a pass, the chips its vibration breaks, the axes following that
vibration, and the room before the face and within travel.

Each rejection names the job field to change and, where one exists, the value that would
do (the least Q, the highest spindle speed).
"""
from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.thread.helix import helix_peaks
from cnc_planner.kinds.thread.ramps import z_to_speed
from cnc_planner.kinds.thread.spec import JOINTS, TWO_PI, ThreadError, ThreadSpec, ThreadVibration, passes_of
from cnc_planner.vibration.waveform import lift

CHECK_POINTS_PER_REV = 720  # groove grid of the chip-breaking check
Q_MAX = 20.0  # the job schema's bound: the search for a working Q stops there
WAVE_LIMIT_SHARE = 0.95  # of each axis limit for the vibration: the compensated command
# leads the motion and runs a few per cent above it
SUGGESTED_Q = 1.2  # a refused Q <= 1 is told this (or the least that breaks the chip, if more)
D_STEP, D_TRIES = 0.5, 8  # vibrations/rev: the higher D a refusal tries, in these steps
MAX_PASS_REVS = 2000  # spindle revolutions of one pass: checks and plans sample every one
MAX_PASS_S = 600.0  # s of helix per pass: a longer pass is a mistyped pitch or speed


def _rpm(omega: float) -> float:
    return omega * 60.0 / TWO_PI


def _mm(value: float) -> str:
    return f"{to_mm(value):.4g} mm"


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
    ramp = z_to_speed(machine, (0.0, 0.0, 0.0), spec.lead_speed).duration
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
    x_deep = spec.surface(spec.end_z) + spec.radial * spec.depth
    for x in (x0 + spec.clear_radius, x0 + spec.air_radius, x0 + x_deep):
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
    judged as cnc_analysis.threads judges feedback: against the envelope of earlier passes.
    The judge's own measure, imported when a chip is checked: importing the planner loads no judge."""
    from cnc_analysis.threads import CUT_TOLERANCE, cuts_against_envelope, longest_runs

    passes = [p for p in passes_of(spec, vib) if not p.spring]
    s = spec.direction
    face, end = s * -spec.start_z / spec.pitch, s * (spec.end_z - spec.start_z) / spec.pitch
    psi = np.linspace(face, end, math.ceil((end - face) * CHECK_POINTS_PER_REV) + 1)

    @functools.cache
    def lifted(per_rev: float, phase: float) -> np.ndarray:  # passes share their rate and phase
        return lift(per_rev * psi + phase)

    depth = np.array([p.depth - p.amplitude * (1.0 - lifted(p.per_rev, p.phase)) for p in passes])
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


def _check_chips(spec: ThreadSpec, vib: ThreadVibration, machine: Machine) -> None:
    """Every vibrated pass must break its chip within CHIP_LIMIT_REVS; else name the field
    to change and a parameter set that works on this machine: phase_shift (if 180 deg
    would do), Q (the least that works), or D (the least in D_TRIES steps that works),
    with the highest spindle speed the axes follow it at where that is below the job's."""
    from cnc_analysis.threads import CHIP_LIMIT_REVS  # the judge's limit, loaded with the check (_chip_revs)

    if spec.spring_passes < 1:
        raise ThreadError(
            "thread.spring_passes", "0 with a vibration leaves the last pass's returns standing; need >= 1"
        )

    def worst(v: ThreadVibration) -> tuple[float, int]:
        revs = _chip_revs(spec, v)
        return float(revs.max()), int(np.argmax(revs)) + 1

    def breaks(q: float) -> bool:
        return worst(replace(vib, Q=q))[0] <= CHIP_LIMIT_REVS

    def least_q(q0: float) -> float | None:
        qs = np.geomspace(q0, Q_MAX, 40)
        first = next((i for i in range(1, qs.size) if breaks(qs[i])), None)
        if first is None:
            return None
        lo, hi = qs[first - 1], qs[first]
        for _ in range(12):
            mid = (lo + hi) / 2
            lo, hi = (lo, mid) if breaks(mid) else (mid, hi)
        return math.ceil(hi * 100) / 100

    if vib.Q <= 1.0:
        q = least_q(1.0)  # suggested with the margin the seed's Q 1.2 has, where that is more
        q = None if q is None else max(q, SUGGESTED_Q)
        works = f"; {_works(spec, machine, replace(vib, Q=q), f'Q {q:.2f}')}" if q is not None else ""
        raise ThreadError(
            "vibration.Q", f"{vib.Q:g} never lifts the tool out of the cut: the return must rise above the "
            f"earlier passes by more than the depth of cut (amplitude = Q x depth of cut); need Q > 1{works}"
        )
    chip, k = worst(vib)
    if chip <= CHIP_LIMIT_REVS:
        return
    told = f"leaves a continuous cut of {chip:.2f} revs in pass {k}"
    if worst(replace(vib, phase_shift=math.pi))[0] <= CHIP_LIMIT_REVS:
        raise ThreadError(
            "vibration.phase_shift", f"{math.degrees(vib.phase_shift):g} deg {told}: its returns miss "
            f"the previous pass's turning points; 180 deg puts them there"
            f" ({_works(spec, machine, replace(vib, phase_shift=math.pi), 'phase_shift 180')})"
        )
    q = least_q(vib.Q)
    if q is not None:
        raise ThreadError("vibration.Q", f"{vib.Q:g} {told}; need Q >= {q:.2f} "
                                         f"({_works(spec, machine, replace(vib, Q=q), f'Q {q:.2f}')})")
    more = next((d for d in vib.D + D_STEP * np.arange(1, D_TRIES + 1)
                 if worst(replace(vib, D=float(d)))[0] <= CHIP_LIMIT_REVS), None)
    raise ThreadError(
        "vibration.D", f"{vib.D:g} vibrations/rev (+{vib.D_step:g} per pass) {told}; the chip breaks at most "
        "once per vibration: raise D"
        + (f" ({_works(spec, machine, replace(vib, D=float(more)), f'D {more:g}')})" if more is not None else "")
    )


def _works(spec: ThreadSpec, machine: Machine, vib: ThreadVibration, named: str) -> str:
    """How a refusal names ``vib`` (the changed parameter ``named``) as working: at the
    job's spindle speed, or up to the highest the axes follow it at."""
    try:
        _check_follow(replace(spec, vibration=vib), machine)
    except ThreadError as err:
        top = str(err).rsplit("max spindle speed ", 1)[-1]
        return f"{named} works up to {top}"
    return f"{named} works at {_rpm(spec.spindle_speed):.0f} rpm"


def _check_follow(spec: ThreadSpec, machine: Machine) -> None:
    """The waveform of every pass within the x and z velocity, acceleration and jerk limits.

    Velocity grows with the spindle speed, acceleration with its square, jerk with its cube,
    so each limit gives the spindle speed at which the waveform just touches it.
    """
    omega = spec.spindle_speed
    worst = None
    for p in passes_of(spec):
        if p.spring:
            continue
        for joint, need in zip(JOINTS, helix_peaks(spec, p)):
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
        ramp = " on the tapered ends' ramp" if joint == "x" and spec.end_taper is not None else ""
        raise ThreadError(
            "vibration.D", f"the {joint} axis cannot follow {p.per_rev:g} vibrations/rev of {_mm(p.amplitude)} "
            f"(pass {p.index + 1}){ramp} at {_rpm(omega):.0f} rpm (needs {quantity} {need:.3g} {unit}, over "
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
        _check_chips(spec, spec.vibration, machine)
        _check_follow(spec, machine)
    _check_room(spec, machine)
