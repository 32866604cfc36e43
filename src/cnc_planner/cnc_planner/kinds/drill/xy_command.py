"""The compensated X/Y command of one overlapped cycle: the S1 moves and their drive-model
corrections as one timeline piece per axis."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_planner.kinds.drill.xy_moves import XY, XY_COMMAND_LEAD, XYMove
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.jerk_profile import ROW_LENGTH, add_corrections, sample_spans
from cnc_planner.motion.timeline import Piece, WritingSampler


@dataclass
class _AxisEntries:
    """The entries of an XYCommand that move one axis, in order, as arrays: their index,
    the move's row (sample_spans), start and end, the correction's first and last instant,
    the target, and where the correction lies in the table (offset -1: none) and its length;
    ``count``: the entries there were (entries are only ever appended)."""

    count: int
    entry: np.ndarray
    rows: np.ndarray
    t_s1: np.ndarray
    ends: np.ndarray
    c0: np.ndarray
    c_end: np.ndarray
    target: np.ndarray
    offset: np.ndarray
    length: np.ndarray


class XYCommand:
    """The compensated X/Y commands of one overlapped cycle, as one timeline piece per axis:
    the ruckig moves (holding at each hole in between) plus every move's correction,
    added where they overlap (a correction's tail may reach into the next S1)."""

    def __init__(self, start: dict[str, float], period: float):
        self.start = {j: start[j] for j in XY}
        self.period = period
        self.entries: list[tuple[float, XYMove, float]] = []  # (move start, move, correction start)
        self._reach: np.ndarray | None = None
        self._times_cache: tuple[np.ndarray, ...] | None = None
        self._table: tuple[np.ndarray, dict[int, int], int] | None = None  # _corrections', for so many entries
        self._axes: dict[str, _AxisEntries] = {}
        self._held_after: list[dict[str, float]] = [dict(self.start)]  # _held's, per entry

    def add(self, t_s1: float, xy: XYMove) -> None:
        lead = XY_COMMAND_LEAD * self.period if xy.correction is not None else 0.0
        self.entries.append((t_s1, xy, t_s1 - lead))

    @property
    def begin(self) -> float:
        return min(c for _, _, c in self.entries)

    @property
    def end(self) -> float:
        return max(max(t + xy.duration, c + (xy.correction_samples - 1) * self.period) for t, xy, c in self.entries)

    def sample_axis(self, j: str, ts: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Axis j's command at sorted instants ts, written into ``out`` (p, v, a). Only the
        entries that reach into [ts[0], ts[-1]] are evaluated, each on its own index range,
        so a chunk costs the same at any hole.

        A move sets its axes from its start on (its samples, then its target held), so
        a later move of an axis overrides everything an earlier one did from the later
        one's start: each entry writes and corrects only up to there.
        """
        first = self._first_entry(ts[0]) if len(ts) else len(self.entries)
        held = self._held(first)[j]
        out[1][:] = 0.0
        out[2][:] = 0.0
        t_s1, _, c0s, _ = self._times()
        last = first + int(np.argmax(np.append(np.minimum(t_s1[first:], c0s[first:]) > ts[-1], True))) if len(ts) else first
        axis = self._axis(j)
        a, b = np.searchsorted(axis.entry, [first, last]).tolist()
        if a == b:
            out[0][:] = held
            return
        # The entries from first to last that move this axis, each up to where the next starts.
        lo = np.searchsorted(ts, axis.t_s1[a:b], side="left")
        stop = np.append(lo[1:], len(ts))
        end = np.minimum(np.searchsorted(ts, axis.ends[a:b], side="left"), stop)
        # Positions: held before the first move, each move's target after it (its samples
        # in between are written next).
        lengths = np.empty(2 * (b - a) + 1, dtype=np.intp)
        values = np.zeros(len(lengths))
        lengths[0], lengths[1::2], lengths[2::2] = lo[0], end - lo, stop - end
        values[0], values[2::2] = held, axis.target[a:b]
        out[0][:] = np.repeat(values, lengths)
        moving = end > lo
        sample_spans(axis.rows[a:b][moving], axis.t_s1[a:b][moving], lo[moving], end[moving], ts, out)
        # Corrections, added in entry order: a correction's lead overlaps the tail before it.
        c_lo = np.searchsorted(ts, axis.c0[a:b], side="left")
        c_end = np.minimum(np.searchsorted(ts, axis.c_end[a:b], side="right"), stop)
        corrected = (axis.offset[a:b] >= 0) & (c_end > c_lo)  # offset -1: a move without headroom for one
        add_corrections(self._corrections()[0], axis.offset[a:b][corrected], axis.length[a:b][corrected],
                        axis.c0[a:b][corrected], c_lo[corrected], c_end[corrected], self.period, ts, out)

    def _axis(self, j: str) -> _AxisEntries:
        """The entries that move axis j, as arrays (built once per change of the entries)."""
        if j not in self._axes or self._axes[j].count != len(self.entries):
            t_s1, ends, c0, c_end = self._times()
            table, bases = self._corrections()
            entry = [k for k, (_, xy, _) in enumerate(self.entries) if j in xy.joints]
            moves = [(self.entries[k][1], self.entries[k][1].joints.index(j)) for k in entry]
            self._axes[j] = _AxisEntries(
                count=len(self.entries), entry=np.array(entry, dtype=np.intp),
                rows=np.array([xy.move.row(dof) for xy, dof in moves]).reshape(-1, ROW_LENGTH),
                t_s1=t_s1[entry], ends=ends[entry], c0=c0[entry], c_end=c_end[entry],
                target=np.array([xy.target[j] for xy, _ in moves]),
                offset=np.array([bases[id(xy.correction)] + 3 * xy.correction_samples * dof
                                 if xy.correction is not None else -1 for xy, dof in moves], dtype=np.intp),
                length=np.array([xy.correction_samples for xy, _ in moves], dtype=np.intp))
        return self._axes[j]

    def _corrections(self) -> tuple[np.ndarray, dict[int, int]]:
        """Every distinct correction in one flat table, per dof its p, v and a samples one
        after the other, and where each correction (by identity) begins in it."""
        if self._table is None or self._table[2] != len(self.entries):
            bases: dict[int, int] = {}
            blocks: list[np.ndarray] = []
            size = 0
            for _, xy, _ in self.entries:
                if xy.correction is not None and id(xy.correction) not in bases:
                    bases[id(xy.correction)] = size
                    blocks.append(np.moveaxis(xy.correction, 2, 0).ravel())  # (dofs, 3, k)
                    size += blocks[-1].size
            self._table = (np.concatenate(blocks) if blocks else np.zeros(0), bases, len(self.entries))
        return self._table[0], self._table[1]

    def _times(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per entry: its move's start and end, its correction's first and last instant."""
        if self._times_cache is None or len(self._times_cache[0]) != len(self.entries):
            t_s1 = np.array([t for t, _, _ in self.entries], dtype=float)
            c0 = np.array([c for _, _, c in self.entries], dtype=float)
            ends = t_s1 + np.array([xy.duration for _, xy, _ in self.entries], dtype=float)
            samples = np.array([xy.correction_samples for _, xy, _ in self.entries])
            self._times_cache = (t_s1, ends, c0, c0 + (samples - 1) * self.period)
        return self._times_cache

    def _held(self, first: int) -> dict[str, float]:
        """Where the axes stand after the first ``first`` entries' moves (kept per entry:
        a long cycle is sampled block by block)."""
        while len(self._held_after) <= len(self.entries):
            xy = self.entries[len(self._held_after) - 1][1]
            self._held_after.append({**self._held_after[-1], **{j: xy.target[j] for j in xy.joints}})
        return self._held_after[first]

    def _first_entry(self, t: float) -> int:
        """Index of the first entry whose move or correction may still act at time t."""
        if self._reach is None or len(self._reach) != len(self.entries):
            # Latest instant each entry or an earlier one acts on (a running maximum).
            ends = [max(t_s1 + xy.duration, c + (xy.correction_samples - 1) * self.period)
                    for t_s1, xy, c in self.entries]
            self._reach = np.maximum.accumulate(ends) if ends else np.zeros(0)
        return int(np.searchsorted(self._reach, t, side="left"))

    def write(self, builder: PlanBuilder) -> None:
        """Add the commands to the builder: one piece per X/Y axis over the whole cycle."""
        if not self.entries:
            return
        begin, end = self.begin, self.end
        final = dict(self.start)
        for _, xy, _ in self.entries:
            final.update(xy.target)
        for j in XY:
            builder.timelines[j].add(Piece(begin, end - begin, _AxisCommand(self, j, begin)), final[j])


class _AxisCommand(WritingSampler):
    """One axis of an XYCommand as a timeline piece, written straight into the plan's
    samples (a long cycle's piece spans all of it: no copies of its arrays)."""

    def __init__(self, command: XYCommand, joint: str, begin: float) -> None:
        self.command = command
        self.joint = joint
        self.begin = begin

    def write(self, t: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        self.command.sample_axis(self.joint, t + self.begin, out)
