"""Rigid tapping (G33.1): in at the lead per spindle revolution, the spindle reversed at the
bottom, out locked to it.

As a G33 pass, the tap waits at rest for the spindle's index and ramps onto its lock (the
tool v T / 2 behind an ideal start at the index once the ramp is over). From then on the
tool's progress into the hole is the lead times the spindle's turns since, whatever the
spindle does: near the bottom the spindle is ramped down to rest and up to the reverse
speed (jerk-limited, within its own limits and within the tap axes' acceleration and jerk
through the lead), and the tool follows it down to the bottom, where the spindle stands,
and back out along the same helix. It ramps off the lock onto the start (the last ramp
centred where the ideal retract arrives), and the spindle then turns forward again.
"""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.sync.passes import TWO_PI, ramp, ramp_time
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import Limits, velocity_change
from cnc_planner.motion.timeline import JointTimeline, Piece, WritingSampler


def reversal_limits(machine: Machine, joints: list[str], direction: np.ndarray, lead: float) -> Limits:
    """The spindle's limits for its reversal: its own, or less where the tool, locked to it at
    lead / 2pi per radian, would exceed an axis's acceleration or jerk."""
    spindle = machine.axes[SPINDLE]
    per_rad = lead / TWO_PI * np.abs(direction)
    moving = per_rad > 0.0
    axes = [machine.axes[j] for j, m in zip(joints, moving) if m]
    return Limits(spindle.max_velocity,
                  min([spindle.max_acceleration] + [a.max_acceleration / k for a, k in zip(axes, per_rad[moving])]),
                  min([spindle.max_jerk] + [a.max_jerk / k for a, k in zip(axes, per_rad[moving])]))


class _Tap(WritingSampler):
    """One axis of the tap, from the index: start + direction * lead * phi / 2pi, phi the
    spindle's turns since the index as the tool follows them (ramped on and off)."""

    def __init__(self, spindle: JointTimeline, index: float, omega: float, ramp_width: float,
                 reverse: tuple[float, float, float], off_at: float, start: float, per_rad: float) -> None:
        """``reverse``: when (tap time) the spindle starts to stop, phi and its angle then."""
        self.spindle, self.index, self.omega, self.width = spindle, index, omega, ramp_width
        self.reverse_at, self.phi_reverse, self.theta_reverse = reverse
        self.off_at, self.start, self.per_rad = off_at, start, per_rad

    def write(self, t: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        p, v, a = ramp(t - self.width / 2.0, self.width)
        phi, dphi, ddphi = self.omega * p, self.omega * v, self.omega * a
        late = t >= self.reverse_at
        if late.any():
            theta, omega, alpha = self.spindle.sample(self.index + t[late])
            off, doff, ddoff = ramp(t[late] - self.off_at, self.width)
            phi[late] = self.phi_reverse + theta - self.theta_reverse + self.omega * off
            dphi[late], ddphi[late] = omega + self.omega * doff, alpha + self.omega * ddoff
        out[0][:], out[1][:], out[2][:] = self.start + self.per_rad * phi, self.per_rad * dphi, self.per_rad * ddphi


def plan_tap(builder: PlanBuilder, joints: list[str], bottom: np.ndarray, lead: float, field: str,
             ease: float = 1.0) -> tuple[float, float]:
    """Append a rigid tap from where the axes stand to ``bottom`` (axis positions, m) and
    back, at ``lead`` (m per revolution); the spindle turning forward at its speed before and
    after. ``ease``: the ramps onto and off the lock that many times as long as the axes'
    limits allow (acceleration / ease, jerk / ease^2; kinds.sync.margin); the spindle's
    reversal keeps its limits (the tool follows it through the lead, the lock barely moves).
    Returns (index time, end time).

    Raises:
        JobError: a lead faster than an axis may go, or a hole too shallow for the ramps and
            the spindle's reversal (named by ``field``).
    """
    machine = builder.machine
    spindle = builder.timelines[SPINDLE]
    omega = spindle.end_velocity
    start = np.array([builder.position(j) for j in joints])
    depth = float(np.linalg.norm(bottom - start))
    if depth <= 1e-12:
        raise JobError(field, "taps nowhere: the bottom is where the tool stands")
    direction = (bottom - start) / depth
    velocity = direction * lead * omega / TWO_PI
    for j, joint in enumerate(joints):
        if abs(velocity[j]) > machine.axes[joint].max_velocity:
            raise JobError(field, f"{to_mm(abs(velocity[j])) * 60:.6g} mm/min (lead x rpm) drives {joint} faster "
                                  f"than its {to_mm(machine.axes[joint].max_velocity) * 60:g} mm/min")
    width = ramp_time(velocity, np.array([machine.axes[j].max_acceleration for j in joints]) / ease,
                      np.array([machine.axes[j].max_jerk for j in joints]) / ease**2)
    limits = reversal_limits(machine, joints, direction, lead)
    coasting = velocity_change([0.0], [omega], [0.0], [0.0], [limits])
    coast = float(coasting.trajectory.at_time(coasting.duration)[0][0])  # the spindle's turn while it stops
    phi_bottom = depth * TWO_PI / lead
    reverse_at = width / 2.0 + (phi_bottom - coast) / omega  # the ideal start is half a ramp after the index
    if reverse_at < width:
        raise JobError(field, f"too shallow to tap at this lead and speed: the ramp and the spindle's reversal "
                              f"need {to_mm(lead * (omega * width / 2.0 + coast) / TWO_PI):.3g} mm")
    ready = max(builder.free_from(joints), builder.spindle_ready, spindle.end_time)
    index = ready + (-spindle.position_at(ready)) % TWO_PI / omega
    theta_reverse = spindle.position_at(index + reverse_at)
    stop = velocity_change([theta_reverse], [omega], [0.0], [0.0], [limits])
    theta_bottom = float(stop.trajectory.at_time(stop.duration)[0][0])
    spindle.add(Piece(index + reverse_at, stop.duration, stop.sampler(0)), theta_bottom, 0.0)
    back = velocity_change([theta_bottom], [0.0], [0.0], [-omega], [limits])
    theta_back = float(back.trajectory.at_time(back.duration)[0][0])
    spindle.add(Piece(index + reverse_at + stop.duration, back.duration, back.sampler(0)), theta_back, -omega)
    reversed_at = reverse_at + stop.duration + back.duration  # the spindle at -omega from here (tap time)
    off_at = reversed_at + (phi_bottom + theta_back - theta_bottom) / omega  # where the ideal retract arrives
    if off_at - width / 2.0 < reversed_at:
        raise JobError(field, "too shallow to tap at this lead and speed: the retract has no room to ramp off")
    duration = off_at + width / 2.0
    phi_reverse = omega * (reverse_at - width / 2.0)
    for j, joint in enumerate(joints):
        sampler = _Tap(spindle, index, omega, width, (reverse_at, phi_reverse, theta_reverse), off_at,
                       float(start[j]), float(direction[j] * lead / TWO_PI))
        builder.timelines[joint].add(Piece(index, duration, sampler), float(start[j]))
    builder.spindle(omega, start=index + duration)
    return index, index + duration
