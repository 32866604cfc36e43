"""Jerk-limited motion primitives, all computed by ruckig.

Rapids are time-optimal multi-axis point-to-point moves (axes time-synchronised so they
start and arrive together); linear feed moves are one ruckig profile along the path
length with limits projected onto the path direction; spindle changes and stops use
ruckig's velocity interface.
"""
from __future__ import annotations

import threading
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from cnc_msgs_py.machine import Axis
from cnc_planner.motion.jerk_profile import TrajectorySampler
from cnc_servo_bridge.stop import velocity_trajectory

# Avoid zero-length divisions and ruckig's numerical floor on tiny moves.
MIN_MOVE = 1e-9
_FOUND = frozenset((Result.Working, Result.Finished))  # ruckig's results that hold a trajectory


class MotionError(ValueError):
    """Ruckig found no trajectory for the requested move."""


@dataclass(frozen=True)
class Limits:
    velocity: float
    acceleration: float
    jerk: float


def axis_limits(axis: Axis) -> Limits:
    return Limits(axis.max_velocity, axis.max_acceleration, axis.max_jerk)


class _SampleScope(threading.local):
    """This thread's open ``shared_samples`` scopes and the samples taken within them."""

    def __init__(self) -> None:
        self.depth = 0
        self.samples: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # key -> (instants, samples)


_scope = _SampleScope()


@contextmanager
def shared_samples() -> Iterator[None]:
    """Within this scope a move asked for the same instants again (by each joint of one
    plan sample) is evaluated once; the samples are dropped when the outermost scope ends.
    (A cache kept in every move instead kept its last, often 30 s long, sample alive with
    the plan: ~24 MiB per 500-move segment held by the planner node.)"""
    _scope.depth += 1
    try:
        yield
    finally:
        _scope.depth -= 1
        if _scope.depth == 0:
            _scope.samples.clear()


class RuckigMove:
    """A ruckig trajectory over several degrees of freedom, sampled on demand."""

    def __init__(self, trajectory: Trajectory) -> None:
        self.trajectory = trajectory
        self._sampler: TrajectorySampler | None = None  # built on first use: most searched moves are never sampled

    @property
    def duration(self) -> float:
        return self.trajectory.duration

    def sample_all(self, t: np.ndarray) -> np.ndarray:
        """Array (3, len(t), dofs): position, velocity, acceleration."""
        if _scope.depth == 0:
            return self._sample(t)
        # The key holds the move itself (compared by identity), so it cannot outlive it; a
        # hit is used only for the very same instants (pieces of one move at other times
        # share the key's ends but not always every instant between them).
        key = (self, len(t), float(t[0]), float(t[-1])) if len(t) else (self, 0, 0.0, 0.0)
        held = _scope.samples.get(key)
        if held is None or not np.array_equal(held[0], t):
            held = _scope.samples[key] = (t, self._sample(t))
        return held[1]

    def _sample(self, t: np.ndarray) -> np.ndarray:
        if self._sampler is None:
            self._sampler = TrajectorySampler(self.trajectory)
        return self._sampler.sample(t)

    def sampler(self, dof: int) -> DofSampler:
        """A sampler of one degree of freedom, for a JointTimeline piece."""
        return DofSampler(self, dof)

    def row(self, dof: int) -> np.ndarray:
        """The dof's phases as a row of jerk_profile.sample_spans' table."""
        if self._sampler is None:
            self._sampler = TrajectorySampler(self.trajectory)
        return self._sampler.rows[dof]


class DofSampler:
    """One degree of freedom of a RuckigMove as a timeline piece's sampler: an object, not
    a closure, so that a timeline can sample a run of such pieces in one call (sample_spans)."""

    __slots__ = ("move", "dof")

    def __init__(self, move: RuckigMove, dof: int) -> None:
        self.move = move
        self.dof = dof

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        out = self.move.sample_all(t)
        return out[0][:, self.dof], out[1][:, self.dof], out[2][:, self.dof]


def point_to_point(start: list[float], target: list[float], limits: list[Limits]) -> RuckigMove:
    """Time-optimal, time-synchronised move from rest to rest."""
    inp = InputParameter(len(start))
    inp.current_position = list(start)
    inp.target_position = list(target)
    inp.max_velocity = [lim.velocity for lim in limits]
    inp.max_acceleration = [lim.acceleration for lim in limits]
    inp.max_jerk = [lim.jerk for lim in limits]
    return RuckigMove(calculate(inp))


def calculate(inp: InputParameter, ruckig: Ruckig | None = None) -> Trajectory:
    """Run ruckig offline on a prepared input (with ``ruckig`` of as many degrees of
    freedom, if given: a search that calls it a thousand times saves building one each time).

    Raises:
        MotionError: ruckig found no trajectory.
    """
    trajectory = Trajectory(inp.degrees_of_freedom)
    try:
        result = (ruckig or Ruckig(inp.degrees_of_freedom)).calculate(inp, trajectory)
    except RuckigError as err:  # invalid input is raised, not returned
        raise MotionError(f"ruckig could not plan the move: {str(err).strip()}") from err
    if result not in _FOUND:
        raise MotionError(f"ruckig could not plan the move ({result.name})")
    return trajectory


def path_limits(direction: np.ndarray, limits: list[Limits], feed: float | None) -> Limits:
    """Limits along a straight path so that no axis exceeds its own."""
    share = np.abs(direction)
    moving = share > 1e-12

    def along(values: list[float]) -> float:
        return float(np.min(np.asarray(values)[moving] / share[moving]))

    velocity = along([lim.velocity for lim in limits])
    if feed is not None:
        velocity = min(velocity, feed)
    return Limits(velocity, along([lim.acceleration for lim in limits]), along([lim.jerk for lim in limits]))


class LinearMove:
    """A straight move at a feed rate: one ruckig profile of the path length s."""

    def __init__(self, start: np.ndarray, end: np.ndarray, limits: list[Limits], feed: float | None):
        self.start = np.asarray(start, dtype=float)
        delta = np.asarray(end, dtype=float) - self.start
        self.length = float(np.linalg.norm(delta))
        self.direction = delta / max(self.length, MIN_MOVE)
        self.limits = path_limits(self.direction, limits, feed)
        self.profile = point_to_point([0.0], [self.length], [self.limits])

    @property
    def duration(self) -> float:
        return self.profile.duration

    def sampler(self, dof: int):
        d = self.direction[dof]
        p0 = self.start[dof]

        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            s = self.profile.sample_all(t)
            return p0 + d * s[0][:, 0], d * s[1][:, 0], d * s[2][:, 0]

        return sample


def velocity_change(
    position: list[float], velocity: list[float], acceleration: list[float],
    target_velocity: list[float], limits: list[Limits],
) -> RuckigMove:
    """Jerk-limited change to a target velocity (spindle ramps, controlled stops)."""
    return RuckigMove(velocity_trajectory(
        position, velocity, acceleration, target_velocity,
        [lim.velocity for lim in limits], [lim.acceleration for lim in limits], [lim.jerk for lim in limits],
    ))
