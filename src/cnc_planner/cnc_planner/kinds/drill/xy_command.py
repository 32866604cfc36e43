"""The compensated X/Y command of one overlapped cycle: the S1 moves and their drive-model
corrections as one timeline piece per axis."""
from __future__ import annotations

import numpy as np

from cnc_planner.kinds.drill.xy_moves import XY, XY_COMMAND_LEAD, XYMove
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.timeline import Piece


class XYCommand:
    """The compensated X/Y commands of one overlapped cycle, as one timeline piece per axis:
    the ruckig moves (holding at each hole in between) plus every move's correction,
    added where they overlap (a correction's tail may reach into the next S1)."""

    def __init__(self, start: dict[str, float], period: float):
        self.start = {j: start[j] for j in XY}
        self.period = period
        self.entries: list[tuple[float, XYMove, float]] = []  # (move start, move, correction start)
        self._cache: tuple[tuple, dict] | None = None
        self._reach: np.ndarray | None = None
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

    def sample(self, ts: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Commands at sorted instants ts. Only the entries that reach into [ts[0], ts[-1]]
        are evaluated, each on its own index range, so a chunk costs the same at any hole.

        A move sets its axes from its start on (its samples, then its target held), so
        a later move of an axis overrides everything an earlier one did from the later
        one's start: each entry writes and corrects only up to there.
        """
        key = (len(ts), float(ts[0]), float(ts[-1])) if len(ts) else (0, 0.0, 0.0)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        first = self._first_entry(ts[0]) if len(ts) else len(self.entries)
        held = self._held(first)
        out = {j: [np.full_like(ts, held[j]), np.zeros_like(ts), np.zeros_like(ts)] for j in XY}
        window = []
        for t_s1, xy, c0 in self.entries[first:]:
            if len(ts) == 0 or min(t_s1, c0) > ts[-1]:
                break
            window.append((xy, c0, t_s1, *np.searchsorted(ts, [t_s1, t_s1 + xy.duration], side="left")))
        overridden = {j: len(ts) for j in XY}  # where the next move of each axis starts
        until = []
        for xy, _, _, lo, _ in reversed(window):
            until.append({j: overridden[j] for j in xy.joints})
            overridden.update({j: lo for j in xy.joints})
        until.reverse()
        for (xy, _, t_s1, lo, hi), stop in zip(window, until):
            pva = xy.move.sample_all(ts[lo:hi] - t_s1) if hi > lo else None
            for dof, j in enumerate(xy.joints):
                out[j][0][hi:stop[j]] = xy.target[j]
                end = min(hi, stop[j])
                for q in range(3):
                    if pva is not None and end > lo:
                        out[j][q][lo:end] = pva[q][: end - lo, dof]
        for (xy, c0, _, _, _), stop in zip(window, until):
            if xy.correction is None:  # a move planned without one (no headroom for it)
                continue
            k = xy.correction.shape[1]
            lo = np.searchsorted(ts, c0, side="left")
            hi = np.searchsorted(ts, c0 + (k - 1) * self.period, side="right")
            grid = np.arange(k) * self.period
            for dof, j in enumerate(xy.joints):
                end = min(hi, stop[j])
                for q in range(3):
                    if end > lo:
                        out[j][q][lo:end] += np.interp(ts[lo:end] - c0, grid, xy.correction[q, :, dof])
        self._cache = (key, out)
        return out

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
            def sample(t: np.ndarray, j: str = j) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return tuple(self.sample(t + begin)[j])  # type: ignore[return-value]

            builder.timelines[j].add(Piece(begin, end - begin, sample), final[j])

