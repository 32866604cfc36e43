"""The lower bound on a drill cycle's time, against which the cycle is measured."""
from __future__ import annotations

import math
from dataclasses import replace

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinds.drill.retract import RetractLaw
from cnc_planner.kinds.drill.xy_moves import s1_moves
from cnc_planner.kinds.drill.z_axis import ZAxis


def lower_bound_time(machine: Machine, cycle: DrillCycle,
                     start_xy: tuple[float, float] | None = None) -> float:
    """Sum over holes of the X/Y positioning time (from ``start_xy`` for the first hole,
    if given) and the fastest possible time below R: feed from R to depth, then full
    acceleration back to R. X/Y may not move while the tip is below R, so no safe cycle
    is shorter. A vibrated feed's tool runs up to its amplitude (Q*F) ahead of the feed
    line, so it may reach depth that much sooner."""
    first = start_xy if start_xy is not None else cycle.holes[0]
    plain = replace(cycle, compensate_xy=False)
    start = {"x": first[0], "y": first[1], "z": cycle.r_z}
    z = ZAxis(machine, plain, start["z"])
    xy_moves = s1_moves(machine, plain, start)
    law = RetractLaw(z, plain.mode)
    # each hole from its own R (a fall from the X/Y plane to a lower one left out) to its bottom
    ahead = 0.0 if cycle.vibration is None else cycle.vibration.Q * cycle.feed * 2 * math.pi / cycle.spindle_speed
    below = sum((z.stroke(top, bottom).duration if ahead == 0.0 else max(top - bottom - ahead, 0.0) / cycle.feed)
                + law.fast_exit(bottom, cycle.r_z).t_r
                for _, top, bottom in map(cycle.planes, range(len(cycle.holes))))
    return sum(xy.duration for xy in xy_moves) + below
