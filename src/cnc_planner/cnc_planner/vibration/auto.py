"""``vibration: auto``: the planner picks the chip-breaking waveform the axis can follow.

A machinist knows the feed per revolution and the spindle speed the tool wants; which D, Q
(or E, R, Q) break the chip at that speed on this machine is the planner's to work out.
The candidates, shortest chip first:

- D 1.5: an air-cut in every revolution (the window: 1 revolution);
- one vibration every E = 2, 3, ... MAX_E revolutions, R of them in the retreat (the
  window: E revolutions). The jerk a vibration needs falls roughly with E^2, so a fast
  spindle still breaks its chip every few revolutions.

Each candidate's Q is the smallest that re-enters an earlier revolution, plus Q_MARGIN of it
(the seed's D 1.5 Q 1.2 is D 1.5 with that margin), rounded up to Q_STEP; its R the one with
the highest spindle speed. The first candidate that the axis follows at the job's speed
with SPEED_HEADROOM to spare, and whose predicted feedback (a few windows of feed run
through the drive model, pre-compensated as the planner commands it) breaks every chip
within its window, is chosen.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from cnc_msgs_py.machine import Axis

from cnc_planner.vibration.waveform import TWO_PI, Vibration, VibrationError, VibrationFeed, _min_q, _speed_limits

if TYPE_CHECKING:
    from cnc_servo_bridge.drive import DriveModel

MAX_E = 8  # revolutions per vibration at most: a longer chip is hardly broken
Q_MARGIN = 0.2  # Q = (1 + margin) * the smallest Q that air-cuts, so that feedback still does
Q_STEP = 0.05
R_STEP = 0.25  # revolutions in retreat tried, in these steps
SPEED_HEADROOM = 0.95  # the axis follows the waveform at up to this share of its limits' speed
TRIAL_WINDOWS = 6  # feed length of the feedback check, in windows (plus the ramps)


@dataclass(frozen=True)
class Candidate:
    """A waveform ``vibration`` that breaks the chip every ``window`` revolutions."""

    vibration: Vibration
    window: float

    def text(self) -> str:
        """As a job would give it."""
        v = self.vibration
        head = f"D {v.D:g}" if v.D is not None else f"E {v.E:g} R {v.R:g}"
        return f"{head} Q {v.Q:g}"


def _with_margin(q_min: float) -> float:
    return round(math.ceil(q_min * (1.0 + Q_MARGIN) / Q_STEP - 1e-9) * Q_STEP, 6)


@lru_cache(maxsize=None)
def _shapes() -> tuple[tuple[Candidate, ...], ...]:
    """The candidate waveforms per window (unitless: they do not depend on the machine);
    for each E every R in R_STEP steps, the best R for an axis chosen later."""
    out = [(Candidate(Vibration(D=1.5, Q=_with_margin(_min_q(Vibration(D=1.5, Q=1.0)))), 1.0),)]
    for e in range(2, MAX_E + 1):
        group = []
        for k in range(1, round(e / R_STEP)):
            r = k * R_STEP
            q_min = _min_q(Vibration(D=None, Q=1.0, E=e, R=r))
            if math.isfinite(q_min):
                group.append(Candidate(Vibration(D=None, Q=_with_margin(q_min), E=e, R=r), float(e)))
        out.append(tuple(group))
    return tuple(out)


def max_speed(vib: Vibration, feed_per_rev: float, axis: Axis) -> float:
    """The highest spindle speed (rad/s) at which the axis follows the waveform."""
    return min(_speed_limits(vib, feed_per_rev, axis))[0]


def candidates(feed_per_rev: float, axis: Axis) -> list[tuple[Candidate, float]]:
    """Per window, shortest first, the waveform the axis follows fastest and that speed (rad/s)."""
    out = []
    for group in _shapes():
        best = max(group, key=lambda c: max_speed(c.vibration, feed_per_rev, axis))
        out.append((best, max_speed(best.vibration, feed_per_rev, axis)))
    return out


def feasible(feed_per_rev: float, spindle_speed: float, axis: Axis) -> list[Candidate]:
    """The candidates the axis follows at this speed with headroom, shortest window first."""
    return [c for c, top in candidates(feed_per_rev, axis) if spindle_speed <= SPEED_HEADROOM * top]


def predicted_chip(candidate: Candidate, feed_per_rev: float, spindle_speed: float, axis: Axis,
                   drive_model_factory: Callable[[], DriveModel], servo_period: float, rests: bool,
                   length: float | None = None, start_angle: float = 0.0) -> float:
    """Longest chip (revolutions) on the drive model's feedback of the feed of ``length``
    from ``start_angle`` (a trial of TRIAL_WINDOWS windows if None), commanded as the
    planner commands it; inf without an air-cut.

    ``rests``: the tool rests at the feed's end while the command settles (a move's
    feed), cutting the ring the last revolutions left, which lengthens the last chip; else
    it leaves on arrival (a drill's retract carries the settling) and the chip ends there.

    The chip is measured by the judge's own air-cut analysis, imported here rather than with
    the module: importing the planner loads none of the judge."""
    from cnc_analysis.aircut import analyze_aircut

    length = feed_per_rev * candidate.window * TRIAL_WINDOWS if length is None else length
    move = VibrationFeed(length, feed_per_rev, candidate.vibration, spindle_speed, axis, start_angle=start_angle,
                         drive_model_factory=drive_model_factory, servo_period=servo_period)
    t = np.arange(math.ceil(move.duration / servo_period) + 1) * servo_period
    s, v, a = move.sample(t)
    feedback, _ = drive_model_factory().simulate(s[:, None], v[:, None], a[:, None])
    moving = t <= (move.duration if rests else move.arrival)
    report = analyze_aircut(start_angle + spindle_speed * t[moving], feedback[moving, 0])
    return report.max_chip_revs if report.revolutions_with_aircut else math.inf


def choose_vibration(feed_per_rev: float, spindle_speed: float, axis: Axis,
                     drive_model_factory: Callable[[], DriveModel], servo_period: float,
                     rests: bool = True, length: float | None = None, start_angle: float = 0.0,
                     field: str = "vibration") -> tuple[Candidate, float]:
    """The shortest-window waveform the axis follows at this spindle speed and whose
    predicted feedback breaks every chip within its window (predicted_chip of the feed,
    or of a trial, ``rests`` as there): (candidate, predicted chip).

    Raises:
        VibrationError: none does (too fast a spindle for this axis), naming the highest
            speed at which the longest window still works.
    """
    for candidate in feasible(feed_per_rev, spindle_speed, axis):
        try:
            chip = predicted_chip(candidate, feed_per_rev, spindle_speed, axis, drive_model_factory, servo_period,
                                  rests, length, start_angle)
        except VibrationError:
            continue  # the axis cannot ramp onto it: the next, slower waveform
        if chip <= candidate.window:
            return candidate, chip
    slowest, top = candidates(feed_per_rev, axis)[-1]
    raise VibrationError(field, f"no chip-breaking vibration (D 1.5 up to one every {MAX_E} revolutions) that the "
                                f"{axis.name} axis follows at {spindle_speed * 60 / TWO_PI:.0f} rpm; "
                                f"{slowest.text()} works up to {math.floor(SPEED_HEADROOM * top * 60 / TWO_PI):.0f} rpm")


def working_alternative(vib: Vibration, feed_per_rev: float, spindle_speed: float, axis: Axis) -> str:
    """What would work on this axis instead of a refused vibration, as a refusal says it:
    the waveform with its Q raised to air-cut (if too small) at the highest speed it allows,
    and the shortest-window waveform at this speed (what ``vibration: auto`` tries first), or
    if none is fast enough, the longest window at the highest speed it allows."""
    parts = []
    q_min = _min_q(vib)
    whole = abs(vib.vibrations_per_rev - round(vib.vibrations_per_rev)) < 1e-9
    if not whole and math.isfinite(q_min) and not vib.Q > q_min:
        same = Vibration(D=vib.D, Q=_with_margin(q_min), E=vib.E, R=vib.R, corner=vib.corner)
        top = math.floor(max_speed(same, feed_per_rev, axis) * 60 / TWO_PI)
        parts.append(f"{Candidate(same, 0.0).text()} up to {top} rpm")
    here = feasible(feed_per_rev, spindle_speed, axis)
    if here:
        parts.append(f"{here[0].text()} at {spindle_speed * 60 / TWO_PI:.0f} rpm")
    elif not parts:  # nothing at this speed: the longest window, at the highest speed it allows
        slowest, top = candidates(feed_per_rev, axis)[-1]
        parts.append(f"{slowest.text()} up to {math.floor(SPEED_HEADROOM * top * 60 / TWO_PI):.0f} rpm")
    return "works: " + ", or ".join(parts) + " (vibration: auto chooses)"
