"""Peck drilling below the R plane: G83 (full retract to R) and G73 (chip-break retract),
with a full retract every N breaks if asked.

Each peck feeds ``depth`` (Q) deeper than the previous bottom. After a retract the tool
comes back down fast (time-optimal, jerk-limited) to REENTRY_GAP above the previous bottom,
arriving there at the cutting feed, and feeds on from there: no air is fed at cutting speed
and the fast re-entry never reaches the previous bottom. All of it happens over the hole:
X/Y stands still until the final retract has brought the tip above the cycle's X/Y plane.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Callable

from cnc_planner.motion.moves import RuckigMove

BREAK_RETRACT = 0.5e-3  # m: a chip-break retract (G73) backs off this far from the bottom
REENTRY_GAP = 0.2e-3  # m above the previous bottom: the fast re-entry hands over to the feed here
PLANE_GAP = 0.2e-3  # m: with full retracts to R the X/Y plane lies this far above the highest R, so
# every peck of a hole stays one visit below that plane (the overlap timing reads visits)

# A Z move to a state: (p0, v0, a0, p1, v1, speed limit or None for rapid) -> RuckigMove.
ZMove = Callable[[float, float, float, float, float, float | None], RuckigMove]


@dataclass(frozen=True)
class Peck:
    """depth: Q per peck (m); full: G83 (every retract to R) or G73 (chip-break retracts);
    full_every: with chip-break retracts, every N-th retract goes to R."""

    depth: float
    full: bool = True
    full_every: int | None = None

    def __post_init__(self) -> None:
        if not self.depth > 0:
            raise ValueError("peck.depth: must be > 0")
        if self.full_every is not None and (self.full or self.full_every < 1):
            raise ValueError("peck.full_every: a whole number >= 1, with chip-break retracts only")

    def is_full(self, k: int) -> bool:
        """Whether retract k (1 = after the first peck) goes all the way to R."""
        return self.full or (self.full_every is not None and k % self.full_every == 0)


@dataclass(frozen=True)
class PeckMove:
    """One Z move of a peck sequence: kind is feed, retract or reentry; ``bottom`` is the
    previous peck's bottom for a retract or re-entry, the new one for a feed."""

    kind: str
    move: RuckigMove
    peck: int
    bottom: float


def levels(surface: float, bottom: float, depth: float) -> list[float]:
    """Bottom of every peck: Q, 2Q, ... below the surface, the last at the hole's bottom."""
    out = []
    k = 1
    while surface - k * depth > bottom + 1e-9:
        out.append(surface - k * depth)
        k += 1
    return out + [bottom]


def peck_moves(z_move: ZMove, peck: Peck, feed: float, top: float, v0: float,
               surface: float, bottom: float, turn: float | None = None) -> list[PeckMove]:
    """The Z moves of one hole from R (``top``, moving at ``v0``) to rest at its bottom; the
    last feed's command turns at ``turn`` (where the drive's feedback turns at the bottom,
    bottom.Bottoms.turning_point), at the bottom if not given."""
    moves: list[PeckMove] = []
    state = (top, v0, 0.0)
    previous = None
    bottoms = levels(surface, bottom, peck.depth)
    for k, level in enumerate(bottoms):
        if previous is not None:
            up = top if peck.is_full(k) else min(previous + BREAK_RETRACT, top)
            moves.append(PeckMove("retract", z_move(previous, 0.0, 0.0, up, 0.0, None), k, previous))
            entry = min(previous + REENTRY_GAP, up)
            moves.append(PeckMove("reentry", z_move(up, 0.0, 0.0, entry, -feed, None), k, previous))
            state = (entry, -feed, 0.0)
        end = turn if turn is not None and k == len(bottoms) - 1 else level
        moves.append(PeckMove("feed", z_move(*state, end, 0.0, feed), k, level))
        previous = level
    return moves


def peck_of(d: SimpleNamespace) -> Peck | None:
    return None if d.peck is None else Peck(d.peck.depth, d.peck.retract == "full", d.peck.full_every)


def xy_plane(d: SimpleNamespace, planes: list | tuple) -> float:
    """The highest R, and just above it when pecks retract fully to R (peck.PLANE_GAP)."""
    r_z = max(r for _, r, _ in planes)
    return r_z + PLANE_GAP if d.peck is not None and (d.peck.retract == "full" or d.peck.full_every) else r_z
