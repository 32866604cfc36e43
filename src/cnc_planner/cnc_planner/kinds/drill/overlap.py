"""The overlapped cycle written into a plan for given gaps and air accelerations.

Per hole i:
  S1  X/Y rapid to the hole (ruckig, axes synchronised; pre-compensated, xy_moves.py);
  S2  Z comes down from the top of its air arc R' through the R plane, where it has
      reached the cutting feed exactly, and feeds to depth (strokes.py);
  S3  Z retracts (retract.py); as the tip passes R going up, S1 of the next hole starts.
Between two holes Z makes one ruckig move from its retract state at R to (R, -feed), the
air arc R -> R' -> R: R' follows from the motion. The arc lasts the longer of its own
minimum time and the X/Y move plus the servo-lag margins (servo_lag.py), so Z descends
before S1 ends.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_planner.kinds.drill.air import air_energies
from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinds.drill.retract import LastRetract, Retract
from cnc_planner.kinds.drill.servo_lag import Emit
from cnc_planner.kinds.drill.strokes import Strokes
from cnc_planner.kinds.drill.xy_command import XYCommand, XYMoveTable
from cnc_planner.kinds.drill.xy_moves import XY_COMMAND_LEAD, XYMove
from cnc_planner.kinds.drill.z_axis import ZAxis, add_z
from cnc_planner.motion.builder import PlanBuilder


def overlapped(cycle: DrillCycle, start: dict[str, float], z: ZAxis, xy_moves: list[XYMove],
               xy_table: XYMoveTable | None, strokes: Strokes, retracts: list[Retract],
               last_retract: LastRetract) -> Emit:
    """Overlapped cycle: e_down[i] = Z at R after the X/Y command ends, e_up[i] = X/Y start
    after Z passed R up from hole i-1; accel[i] = Z acceleration limit of hole i's air move.
    ``xy_table``: the moves' table for their compensated command (None: plain ruckig moves,
    compensate_xy off). ``retracts``: per hole, its retract into the next air arc (the last
    hole's is unused: ``last_retract`` ends the cycle)."""
    n = len(xy_moves)
    approach_min = z.arc((start["z"], 0.0, 0.0), cycle.air_plane(0))
    arc_min = [approach_min.duration] + [z.arc(r.state, r.state[0]).duration for r in retracts[:-1]]

    def emit(builder: PlanBuilder, t0: float, e_down: np.ndarray, e_up: np.ndarray,
             accel: np.ndarray, energy: bool) -> list[dict]:
        u = t0  # when Z last passed R going up (the cycle start for the first hole)
        infos = []
        period = cycle.servo_period
        command = XYCommand(xy_table) if xy_table is not None else None
        lead = XY_COMMAND_LEAD * period
        airs = []  # each hole's air move, for its energy
        for i, xy in enumerate(xy_moves):
            last = i == n - 1
            mode = last_retract.mode if last else retracts[i].mode
            t_s1 = t0 if i == 0 else u + e_up[i]
            if command is None:
                xy_end = builder.rapid(xy.target, start=t_s1)
            else:
                # On the servo grid, where the correction was learned; the first command
                # starts no earlier than the cycle.
                t_s1 = (math.ceil(t0 / period - 1e-9) * period + lead if i == 0
                        else round(t_s1 / period) * period)
                xy_end = t_s1 + xy.duration
                if xy.move:
                    command.add(t_s1, xy)
            builder.event(t_s1, "S1", hole=i, mode=mode)
            air_time = max(arc_min[i], t_s1 + xy.duration + e_down[i] - u)
            if i == 0:
                gentle = accel[0] < z.rapid.acceleration
                t_air = t0 if gentle else t0 + air_time - arc_min[0]
                air = (z.arc((start["z"], 0.0, 0.0), cycle.air_plane(0), accel[0], t0 + air_time - t_air) if gentle
                       else approach_min)
            else:
                t_air = u
                air = z.arc(retracts[i - 1].state, cycle.air_plane(i), accel[i], air_time)
            t_down = add_z(builder, t_air, air)
            apex = air.trajectory.position_extrema[0]
            builder.event(t_air + apex.t_max, "S2", hole=i, mode=mode)
            builder.event(t_down, "R_down", hole=i, mode=mode)
            t_s3 = strokes.feed_to_depth(builder, t_down, i, True, cycle.air_plane(i))
            builder.event(t_s3, "S3", hole=i, mode=mode)
            if last:
                u = t_s3 + last_retract.t_r
                end = add_z(builder, t_s3, last_retract.move, last_retract.t_r if last_retract.stop else None)
                if last_retract.stop:
                    add_z(builder, end, last_retract.stop)
            else:
                u = add_z(builder, t_s3, retracts[i].move, retracts[i].t_r)
            builder.event(u, "R_up", hole=i, mode=mode)
            info = {"hole": i, "x": xy.target["x"], "y": xy.target["y"], "mode": mode,
                    "s1": float(t_s1), "s1_end": float(xy_end), "s2": float(t_air + apex.t_max),
                    "r_down": float(t_down),
                    "s3": float(t_s3), "r_up": float(u), "apex_z": float(apex.max),
                    "air_time": float(t_down - t_air), "air_accel": float(accel[i])}
            airs.append(air)
            infos.append(info)
        if energy:
            for info, value in zip(infos, air_energies(airs)):
                info["air_energy"] = value
        if command is not None:
            command.write(builder)
        strokes.settle_corrections(builder)
        return infos

    return emit
