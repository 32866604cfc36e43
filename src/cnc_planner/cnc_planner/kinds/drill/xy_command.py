"""The compensated X/Y command of one overlapped cycle: the S1 moves and their drive-model
corrections as one timeline piece per axis.

The moves and corrections are the same in every plan of a cycle (each round of the timing
search and the final plan); only when each move starts differs. XYMoveTable holds what they
share as arrays, built once per cycle; XYCommand is one plan's command: the table and the
start of each move.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_planner.kinds.drill.xy_moves import XY, XY_COMMAND_LEAD, XYMove
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.jerk_profile import ROW_LENGTH, add_corrections, sample_spans
from cnc_planner.motion.timeline import Piece, WritingSampler


@dataclass(frozen=True)
class _AxisMoves:
    """The moves of one axis, in order: their index among the cycle's moves, their dof's
    row (sample_spans), their target, and where their correction lies in the table
    (offset -1: none) and how many samples it has."""

    move: np.ndarray
    rows: np.ndarray
    target: np.ndarray
    offset: np.ndarray
    length: np.ndarray


class XYMoveTable:
    """The S1 moves of one cycle that move X/Y (null moves left out), as arrays."""

    def __init__(self, start: dict[str, float], moves: list[XYMove], period: float) -> None:
        self.moves = [xy for xy in moves if xy.move]
        self.period = period
        self.duration = np.array([xy.duration for xy in self.moves], dtype=float)
        lead = XY_COMMAND_LEAD * period
        self.lead = np.array([lead if xy.correction is not None else 0.0 for xy in self.moves], dtype=float)
        self.samples = np.array([xy.correction_samples for xy in self.moves], dtype=np.intp)
        # Every distinct correction in one flat table, per dof its p, v and a samples one
        # after the other (add_corrections), each where it first appears.
        bases: dict[int, int] = {}
        blocks: list[np.ndarray] = []
        for xy in self.moves:
            if xy.correction is not None and id(xy.correction) not in bases:
                bases[id(xy.correction)] = sum(block.size for block in blocks)
                blocks.append(np.moveaxis(xy.correction, 2, 0).ravel())  # (dofs, 3, samples)
        self.corrections = np.concatenate(blocks) if blocks else np.zeros(0)
        self.axes: dict[str, _AxisMoves] = {}
        self.held: dict[str, np.ndarray] = {}  # per axis: where it stands after the first k moves
        for j in XY:
            index = [k for k, xy in enumerate(self.moves) if j in xy.joints]
            moved = [(self.moves[k], self.moves[k].joints.index(j)) for k in index]
            self.axes[j] = _AxisMoves(
                move=np.array(index, dtype=np.intp),
                rows=np.array([xy.move.row(dof) for xy, dof in moved]).reshape(-1, ROW_LENGTH),
                target=np.array([xy.target[j] for xy, _ in moved], dtype=float),
                offset=np.array([bases[id(xy.correction)] + 3 * xy.correction_samples * dof
                                 if xy.correction is not None else -1 for xy, dof in moved], dtype=np.intp),
                length=np.array([xy.correction_samples for xy, _ in moved], dtype=np.intp))
            held = [start[j]]
            for xy in self.moves:
                held.append(xy.target[j] if j in xy.joints else held[-1])
            self.held[j] = np.array(held, dtype=float)


class XYCommand:
    """The compensated X/Y commands of one overlapped cycle, as one timeline piece per axis:
    the ruckig moves (holding at each hole in between) plus every move's correction,
    added where they overlap (a correction's tail may reach into the next S1). Moves are
    added in the table's order."""

    def __init__(self, table: XYMoveTable) -> None:
        self.table = table
        self.period = table.period
        self._starts: list[float] = []
        self._times_cache: tuple[np.ndarray, ...] | None = None

    def add(self, t_s1: float, xy: XYMove) -> None:
        """The table's next move starts at t_s1."""
        if xy is not self.table.moves[len(self._starts)]:
            raise ValueError("XYCommand: moves must be added in the order of their table")
        self._starts.append(t_s1)

    @property
    def begin(self) -> float:
        return float(np.min(self._times()[2]))

    @property
    def end(self) -> float:
        return float(self._times()[4][-1])

    def _times(self) -> tuple[np.ndarray, ...]:
        """Per move added: its start and end, its correction's first and last instant, and
        the latest instant it or an earlier one acts on (a running maximum)."""
        m = len(self._starts)
        if self._times_cache is None or len(self._times_cache[0]) != m:
            table = self.table
            t_s1 = np.array(self._starts, dtype=float)
            ends = t_s1 + table.duration[:m]
            c0 = t_s1 - table.lead[:m]
            c_end = c0 + (table.samples[:m] - 1) * self.period
            self._times_cache = (t_s1, ends, c0, c_end, np.maximum.accumulate(np.maximum(ends, c_end)))
        return self._times_cache

    def sample_axis(self, j: str, ts: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Axis j's command at sorted instants ts, written into ``out`` (p, v, a). Only the
        moves that reach into [ts[0], ts[-1]] are evaluated, each on its own index range,
        so a chunk costs the same at any hole.

        A move sets its axes from its start on (its samples, then its target held), so
        a later move of an axis overrides everything an earlier one did from the later
        one's start: each move writes and corrects only up to there.
        """
        t_s1, ends, c0s, c_ends, reach = self._times()
        m = len(t_s1)
        first = int(np.searchsorted(reach, ts[0], side="left")) if len(ts) else m
        held = self.table.held[j][first]
        out[1][:] = 0.0
        out[2][:] = 0.0
        last = first + int(np.argmax(np.append(np.minimum(t_s1[first:], c0s[first:]) > ts[-1], True))) if len(ts) else first
        axis = self.table.axes[j]
        a, b = np.searchsorted(axis.move, [first, last]).tolist()
        if a == b:
            out[0][:] = held
            return
        moves = axis.move[a:b]
        # This axis's moves from first to last, each up to where the next starts.
        lo = np.searchsorted(ts, t_s1[moves], side="left")
        stop = np.append(lo[1:], len(ts))
        end = np.minimum(np.searchsorted(ts, ends[moves], side="left"), stop)
        # Positions: held before the first move, each move's target after it (its samples
        # in between are written next).
        lengths = np.empty(2 * (b - a) + 1, dtype=np.intp)
        values = np.zeros(len(lengths))
        lengths[0], lengths[1::2], lengths[2::2] = lo[0], end - lo, stop - end
        values[0], values[2::2] = held, axis.target[a:b]
        out[0][:] = np.repeat(values, lengths)
        moving = end > lo
        sample_spans(axis.rows[a:b][moving], t_s1[moves][moving], lo[moving], end[moving], ts, out)
        # Corrections, added in move order: a correction's lead overlaps the tail before it.
        c_lo = np.searchsorted(ts, c0s[moves], side="left")
        c_end = np.minimum(np.searchsorted(ts, c_ends[moves], side="right"), stop)
        corrected = (axis.offset[a:b] >= 0) & (c_end > c_lo)  # offset -1: a move without headroom for one
        add_corrections(self.table.corrections, axis.offset[a:b][corrected], axis.length[a:b][corrected],
                        c0s[moves][corrected], c_lo[corrected], c_end[corrected], self.period, ts, out)

    def write(self, builder: PlanBuilder) -> None:
        """Add the commands to the builder: one piece per X/Y axis over the whole cycle."""
        if not self._starts:
            return
        begin, end = self.begin, self.end
        for j in XY:
            final = float(self.table.held[j][len(self._starts)])
            builder.timelines[j].add(Piece(begin, end - begin, _AxisCommand(self, j, begin)), final)


class _AxisCommand(WritingSampler):
    """One axis of an XYCommand as a timeline piece, written straight into the plan's
    samples (a long cycle's piece spans all of it: no copies of its arrays)."""

    def __init__(self, command: XYCommand, joint: str, begin: float) -> None:
        self.command = command
        self.joint = joint
        self.begin = begin

    def write(self, t: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        self.command.sample_axis(self.joint, t + self.begin, out)
