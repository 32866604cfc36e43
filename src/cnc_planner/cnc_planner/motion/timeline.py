"""A plan as one timeline per joint, sampled lazily at any set of instants.

Each joint moves through pieces (start time, duration, sampler). Between pieces a joint
coasts at the velocity its last piece ended with: zero for axes, the spindle speed for
the spindle. Joints have independent timelines so that one axis may start moving before
another has stopped, which is what overlapped drilling needs. Nothing is sampled until
a chunk asks for it, so a job of an hour costs memory for its pieces, not its samples.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from cnc_planner.motion.jerk_profile import ROW_LENGTH, sample_spans
from cnc_planner.motion.moves import DofSampler, shared_samples

# Local time (s, from the piece's start) -> position, velocity, acceleration arrays.
Sampler = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
# Plan time (s) -> position, velocity and acceleration offsets (JointTimeline.carry).
Correction = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


class WritingSampler:
    """A sampler that writes its samples into given arrays (p, v, a views of a plan's
    sample): a piece as long as a whole cycle costs no arrays of its own."""

    def write(self, t: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        raise NotImplementedError

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        out = (np.empty_like(t), np.empty_like(t), np.empty_like(t))
        self.write(t, out)
        return out


@dataclass(frozen=True)
class Piece:
    start: float
    duration: float
    sample: Sampler

    @property
    def end(self) -> float:
        return self.start + self.duration


@dataclass(frozen=True)
class Event:
    """A phase mark published on job_events (hole i S1/S2/S3, pass k, ...)."""

    time: float
    name: str
    data: dict = field(default_factory=dict)


class JointTimeline:
    """One joint's motion: pieces in time order, coasting between them."""

    def __init__(self, position: float, velocity: float = 0.0) -> None:
        self.pieces: list[Piece] = []
        self._starts: list[float] = []
        self._coast: list[tuple[float, float, float]] = [(0.0, position, velocity)]  # (t, p, v)
        self._coast_array: np.ndarray | None = None
        self._spans = np.zeros((0, 2))  # (start, end) per piece, as an array
        self._ruckig = np.zeros(0, bool)  # per piece: one dof of a ruckig move (DofSampler)
        self._rows = np.zeros((0, ROW_LENGTH))  # their sample_spans rows, read when first sampled
        self._row_known = np.zeros(0, bool)
        self._carried: list[tuple[float, float, Correction]] = []  # (from, until, plan time -> p, v, a)

    @property
    def end_time(self) -> float:
        return self._coast[-1][0]  # the last piece's end (0 before any), asked for every move added

    @property
    def settled_time(self) -> float:
        """When its last piece and every correction it carries are over: a move of this
        joint starts no sooner (only other joints' moves overlap a carried settling)."""
        return max([self.end_time] + [end for _, end, _ in self._carried])

    @property
    def start_position(self) -> float:
        return self._coast[0][1]

    @property
    def end_position(self) -> float:
        return self._coast[-1][1]

    @property
    def end_velocity(self) -> float:
        return self._coast[-1][2]

    def position_at(self, t: float) -> float:
        """Position at a time at or after the last piece (coasting included)."""
        t0, p0, v0 = self._coast[-1]
        return p0 + v0 * (t - t0)

    def carry(self, start: float, end: float, correction: Correction) -> None:
        """Add ``correction`` (plan times -> position, velocity and acceleration offsets) to
        whatever this joint is commanded from ``start`` (where its timeline ends) until
        ``end``: a compensated command still settling while the next move already runs
        (the drive is linear: its feedback is the sum of both responses). Pieces added
        later carry their share; where none is, the joint holds with it (flush)."""
        self._carried.append((start, end, correction))

    def flush(self) -> None:
        """Hold the joint with every correction still carried until it has settled."""
        if self._carried:
            self._fill(max(end for _, end, _ in self._carried))

    def _fill(self, until: float) -> None:
        """A hold carrying the corrections from the timeline's end up to ``until``."""
        start, position = self.end_time, self.end_position
        end = min(until, max((end for _, end, _ in self._carried), default=start))
        if end > start + 1e-12:
            def hold(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return np.full_like(t, position), np.zeros_like(t), np.zeros_like(t)
            self._append(self._carrying(Piece(start, end - start, hold)), position, 0.0)

    def _carrying(self, piece: Piece) -> Piece:
        """The piece plus the carried corrections over its span; those it outlasts dropped."""
        mine = [c for c in self._carried if c[0] < piece.end and c[1] > piece.start]
        self._carried = [c for c in self._carried if c[1] > piece.end]
        if not mine:
            return piece
        base = piece.sample

        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            p, v, a = (np.array(x, dtype=float) for x in base(t))
            g = t + piece.start
            for lo, hi, correction in mine:
                inside = (g >= lo) & (g < hi)
                if inside.any():
                    dp, dv, da = correction(g[inside])
                    p[inside] += dp
                    v[inside] += dv
                    a[inside] += da
            return p, v, a

        return Piece(piece.start, piece.duration, sample)

    def add(self, piece: Piece, end_position: float, end_velocity: float = 0.0) -> None:
        if piece.start < self.end_time - 1e-12:
            raise ValueError(f"piece at {piece.start} s overlaps the timeline ending {self.end_time} s")
        if self._carried:
            self._fill(piece.start)
            piece = self._carrying(piece)
        self._append(piece, end_position, end_velocity)

    def _append(self, piece: Piece, end_position: float, end_velocity: float) -> None:
        self.pieces.append(piece)
        self._starts.append(piece.start)
        self._coast.append((piece.end, end_position, end_velocity))

    def replace(self, k: int, piece: Piece) -> None:
        """Put ``piece`` in place of the k-th (same span: a correction superimposed on it)."""
        old = self.pieces[k]
        if (piece.start, piece.duration) != (old.start, old.duration):
            raise ValueError(f"a piece at {piece.start} s for {piece.duration} s cannot replace one at "
                             f"{old.start} s for {old.duration} s")
        self.pieces[k] = piece
        if k < len(self._ruckig):  # what sampling keeps of it, read again
            self._ruckig[k] = type(piece.sample) is DofSampler
            self._row_known[k] = False

    def add_hold(self, start: float, duration: float) -> None:
        """Stand still (a dwell) so that later moves of this joint start after it."""
        position = self.position_at(start)

        def hold(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return np.full_like(t, position), np.zeros_like(t), np.zeros_like(t)

        self.add(Piece(start, duration, hold), position)

    def sample(self, ts: np.ndarray, out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at sorted instants ts, written into ``out``
        (three arrays of len(ts), e.g. columns of a plan's sample) if given."""
        p, v, a = out if out is not None else (np.empty_like(ts), np.empty_like(ts), np.empty_like(ts))
        first = max(bisect.bisect_right(self._starts, ts[0]) - 1, 0) if len(ts) else 0
        last = bisect.bisect_right(self._starts, ts[-1]) if len(ts) else 0
        self._index_pieces()
        spans = self._spans[first:last]
        # Every piece's index range in one call; only pieces that hold instants are sampled.
        lo, hi = np.searchsorted(ts, spans, side="left").T
        # Coasting only where no piece is (the pieces overwrite the rest): piece i's coast
        # state applies after piece i-1 ends.
        gap_lo, gap_hi = self._gaps(lo, hi, len(ts))
        if len(gap_lo):
            if self._coast_array is None or len(self._coast_array) != len(self._coast):
                self._coast_array = np.asarray(self._coast)  # (t, p, v) rows, built once per change
            coast_t = self._coast_array[:, 0]
            first_state = np.searchsorted(coast_t, ts[gap_lo], side="right") - 1
            last_state = np.searchsorted(coast_t, ts[gap_hi - 1], side="right") - 1
            for g_lo, g_hi, i, i_last in zip(*(x.tolist() for x in (gap_lo, gap_hi, first_state, last_state))):
                # one coast state over the whole gap, or (a piece shorter than the gap between
                # two instants ended inside it) one per instant
                t0, p0, v0 = self._coast_array[max(i, 0)] if i == i_last else self._coast_at(ts[g_lo:g_hi]).T
                v[g_lo:g_hi] = v0
                p[g_lo:g_hi] = p0 + v0 * (ts[g_lo:g_hi] - t0)
                a[g_lo:g_hi] = 0.0
        held = np.nonzero(hi > lo)[0]
        # A later piece overwrites an earlier one where they share instants: in one pass
        # only where none do, the ruckig pieces all in one call, the others one by one.
        others = held
        if np.all(hi[held[:-1]] <= lo[held[1:]]):
            ruckig = held[self._ruckig[first + held]]
            if len(ruckig):
                sample_spans(self._rows_of(first + ruckig), spans[ruckig, 0], lo[ruckig], hi[ruckig], ts, (p, v, a))
            others = held[~self._ruckig[first + held]]
        for k in others.tolist():
            piece, k_lo, k_hi = self.pieces[first + k], int(lo[k]), int(hi[k])
            if isinstance(piece.sample, WritingSampler):
                piece.sample.write(ts[k_lo:k_hi] - piece.start, (p[k_lo:k_hi], v[k_lo:k_hi], a[k_lo:k_hi]))
            else:
                p[k_lo:k_hi], v[k_lo:k_hi], a[k_lo:k_hi] = piece.sample(ts[k_lo:k_hi] - piece.start)
        return p, v, a

    def _index_pieces(self) -> None:
        """The pieces' spans and kinds as arrays, extended to pieces added since."""
        known, n = len(self._spans), len(self.pieces)
        if known == n:
            return
        added = self.pieces[known:]
        self._spans = np.concatenate((self._spans, np.array([(q.start, q.end) for q in added]).reshape(-1, 2)))
        self._ruckig = np.concatenate((self._ruckig, [type(q.sample) is DofSampler for q in added]))
        self._row_known = np.concatenate((self._row_known, np.zeros(n - known, bool)))
        self._rows = np.resize(self._rows, (n, ROW_LENGTH))

    def _rows_of(self, which: np.ndarray) -> np.ndarray:
        """The sample_spans rows of the ruckig pieces ``which``, each read from its move once."""
        for k in which[~self._row_known[which]].tolist():
            sampler = self.pieces[k].sample
            self._rows[k] = sampler.move.row(sampler.dof)
            self._row_known[k] = True
        return self._rows[which]

    def _coast_at(self, ts: np.ndarray) -> np.ndarray:
        """The (t, p, v) coast state in force at each of the instants ts."""
        index = np.searchsorted(self._coast_array[:, 0], ts, side="right") - 1
        return self._coast_array[np.maximum(index, 0)]

    @staticmethod
    def _gaps(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The index ranges [gap_lo, gap_hi) in [0, n) outside every [lo, hi) (sorted by lo),
        as two arrays."""
        # Gap i runs from the furthest end of the pieces before piece i to its start.
        gap_lo = np.concatenate(([0], np.maximum.accumulate(hi))).astype(np.intp)
        gap_hi = np.concatenate((lo, [n])).astype(np.intp)
        keep = gap_hi > gap_lo
        return gap_lo[keep], gap_hi[keep]


@dataclass
class Plan:
    """Everything a job will do: joint timelines and phase events, in plan time (s)."""

    joints: tuple[str, ...]
    timelines: dict[str, JointTimeline]
    events: list[Event]

    @property
    def duration(self) -> float:
        return max(tl.end_time for tl in self.timelines.values())

    @shared_samples()  # every joint asks a multi-axis move for the same instants
    def sample(self, ts: np.ndarray, joints: tuple[str, ...] | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Setpoints at sorted plan times ts: three arrays of shape (len(ts), joints), of
        every joint or of ``joints`` only, in that order."""
        joints = self.joints if joints is None else joints
        out = np.empty((3, len(ts), len(joints)))
        for i, j in enumerate(joints):
            self.timelines[j].sample(ts, out=(out[0, :, i], out[1, :, i], out[2, :, i]))
        return out[0], out[1], out[2]

    def start_position(self) -> dict[str, float]:
        return {j: self.timelines[j].start_position for j in self.joints}

    def final_position(self) -> dict[str, float]:
        return {j: self.timelines[j].position_at(self.duration) for j in self.joints}
