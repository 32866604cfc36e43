"""Planning a sync job: its moves as a move job's, each run of synchronised moves one pass
locked to the spindle (cnc_planner.kinds.sync.passes), each tap a rigid tap
(cnc_planner.kinds.sync.tap)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_planner.kinds.move.planning import plan_move
from cnc_planner.kinds.sync.passes import plan_pass
from cnc_planner.kinds.sync.tap import plan_tap
from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder


def pass_runs(moves: list) -> dict[int, int]:
    """The passes: the first synchronised move of each run -> one past its last."""
    runs: dict[int, int] = {}
    first = None
    for i, move in enumerate([*moves, None]):
        if move is not None and move.sync is not None:
            first = i if first is None else first
        elif first is not None:
            runs[first], first = i, None
    return runs


def plan_sync_job(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """The moves in order; at the first move of a pass, the whole pass (its other moves are in it)."""
    runs = pass_runs(job.sync)
    joints = list(machine.linear_axes)

    def sync(builder: PlanBuilder, i: int, targets: list) -> bool:
        move = job.sync[i]
        if move.tap is not None:
            index, _ = plan_tap(builder, joints, np.array([targets[i][j] for j in joints]), move.lead,
                                f"sync[{i}].tap")
            builder.event(index, "sync_pass", move=i, moves=1)
        elif i in runs:
            moves = range(i, runs[i])
            index, _ = plan_pass(builder, joints, [np.array([targets[k][j] for j in joints]) for k in moves],
                                 [job.sync[k].lead for k in moves], [f"sync[{k}].sync" for k in moves])
            builder.event(index, "sync_pass", move=i, moves=len(moves))
        return move.sync is not None or move.tap is not None

    plan_move(job, machine, builder, kin, block="sync", sync=sync)
