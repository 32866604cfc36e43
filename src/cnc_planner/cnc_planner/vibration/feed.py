"""Straight feed moves at a feed per spindle revolution, vibrated for chip breaking if the job asks.

Move and turn jobs feed this way; drilling and threads vibrate inside their own cycles.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion import SERVO_PERIOD
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import axis_limits, path_limits
from cnc_planner.motion.timeline import Piece
from cnc_planner.vibration.waveform import Vibration, VibrationError, VibrationFeed, er_vibration


TWO_PI = 6.283185307179586
MAX_VIBRATION_FEED_S = 600.0  # one vibrated feed move at most this long: its compensation is
# precomputed on the servo grid, so its memory grows with its duration


def vibration_of(job: SimpleNamespace) -> Vibration | None:
    """The job's vibration; E and R without Q take the method's straight-stroke waveform
    (vibration.er_vibration)."""
    v = job.vibration
    if v is None:
        return None
    return Vibration(D=v.D, Q=v.Q, E=v.E, R=v.R) if v.Q is not None else er_vibration(v.E, v.R)


def vibration_error(err: VibrationError) -> JobError:
    """A VibrationError as the JobError naming the same vibration field."""
    return JobError(err.field, err.reason)


def feed_move(builder: PlanBuilder, target: dict[str, float], feed_per_rev: float,
              vibration: Vibration | None, field: str) -> float:
    """A straight feed at ``feed_per_rev`` of the turning spindle, with chip-breaking
    vibration along the path if given; returns the end time.

    The vibration is locked to the spindle angle, so the move starts once the spindle
    runs at speed; the drive model of the axis that moves most pre-compensates it.
    """
    machine = builder.machine
    speed = builder.timelines[SPINDLE].end_velocity
    if vibration is None:
        return builder.linear(target, feed_per_rev * abs(speed) / TWO_PI)
    joints = list(target)
    p0 = np.array([builder.position(j) for j in joints])
    delta = np.array([target[j] for j in joints]) - p0
    length = float(np.linalg.norm(delta))
    start = max(builder.end_time(), builder.spindle_ready)
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
    try:
        move = VibrationFeed(length, feed_per_rev, vibration, abs(speed), along,
                             start_angle=builder.timelines[SPINDLE].position_at(start),
                             drive_model_factory=lambda: DriveModel(machine, SERVO_PERIOD, (lead,)))
    except VibrationError as err:
        if not err.field.startswith("vibration"):  # about the move itself (e.g. its length)
            raise JobError(field, str(err)) from err
        raise vibration_error(err) from err
    builder.event(start, "vibration_feed", start=p0.tolist(), direction=direction.tolist(),
                  joints=joints, length=length, feed_per_rev=feed_per_rev, field=field)
    for dof, joint in enumerate(joints):
        builder.timelines[joint].add(Piece(start, move.duration, _along(move, p0[dof], direction[dof])),
                                     float(target[joint]))
    builder.event(start + move.duration, "vibration_end")
    return start + move.duration


def _along(move: VibrationFeed, p0: float, d: float):
    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, v, a = move.sample(t)
        return p0 + d * s, d * v, d * a
    return sample
