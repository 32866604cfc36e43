"""Drilling cycles on a 3-axis mill: overlapped (S1/S2/S3, overlap.py) and conventional
(G81/G99, conventional.py), timed against the servo lag on the drive model (servo_lag.py).

Planning a cycle takes, per hole: S1, the X/Y move to it (xy_moves.py, its compensated
command in xy_command.py); where its last feed stroke turns so that the feedback turns at
the depth (bottom.py) or stops there for a dwell (dwell.py); the feed strokes themselves
(strokes.py: plain, pecked, vibrated); and the retract law out of it (retract.py). The
overlapped cycle then searches the gaps that keep X/Y on the hole on feedback, chooses the
retract laws for them, and optionally lowers each air arc's acceleration (air.py).
"""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.schema import JobError

from cnc_planner.kinds.drill.air import gentle_accels
from cnc_planner.kinds.drill.bottom import Bottoms
from cnc_planner.kinds.drill.conventional import conventional
from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinds.drill.dwell import Dwells
from cnc_planner.kinds.drill.overlap import overlapped
from cnc_planner.kinds.drill.retract import Retract, RetractLaw
from cnc_planner.kinds.drill.servo_lag import ServoLag
from cnc_planner.kinds.drill.strokes import Strokes
from cnc_planner.kinds.drill.xy_command import XYMoveTable
from cnc_planner.kinds.drill.xy_moves import s1_moves
from cnc_planner.kinds.drill.z_axis import ZAxis
from cnc_planner.motion.builder import PlanBuilder


def plan_drilling(builder: PlanBuilder, cycle: DrillCycle, energies: bool = True) -> list[dict]:
    """Append the whole drilling cycle to ``builder`` (tool above R, at rest) and return,
    per hole: hole index, x, y, mode, the plan times s1, s1_end, s2 (Z leaves R'),
    r_down, s3 and r_up; for the overlapped cycle also apex_z (R'), air_time, air_accel
    and, with ``energies``, air_energy (integral of a_z^2 dt over the air move into the
    hole: the proxy the gentle variant lowers; sampled at 10 kHz, 6 % of a long plate's
    planning, so a job that does not read it does not pay for it).

    The timing search runs the drive model from the cycle's start with the drives at
    rest there, as after any rapid.
    """
    machine = builder.machine
    start = {j: builder.position(j) for j in machine.joint_names}
    z = ZAxis(machine, cycle, start["z"])
    xy_moves = s1_moves(machine, cycle, start)
    law = RetractLaw(z, cycle.mode)
    bottoms = Bottoms(machine, cycle, z, law.fast_exit)
    strokes = Strokes(machine, cycle, z, bottoms, Dwells(machine, cycle, z, bottoms))
    lag = ServoLag(machine, cycle, start, z)
    n = len(cycle.holes)
    t0 = builder.end_time()
    full = np.full(n, z.rapid.acceleration)
    if not cycle.overlap:
        emit = conventional(cycle, xy_moves, strokes)
        zeros = np.zeros(n)
        e_down, e_up = lag.safe_gaps(emit, t0, zeros, zeros, zeros, zeros)
        return emit(builder, t0, e_down, e_up, full, energies)
    # Command-level floors: X/Y may leave the hole only once Z is above R, and must be
    # back inside the tolerance before Z goes below R (in whole servo periods).
    period = cycle.servo_period
    floor_down = np.array([math.ceil((xy.arrive - xy.duration) / period - 1e-9) * period for xy in xy_moves])
    floor_up = np.array([0.0] + [-math.floor(xy.leave / period + 1e-9) * period
                                 if xy.move and math.isfinite(xy.leave) else 0.0 for xy in xy_moves[1:]])
    xy_time = np.array([xy.duration for xy in xy_moves])
    last_bottom = bottoms.turning_point(n - 1)

    def retracts(e_down: np.ndarray, e_up: np.ndarray) -> list[Retract]:
        air_needed = e_up + xy_time + e_down
        laws: dict[tuple[float, float, float], Retract] = {}  # holes of one pitch and depth need the same law
        out = []
        for i in range(n - 1):
            key = (float(air_needed[i + 1]), bottoms.turning_point(i), cycle.air_plane(i + 1))
            if key not in laws:
                laws[key] = law.choose(*key)
            out.append(laws[key])
        return out + [law.fast_exit(last_bottom, cycle.r_z)]

    # One round at the command floors measures the lag margins; with them the retract
    # laws are chosen once more, then the gaps settle.
    first = retracts(floor_down, floor_up)
    last = law.last(last_bottom, cycle.r_z)
    xy_table = XYMoveTable(start, xy_moves, period) if cycle.compensate_xy else None  # shared by every plan
    e_down, e_up = lag.safe_gaps(overlapped(cycle, start, z, xy_moves, xy_table, strokes, first, last), t0,
                                 floor_down, floor_up, floor_down, floor_up, rounds=1)
    chosen = retracts(e_down, e_up)
    emit = overlapped(cycle, start, z, xy_moves, xy_table, strokes, chosen, last)
    e_down, e_up = lag.safe_gaps(emit, t0, e_down, e_up, floor_down, floor_up)
    accel = full
    if cycle.gentle_air_accel:
        infos = emit(PlanBuilder(machine, start, events=False), t0, e_down, e_up, full, False)
        ups = [t0] + [info["r_up"] for info in infos[:-1]]
        air_times = [info["r_down"] - u for info, u in zip(infos, ups)]
        starts = [(start["z"], 0.0, 0.0)] + [r.state for r in chosen[:-1]]
        accel = gentle_accels(lag, z, cycle, emit, t0, e_down, e_up, starts, air_times)
    return emit(builder, t0, e_down, e_up, accel, energies)


def plan_cycle(builder: PlanBuilder, cycle: DrillCycle) -> None:
    """plan_drilling for a job (its per-hole figures unread): what this machine cannot
    drill is refused naming the job's field (DrillError, or the vibration's JobError)."""
    try:
        plan_drilling(builder, cycle, energies=False)
    except JobError:
        raise  # names its field already
    except ValueError as err:  # ruckig's own, in one line: it appends its whole input to its errors
        raise JobError("drill", (str(err).splitlines() or [""])[0]) from err
