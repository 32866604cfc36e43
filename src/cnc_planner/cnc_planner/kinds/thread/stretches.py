"""One axis's motion over the thread cycle as stretches, each from the cycle time it
begins until the next begins: ruckig moves (the approach, the air paths, the pull-outs)
held in their end state after them, the tool at rest, and the helix. The moves are
sampled together in one kernel call (motion/_sample_kernel.c), and handed as they are to
the stock check's kernel (_stock_kernel.c): the join search samples thousands of short
stretches.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from ruckig import Trajectory

from cnc_planner.motion.jerk_profile import axis_row, rest_row, sample_spans


Stretch = tuple[float, Callable[[np.ndarray], np.ndarray]]  # (cycle time it begins,
# cycle times -> (3, len(t)): one axis's position, velocity and acceleration)


class Move:
    """One axis along a ruckig move (a row of TrajectorySampler.rows) from cycle time
    ``start``, in its end state after it: a stretch the kernels evaluate with its neighbours
    in one call (sample_track, ThreadCycle._cuts_stock)."""

    __slots__ = ("start", "row")

    def __init__(self, start: float, row: np.ndarray) -> None:
        self.start, self.row = start, row

    def __call__(self, t: np.ndarray) -> np.ndarray:
        out = np.empty((3, t.size))
        sample_spans(self.row[None], np.array([self.start]), _FIRST, np.array([t.size]), t, out, held=True)
        return out


_FIRST = np.zeros(1, dtype=np.intp)  # a lone stretch's instants start at the first


def pieces(track: list[Stretch], t: np.ndarray) -> tuple[list[tuple], list[tuple]]:
    """The stretches of ``track`` at sorted instants t, each from its start until the next
    begins (the first one before its start too): its moves as the kernels take them, (row,
    start, lo, hi) for the instants [lo, hi), and the other stretches as (stretch, lo, hi)."""
    bounds = t.searchsorted([begin for begin, _ in track[1:]]).tolist()  # side="left"
    moves, others = [], []
    for (_, stretch), lo, hi in zip(track, [0, *bounds], [*bounds, t.size]):
        if hi > lo:
            if type(stretch) is Move:
                moves.append((stretch.row, stretch.start, lo, hi))
            else:
                others.append((stretch, lo, hi))
    return moves, others


def moving(start: float, trajectory: Trajectory) -> Stretch:
    """Along a one-axis ruckig move from cycle time ``start`` (its row read once: a
    stretch is sampled many times)."""
    return (start, Move(start, axis_row(trajectory)))


def at_rest(position: float) -> Stretch:
    """Standing at ``position`` from cycle time 0 (and before)."""
    return (0.0, Move(0.0, rest_row(position)))


def sample_track(track: list[Stretch], t: np.ndarray) -> np.ndarray:
    """(3, len(t)) of one axis at sorted t: each stretch from its start until the next
    begins (the first one before its start too)."""
    out = np.empty((3, t.size))
    moves, others = pieces(track, t)
    for stretch, lo, hi in others:
        out[:, lo:hi] = stretch(t[lo:hi])
    if moves:
        rows, starts, lo, hi = zip(*moves)
        sample_spans(np.stack(rows), starts, lo, hi, t, out, held=True)
    return out
