"""Servo drive model: one position loop with feed-forward over a first-order velocity loop.

Per axis and servo period T (all joints vectorised):

    e      = p_ref - p_measured                         following error
    v_cmd  = velocity_ff * v_ref + accel_ff * velocity_lag * a_ref + kp * e
    v_cmd  clamped to +-VELOCITY_HEADROOM * max_velocity
    v'     = v_cmd + (v - v_cmd) * exp(-T / velocity_lag)   (velocity loop lag)
    v'     rate-limited to +-ACCELERATION_HEADROOM * max_acceleration
    p'     = p + (v + v') / 2 * T
    p_measured = p' quantised to the encoder resolution

With accel_ff = 1 the velocity loop's lag is cancelled for slow references; the planner
uses the same model (this module) to predict and pre-compensate the lag.

``step`` is the reference implementation, one period at a time in numpy. ``run`` and
``simulate`` advance many periods at once through a compiled kernel that performs the
same floating-point operations in the same order, so both give the same positions
(tested to 1e-12 m, clamps and quantisation included) at a few hundred times the speed:
the planner's safety searches and the bridge's block stepping use it. The kernel is a
small C function (_drive_kernel.c) that the package's setup.py compiles when it is
installed, so a node loads a few kilobytes of machine code, not a JIT compiler (numba
and LLVM cost each node about 125 MiB of resident memory).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import Machine

from ._drive_kernel import run as _run

VELOCITY_HEADROOM = 1.2
ACCELERATION_HEADROOM = 1.5


@dataclass
class DriveState:
    """True position and velocity of every joint, and what the encoders report."""

    position: np.ndarray
    velocity: np.ndarray
    measured: np.ndarray


class DriveModel:
    """The servo drives of one machine, stepped once per servo period."""

    def __init__(self, machine: Machine, servo_period: float, joints: tuple[str, ...] | None = None):
        self.joints = joints or machine.joint_names
        self.period = servo_period
        drives = [machine.drives[j] for j in self.joints]
        axes = [machine.drive_axes[j] for j in self.joints]
        self.kp = np.array([d.kp for d in drives])
        self.velocity_ff = np.array([d.velocity_ff for d in drives])
        self.accel_ff = np.array([d.accel_ff for d in drives])
        self.lag = np.array([d.velocity_lag for d in drives])
        self.resolution = np.array([d.resolution for d in drives])
        self.following_error_limit = np.array([d.following_error_limit for d in drives])
        self.decay = np.exp(-servo_period / self.lag)
        self.v_limit = VELOCITY_HEADROOM * np.array([a.max_velocity for a in axes])
        self.dv_limit = ACCELERATION_HEADROOM * np.array([a.max_acceleration for a in axes]) * servo_period
        self.state = self.reset(np.zeros(len(self.joints)))

    def quantise(self, position: np.ndarray) -> np.ndarray:
        return np.round(position / self.resolution) * self.resolution

    def reset(self, position: np.ndarray) -> DriveState:
        """Put the drives at rest at a position (power-up, or after a restart)."""
        position = np.asarray(position, dtype=float).copy()
        self.state = DriveState(position, np.zeros_like(position), self.quantise(position))
        return self.state

    def step(self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray) -> np.ndarray:
        """Advance one servo period towards the reference; returns the following error."""
        s = self.state
        error = p_ref - s.measured
        v_cmd = self.velocity_ff * v_ref + (self.accel_ff * self.lag) * a_ref + self.kp * error
        v_cmd = np.clip(v_cmd, -self.v_limit, self.v_limit)
        v_new = v_cmd + (s.velocity - v_cmd) * self.decay
        v_new = s.velocity + np.clip(v_new - s.velocity, -self.dv_limit, self.dv_limit)
        s.position = s.position + 0.5 * (s.velocity + v_new) * self.period
        s.velocity = v_new
        s.measured = self.quantise(s.position)
        return error

    def run(
        self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the drives once per reference row (shape (n, joints)) from their state.

        Row i of the result is what the encoders read (measured position, velocity and
        following error) before step i, as ``step`` would give it row by row.
        """
        p_ref, v_ref, a_ref = (np.ascontiguousarray(x, dtype=float).reshape(-1, len(self.joints))
                               for x in (p_ref, v_ref, a_ref))
        s = self.state
        s.position, s.velocity, s.measured = (np.array(x, dtype=float) for x in (s.position, s.velocity, s.measured))
        out = np.empty((3, *p_ref.shape))
        _run(p_ref, v_ref, a_ref, s.position, s.velocity, s.measured, self.kp, self.velocity_ff,
             self.accel_ff * self.lag, self.decay, self.v_limit, self.dv_limit, self.resolution,
             self.period, out)
        return out[0], out[1], out[2]

    def simulate(
        self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Run the drives over references sampled every servo period (shape (n, joints)).

        The drives start at rest at the first reference. Row i of the result is what the
        encoders read at the time of reference row i, before that period's step: exactly
        what the bridge publishes for that instant, computed offline.
        """
        self.reset(p_ref[0])
        positions, velocities, _ = self.run(p_ref, v_ref, a_ref)
        return positions, velocities


def warm_up() -> None:
    """Run the compiled kernel once at a node's start, so a kernel that does not load or
    run fails there and not on the first job's clock."""
    one = np.zeros((1, 1))
    state = [np.zeros(1) for _ in range(3)]
    _run(one, one, one, *state, *(np.ones(1) for _ in range(4)), np.ones(1), np.ones(1), np.ones(1),
         1e-3, np.empty((3, 1, 1)))
