"""Gentle air acceleration (gentle_air_accel): each air arc between two holes at the lowest
Z acceleration that keeps its duration and the feedback safe, so less heat and power for
the same cycle time; its energy proxy is the integral of a_z^2 dt over the arc."""
from __future__ import annotations

import numpy as np

from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinds.drill.servo_lag import Emit, ServoLag
from cnc_planner.kinds.drill.z_axis import ZAxis
from cnc_planner.motion.jerk_profile import sample_spans
from cnc_planner.motion.moves import RuckigMove

GENTLE_ROUNDS = 6  # bisection rounds for the gentle air acceleration
ENERGY_STEP = 1e-4  # s, sampling of a_z^2
ENERGY_MOVES = 64  # air moves whose energies are sampled in one pass


def air_energy(move: RuckigMove) -> float:
    """Integral of a_z^2 dt over an air move: the heat/power proxy of the gentle variant."""
    a = move.sample_all(np.arange(0.0, move.duration, ENERGY_STEP))[2][:, 0]
    return float(np.sum(a * a) * ENERGY_STEP)


def air_energies(moves: list[RuckigMove]) -> list[float]:
    """air_energy of each move, the accelerations of ENERGY_MOVES at a time sampled in one
    call (sample_spans: the same values) and summed per move as air_energy sums them."""
    energies = []
    for first in range(0, len(moves), ENERGY_MOVES):
        group = moves[first:first + ENERGY_MOVES]
        instants = [np.arange(0.0, move.duration, ENERGY_STEP) for move in group]
        ends = np.cumsum([len(t) for t in instants])
        out = [np.empty(ends[-1]) for _ in range(3)]
        # each move's own instants, from its own start (0 s)
        sample_spans(np.array([move.row(0) for move in group]), np.zeros(len(group)), ends - [len(t) for t in instants],
                     ends, np.concatenate(instants), out)
        energies += [float(np.sum(a * a) * ENERGY_STEP) for a in np.split(out[2], ends[:-1].tolist())]
    return energies


def gentle_accels(lag: ServoLag, z: ZAxis, cycle: DrillCycle, emit: Emit, t0: float, e_down: np.ndarray,
                  e_up: np.ndarray, starts: list[tuple[float, float, float]], air_times: list[float]) -> np.ndarray:
    """Lowest Z acceleration per air move that keeps its duration and the feedback safe.

    Time first: bisect the limit until the move's own minimum time just fits the time
    the cycle leaves it. Then safety: gentler braking into R shrinks Z's favourable lag
    there, so holes whose feedback turns unsafe get their limit bisected back up
    (the full limit is the plain cycle, known safe).
    """
    full = z.rapid.acceleration
    n = len(cycle.holes)
    low = np.empty(n)
    for i, (state, air_time) in enumerate(zip(starts, air_times)):
        lo, hi = max(abs(state[2]), 0.02 * full), full
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if z.arc(state, cycle.air_plane(i), mid).duration <= air_time + 1e-9 else (mid, hi)
        low[i] = hi
    safe = np.full(n, full)
    test = low
    for _ in range(GENTLE_ROUNDS):
        ok = lag.margins(emit, t0, e_down, e_up, test)[0] <= 0
        safe = np.where(ok, np.minimum(safe, test), safe)
        low = np.where(ok, low, test)
        test = 0.5 * (low + safe)
    # Keep a lower limit only where it really lowers the energy: ruckig stretches a
    # move to a given duration differently under different limits.
    for i, (state, air_time) in enumerate(zip(starts, air_times)):
        plane = cycle.air_plane(i)
        plain = z.arc(state, plane) if i == 0 else z.arc(state, plane, full, air_time)
        if safe[i] < full and air_energy(z.arc(state, plane, safe[i], air_time)) >= air_energy(plain):
            safe[i] = full
    return safe
