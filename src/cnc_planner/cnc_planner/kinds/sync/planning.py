"""Planning a sync job: its moves as a move job's, each run of synchronised moves one pass
locked to the spindle (cnc_planner.kinds.sync.passes), each tap a rigid tap
(cnc_planner.kinds.sync.tap), each with the ramps and the hold after it that keep its lock
on every drive inside the tolerance (cnc_planner.kinds.sync.margin)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_planner.kinds.move.planning import plan_move
from cnc_planner.kinds.sync.margin import Margin, find_margin, pass_error, tap_error
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


def _starts(job: SimpleNamespace, here: np.ndarray, targets: list, joints: list[str]) -> list[np.ndarray]:
    """Where each move starts (axis positions): the previous move's target, a tap's start
    for the move after it, the tool's position for the first."""
    before = []
    for move, target in zip(job.sync, targets):
        before.append(here)
        here = here if target is None or move.tap is not None else np.array([target[j] for j in joints])
    return before


def _pass_margins(job: SimpleNamespace, builder: PlanBuilder, joints: list[str], starts: list[np.ndarray],
                  points: dict[int, list[np.ndarray]]) -> dict[int, Margin]:
    """Each pass's margin, the passes of one thread (first lead, first direction, spindle
    speed) at the largest ease any of them needs, so that their ramps onto the lead, which
    place them in the groove, are alike."""
    speed = builder.timelines[SPINDLE].end_velocity
    leads = {i: [job.sync[k].lead for k in range(i, i + len(p))] for i, p in points.items()}

    def thread(i: int) -> tuple:
        direction = (points[i][0] - starts[i]) / np.linalg.norm(points[i][0] - starts[i])
        return round(leads[i][0], 12), *np.round(direction, 9).tolist(), round(speed, 9)

    eases: dict[tuple, float] = {}
    margins: dict[int, Margin] = {}
    while stale := [i for i in points if i not in margins or margins[i].ease < eases[thread(i)]]:
        for i in stale:
            fields = [f"sync[{k}].sync" for k in range(i, i + len(points[i]))]
            margins[i] = find_margin(
                builder.machine, joints, starts[i], speed, eases.get(thread(i), 1.0),
                lambda b, ease, i=i, fields=fields: plan_pass(b, joints, points[i], leads[i], fields, ease),
                lambda axes, theta, i=i: pass_error(axes, theta, starts[i], points[i], leads[i]),
                points[i][-1], fields[0])
            eases[thread(i)] = max(eases.get(thread(i), 1.0), margins[i].ease)
    return margins


def _hold(builder: PlanBuilder, joints: list[str], end: float, hold: float) -> None:
    """The axes stand still ``hold`` after ``end``: every drive inside the tolerance arrives."""
    if hold > 0.0:
        for joint in joints:
            builder.timelines[joint].add_hold(end, hold)


def plan_sync_job(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """The moves in order; at the first move of a pass, the whole pass (its other moves are in it)."""
    runs = pass_runs(job.sync)
    joints = list(machine.linear_axes)
    here = np.array([builder.position(j) for j in joints])
    margins: dict[int, Margin] = {}

    def sync(builder: PlanBuilder, i: int, targets: list) -> bool:
        move = job.sync[i]
        starts = _starts(job, here, targets, joints)
        if move.tap is not None:
            bottom, field = np.array([targets[i][j] for j in joints]), f"sync[{i}].tap"
            speed = builder.timelines[SPINDLE].end_velocity
            margin = find_margin(builder.machine, joints, starts[i], speed, 1.0,
                                 lambda b, ease: plan_tap(b, joints, bottom, move.lead, field, ease),
                                 lambda axes, theta: tap_error(axes, theta, starts[i], bottom, move.lead),
                                 starts[i], field)
            index, end = plan_tap(builder, joints, bottom, move.lead, field, margin.ease)
            _hold(builder, joints, end, margin.hold)
            builder.event(index, "sync_pass", move=i, moves=1)
        elif i in runs:
            if not margins:
                margins.update(_pass_margins(job, builder, joints, starts, {
                    k: [np.array([targets[m][j] for j in joints]) for m in range(k, last)] for k, last in runs.items()}))
            moves = range(i, runs[i])
            index, end = plan_pass(builder, joints, [np.array([targets[k][j] for j in joints]) for k in moves],
                                   [job.sync[k].lead for k in moves], [f"sync[{k}].sync" for k in moves],
                                   margins[i].ease)
            _hold(builder, joints, end, margins[i].hold)
            builder.event(index, "sync_pass", move=i, moves=len(moves))
        return move.sync is not None or move.tap is not None

    plan_move(job, machine, builder, kin, block="sync", sync=sync)
