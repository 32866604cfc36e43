"""S3, the retract out of a hole up to the plane X/Y moves above, and the law it follows.

The retract law (mode) trades time below R against time in the air:
  1  deep, wide pitch: full acceleration out of the hole, rapid reached before R;
  2  shallow: full acceleration up to R, the speed at R still below rapid;
  3  close pitch: Z reaches R at a chosen lower speed with zero acceleration, so it starts
     decelerating before R (the closer the pitch, the lower the speed, the earlier);
     the short X/Y move then does not wait for a high, long arc.
Auto picks, per hole, the law with the shortest retract + arc time for the next X/Y move.
After the last hole Z comes to rest above R (RETURN_CLEARANCE).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE, DrillError
from cnc_planner.kinds.drill.z_axis import ZAxis, crossing, z_move, z_state
from cnc_planner.motion.moves import Limits, RuckigMove

MODE3_GRID = 24  # retract speeds tried per level of the mode-3 search


@dataclass(frozen=True)
class Retract:
    """S3 of one hole up to the R plane: the law (mode), its move and the state at R."""

    mode: int
    move: RuckigMove
    t_r: float
    state: tuple[float, float, float]


@dataclass(frozen=True)
class LastRetract:
    """S3 of the last hole to rest above R: the law, the move, its time at R and the
    move that stops it above R (None where the move itself comes to rest)."""

    mode: int
    move: RuckigMove
    t_r: float
    stop: RuckigMove | None


# The retract search asks every hole the same questions (the same speeds, the same arcs
# from the same states): each is answered by ruckig once.
@lru_cache(maxsize=4096)
def _slow_exit(z: Limits, bottom_z: float, r_z: float, speed: float) -> Retract | None:
    move = z_move(z, bottom_z, 0.0, 0.0, r_z, speed)
    extrema = move.trajectory.position_extrema[0]
    if extrema.min < bottom_z - 1e-9 or extrema.max > r_z + 1e-9:
        return None
    return Retract(3, move, move.duration, (r_z, speed, 0.0))


@lru_cache(maxsize=4096)
def _arc_time(z: Limits, state: tuple[float, float, float], r_z: float, feed: float) -> float:
    """Duration of the fastest air arc from ``state`` to R at cutting feed (air.arc)."""
    return z_move(z, *state, r_z, -feed, 0.0).duration


class RetractLaw:
    """The retract of each hole: forced by ``mode`` (1, 2, 3) or, with None, the fastest
    retract and air arc for the time the next X/Y move needs."""

    def __init__(self, z: ZAxis, mode: int | None):
        self.z = z
        self.mode = mode
        self._exits: dict[tuple[float, float], Retract] = {}

    def fast_exit(self, bottom: float, plane: float) -> Retract:
        """Full acceleration out of a hole from ``bottom`` up through the X/Y ``plane``:
        mode 1 if rapid is reached below it, else 2."""
        if (bottom, plane) not in self._exits:
            z = self.z.turn
            run = z_move(z, bottom, 0.0, 0.0, None, z.velocity)
            if z_state(run, run.duration)[0] <= plane:
                move = z_move(z, bottom, 0.0, 0.0, plane, z.velocity)
                self._exits[(bottom, plane)] = Retract(1, move, move.duration, (plane, z.velocity, 0.0))
            else:
                t_r = crossing(run, plane)
                self._exits[(bottom, plane)] = Retract(2, run, t_r, z_state(run, t_r))
        return self._exits[(bottom, plane)]

    def cost(self, retract: Retract, air_needed: float) -> float:
        """Time from the bottom to R at feed over the next hole: retract plus air arc."""
        return retract.t_r + max(_arc_time(self.z.rapid, retract.state, retract.state[0], self.z.feed), air_needed)

    def _best_slow_exit(self, air_needed: float, bottom: float, plane: float) -> Retract:
        """Mode 3: the speed at the X/Y plane (zero acceleration there) that costs least,
        on a grid refined once around the best."""
        top = self.fast_exit(bottom, plane).state[1]
        speeds = np.linspace(0.0, top, MODE3_GRID + 1)[:-1]
        for _ in range(2):
            found = [r for r in (_slow_exit(self.z.turn, bottom, plane, float(v)) for v in speeds) if r is not None]
            costs = [self.cost(r, air_needed) for r in found]
            best = found[int(np.argmin(costs))]
            step = speeds[1] - speeds[0]
            speeds = np.linspace(max(best.state[1] - step, 0.0), min(best.state[1] + step, top), MODE3_GRID)
        return best

    def choose(self, air_needed: float, bottom: float, plane: float) -> Retract:
        """The retract from a hole's ``bottom`` (its turning point) through ``plane``, the
        X/Y plane into the next hole, followed by an air arc of at least ``air_needed``."""
        forced = self.mode
        fast = self.fast_exit(bottom, plane)
        if forced in (1, 2):
            if fast.mode != forced:
                reason = ("too shallow to reach rapid below R" if forced == 1
                          else "deep enough to reach rapid below R (mode 1)")
                raise DrillError("drill.mode", f"{forced} is impossible here, the hole is {reason}")
            return fast
        slow = self._best_slow_exit(air_needed, bottom, plane)
        if forced == 3 or self.cost(slow, air_needed) < self.cost(fast, air_needed) - 1e-6:
            return slow
        return fast

    def last(self, bottom: float, r_z: float) -> LastRetract:
        """S3 of the last hole from its ``bottom`` to rest above ``r_z``.

        Modes 1/2 keep their exit law and brake above R; mode 3 (and auto) takes the
        time-optimal rest-to-rest move to R + RETURN_CLEARANCE, braking before R.
        """
        if self.mode in (1, 2):
            fast = self.choose(0.0, bottom, r_z)
            stop = z_move(self.z.rapid, *fast.state, None, 0.0)
            return LastRetract(fast.mode, fast.move, fast.t_r, stop)
        move = z_move(self.z.turn, bottom, 0.0, 0.0, r_z + RETURN_CLEARANCE)
        return LastRetract(3, move, crossing(move, r_z), None)
