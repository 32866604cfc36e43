"""Straight feed moves at a feed per spindle revolution, vibrated for chip breaking if the job asks.

Move and turn jobs feed this way; drilling and threads vibrate inside their own cycles.
``vibration: auto`` is resolved here for every kind that takes the feed's waveform (resolved).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.job import AUTO
from cnc_msgs_py.machine import SPINDLE, Axis
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import axis_limits, path_limits
from cnc_planner.motion.timeline import Piece
from cnc_planner.vibration.auto import choose_vibration, working_alternative
from cnc_planner.vibration.waveform import Vibration, VibrationError, VibrationFeed, er_vibration


TWO_PI = 6.283185307179586
MAX_VIBRATION_FEED_S = 600.0  # one vibrated feed move at most this long: its compensation is
# precomputed on the servo grid, so its memory grows with its duration
MAX_CHOSEN = 256  # choose_vibration's answers kept (it runs the drive model): a node plans for long
_CHOSEN: dict[tuple, tuple] = {}


def vibration_of(job: SimpleNamespace) -> Vibration | str | None:
    """The job's vibration, or AUTO (``vibration: auto``: the waveform is chosen per feed,
    resolved); E and R without Q take the method's straight-stroke waveform
    (vibration.er_vibration)."""
    v = job.vibration
    if v is None:
        return None
    if v == AUTO:
        return AUTO
    return Vibration(D=v.D, Q=v.Q, E=v.E, R=v.R) if v.Q is not None else er_vibration(v.E, v.R)


def vibration_error(err: VibrationError, vib: Vibration | None = None, feed_per_rev: float = 0.0,
                    spindle_speed: float = 0.0, axis: Axis | None = None) -> JobError:
    """A VibrationError as the JobError naming the same vibration field; given the refused
    waveform and where it ran, the reason also names a parameter set that works there."""
    reason = err.reason
    if vib is not None and axis is not None and err.field.startswith("vibration"):
        reason = f"{reason}; {working_alternative(vib, feed_per_rev, spindle_speed, axis)}"
    return JobError(err.field, reason)


def resolved(vibration: Vibration | str, feed_per_rev: float, spindle_speed: float, axis: Axis,
             drive_model_factory: Callable[[], DriveModel], servo_period: float,
             rests: bool = True, length: float | None = None, start_angle: float = 0.0) -> tuple[Vibration, dict]:
    """The waveform a feed vibrates with: the job's, or (AUTO) the one choose_vibration picks
    for this axis, feed and speed, judged on the feed of ``length`` from ``start_angle``
    (``rests``: the tool rests at the feed's end while the command settles, as after
    feed_move); with what an event records of it."""
    if vibration != AUTO:
        return vibration, {"auto": False, **_parameters(vibration)}
    drive = drive_model_factory()
    key = (round(feed_per_rev, 12), round(spindle_speed, 9), axis, servo_period, rests,
           None if length is None else round(length, 9), round(math.fmod(start_angle, TWO_PI), 9),
           tuple(np.concatenate([np.ravel(x) for x in (drive.kp, drive.velocity_ff, drive.accel_ff, drive.lag,
                                                       drive.resolution)]).tolist()))
    if key not in _CHOSEN:  # a drill's holes, a turn job's passes of one length
        if len(_CHOSEN) >= MAX_CHOSEN:
            _CHOSEN.clear()
        try:
            _CHOSEN[key] = choose_vibration(feed_per_rev, spindle_speed, axis, drive_model_factory, servo_period,
                                            rests, length, start_angle)
        except VibrationError as err:
            raise vibration_error(err) from err
    chosen, chip = _CHOSEN[key]
    return chosen.vibration, {"auto": True, **_parameters(chosen.vibration), "window_revs": chosen.window,
                              "predicted_chip_revs": round(chip, 3)}


def _parameters(vib: Vibration) -> dict:
    if vib.D is not None:
        return {"D": vib.D, "Q": vib.Q}
    return {"E": vib.E, "R": vib.R, "Q": round(vib.Q, 6)}


def feed_move(builder: PlanBuilder, target: dict[str, float], feed_per_rev: float,
              vibration: Vibration | str | None, field: str) -> float:
    """A straight feed at ``feed_per_rev`` of the turning spindle, with chip-breaking
    vibration along the path if given (AUTO: chosen for this move); returns the end time.

    The vibration is locked to the spindle angle, so the move starts once the spindle
    runs at speed; the drive model of the axis that moves most pre-compensates it. It
    ends on arrival at ``target``: the command's settling is carried by whatever its axes
    do next (JointTimeline.carry), so the tool does not rest there while it settles.
    """
    machine = builder.machine
    speed = builder.timelines[SPINDLE].end_velocity
    if vibration is None:
        return builder.linear(target, feed_per_rev * abs(speed) / TWO_PI)
    joints = list(target)
    p0 = np.array([builder.position(j) for j in joints])
    delta = np.array([target[j] for j in joints]) - p0
    length = float(np.linalg.norm(delta))
    start = max(builder.free_from(joints), builder.spindle_ready)
    if length <= 1e-12:
        return start
    direction = delta / length
    lim = path_limits(direction, [axis_limits(machine.axes[j]) for j in joints], None)
    lead = joints[int(np.argmax(np.abs(direction)))]  # errors name the axis that moves most
    along = replace(machine.axes[lead], max_velocity=lim.velocity,
                    max_acceleration=lim.acceleration, max_jerk=lim.jerk)
    seconds = length / (feed_per_rev * abs(speed) / TWO_PI)
    if seconds > MAX_VIBRATION_FEED_S:
        raise JobError(f"{field}.feed", f"a vibrated feed of {to_mm(length):.4g} mm lasts {seconds:.4g} s at this "
                       f"feed and spindle speed, more than the maximum {MAX_VIBRATION_FEED_S:g} s")
    drive = lambda: DriveModel(machine, SERVO_PERIOD, (lead,))  # noqa: E731
    angle = builder.timelines[SPINDLE].position_at(start)
    vibration, chosen = resolved(vibration, feed_per_rev, abs(speed), along, drive, SERVO_PERIOD,
                                 rests=False, length=length, start_angle=angle)
    try:
        move = VibrationFeed(length, feed_per_rev, vibration, abs(speed), along,
                             start_angle=angle, drive_model_factory=drive)
    except VibrationError as err:
        if not err.field.startswith("vibration"):  # about the move itself (e.g. its length)
            raise JobError(field, str(err)) from err
        raise vibration_error(err, vibration, feed_per_rev, abs(speed), along) from err
    builder.event(start, "vibration_feed", start=p0.tolist(), direction=direction.tolist(),
                  joints=joints, length=length, feed_per_rev=feed_per_rev, field=field, vibration=chosen)
    # the feed ends on arrival: the next move starts there and carries the command's
    # settling (a retract leaves at once instead of resting on the ring the last
    # revolution left), as a drill's retract does
    arrival = move.settle_start
    for dof, joint in enumerate(joints):
        timeline = builder.timelines[joint]
        timeline.add(Piece(start, arrival, _along(move, p0[dof], direction[dof])), float(target[joint]))
        if move.duration > arrival and direction[dof] != 0.0:
            timeline.carry(start + arrival, start + move.duration, _settling(move, start, direction[dof]))
    builder.event(start + arrival, "vibration_end")
    return start + arrival


def _settling(move: VibrationFeed, start: float, d: float):
    def correction(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, v, a = move.settling(t - start)
        return d * s, d * v, d * a
    return correction


def _along(move: VibrationFeed, p0: float, d: float):
    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, v, a = move.sample(t)
        return p0 + d * s, d * v, d * a
    return sample
