"""What a roughing cycle is made of: straight moves from the machining origin Q0 back to Q0,
and what they measure (path, feed travel, and the feed travel spent in air).

A move's length in air is found by replaying the moves against the stock (StockModel), so
it counts what the path touches, not what it intends to cut.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.kinds.turn import Frame
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.turn.stock import Point, StockModel


@dataclass(frozen=True)
class TurnMove:
    """One straight move of the roughing cycle to (z, x); cutting if planned to remove material."""

    kind: str  # "rapid" | "feed"
    z: float
    x: float
    cutting: bool

    @property
    def end(self) -> Point:
        return (self.z, self.x)


@dataclass
class RoughingPlan:
    """A roughing cycle as straight moves from the machining origin Q0 back to Q0, in the
    cycle's own axes (frame: the job's directions); stock is the one the cycle started from.

    passes counts pass lines cut over one free stretch each (and the contour pass, if any).
    """

    moves: list[TurnMove]
    passes: int
    origin: Point
    stock: list[Point]
    frame: Frame = Frame()

    def job_moves(self) -> list[TurnMove]:
        """The moves in the job's (z, x)."""
        return [TurnMove(m.kind, *self.frame.to_job(m.z, m.x), m.cutting) for m in self.moves]

    def job_segments(self) -> list[tuple[Point, TurnMove]]:
        """Each move with the point it starts from, in the job's (z, x)."""
        return with_starts(self.frame.to_job(*self.origin), self.job_moves())

    def segments(self) -> list[tuple[Point, TurnMove]]:
        """Each move with the point it starts from."""
        return with_starts(self.origin, self.moves)

    @property
    def path_length(self) -> float:
        return sum(math.dist(a, m.end) for a, m in self.segments())

    @property
    def feed_length(self) -> float:
        return sum(math.dist(a, m.end) for a, m in self.segments() if m.kind == "feed")

    def engagement(self) -> list[float]:
        """Per move, the length along which the tool touches the stock left at that moment."""
        model = StockModel(self.stock)
        return [model.cut(a, m.end) for a, m in self.segments()]

    @property
    def air_feed_length(self) -> float:
        """Feed-rate travel in which the tool touches no material: the time the method saves."""
        return sum(
            math.dist(a, m.end) - touched
            for (a, m), touched in zip(self.segments(), self.engagement())
            if m.kind == "feed"
        )

    def points(self, step: float) -> np.ndarray:
        """The tool tip sampled along the whole path at most step apart, shape (n, 2)."""
        chunks = [np.array([self.origin])]
        for a, m in self.segments():
            n = max(1, math.ceil(math.dist(a, m.end) / step))
            t = np.linspace(0.0, 1.0, n + 1)[1:, None]
            chunks.append(np.array(a) + t * (np.array(m.end) - np.array(a)))
        return np.vstack(chunks)

    def to_dict(self) -> dict:
        """Summary for reports, in mm."""
        return {
            "passes": self.passes,
            "air_feed_mm": round(float(to_mm(self.air_feed_length)), 3),
            "path_mm": round(float(to_mm(self.path_length)), 3),
            "feed_mm": round(float(to_mm(self.feed_length)), 3),
        }


def with_starts(origin: Point, moves: list[TurnMove]) -> list[tuple[Point, TurnMove]]:
    """Each move with the point it starts from: the origin, then the previous move's end."""
    starts = [origin] + [m.end for m in moves[:-1]]
    return list(zip(starts, moves))
