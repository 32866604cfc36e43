"""The conventional cycle (overlap: off), like G81 with G99: X/Y rapid, Z rapid to R, feed
to depth, rapid up to R + RETURN_CLEARANCE, each move after the previous one ends."""
from __future__ import annotations

import numpy as np

from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE, DrillCycle
from cnc_planner.kinds.drill.servo_lag import Emit
from cnc_planner.kinds.drill.strokes import Strokes
from cnc_planner.kinds.drill.xy_moves import XYMove
from cnc_planner.kinds.drill.z_axis import crossing
from cnc_planner.motion.builder import PlanBuilder


def conventional(cycle: DrillCycle, xy_moves: list[XYMove], strokes: Strokes) -> Emit:
    """Sequential G81/G99 cycle: e_up[i] = dwell before the X/Y move, e_down[i] = dwell
    between the X/Y move's end and the rapid down to R."""

    def emit(builder: PlanBuilder, t0: float, e_down: np.ndarray, e_up: np.ndarray,
             accel: np.ndarray, energy: bool) -> list[dict]:
        infos = []
        for i, xy in enumerate(xy_moves):
            t_s1 = max(builder.end_time(), t0) + e_up[i]
            xy_end = builder.rapid(xy.target, start=t_s1)
            builder.event(t_s1, "S1", hole=i, mode=None)
            t_s2 = xy_end + e_down[i]
            t_down = builder.rapid({"z": cycle.r_z}, start=t_s2)
            builder.event(t_s2, "S2", hole=i, mode=None)
            builder.event(t_down, "R_down", hole=i, mode=None)
            t_s3 = strokes.feed_to_depth(builder, t_down, i, False, cycle.r_z)
            builder.event(t_s3, "S3", hole=i, mode=None)
            clearance = cycle.air_plane(i + 1) + RETURN_CLEARANCE  # X/Y moves on at this level
            up = builder.rapid_move({"z": clearance})
            t_up = t_s3 + crossing(up, cycle.r_z)
            builder.rapid({"z": clearance}, start=t_s3)
            builder.event(t_up, "R_up", hole=i, mode=None)
            infos.append({"hole": i, "x": xy.target["x"], "y": xy.target["y"], "mode": None,
                          "s1": float(t_s1), "s1_end": float(xy_end), "s2": float(t_s2), "r_down": float(t_down),
                          "s3": float(t_s3), "r_up": float(t_up)})
        strokes.settle_corrections(builder)
        return infos

    return emit
