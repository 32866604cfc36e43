"""Candidate joins onto a pass's helix, one servo instant apart, a helix revolution at a
time (Revolution), and the search the join finding relies on (latest): the thread cycle
passes over the joins z cannot reach in time without asking ruckig about each.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np


def latest(holds: Callable[[int], bool], lo: int, hi: int, hint: int | None) -> int:
    """The latest k in [lo, hi) at which ``holds``, given that it holds at lo and, once it
    fails, fails for every later k: searched outwards from ``hint`` (doubling the step),
    then by bisection, so that a hint next to the answer costs two or three calls."""
    if hint is not None and lo < hint < hi:
        step = 1
        if holds(hint):
            lo = hint
            while lo + step < hi and holds(lo + step):
                lo, step = lo + step, 2 * step
            hi = min(hi, lo + step)
        else:
            hi = hint
            while hi - step > lo and not holds(hi - step):
                hi, step = hi - step, 2 * step
            lo = max(lo, hi - step)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if holds(mid) else (lo, mid)
    return lo


class Revolution:
    """The candidate joins onto one helix revolution, in order, as (k, t_join, theta_ref, the
    helix state there (rows x, z; columns p, v, a)): each made when it is asked for (most
    of a revolution is passed over unread)."""

    __slots__ = ("ks", "t_joins", "theta_ref", "targets", "probes", "reach")

    def __init__(self, ks: np.ndarray, t_joins: np.ndarray, theta_ref: float, targets: np.ndarray,
                 probes: np.ndarray) -> None:
        self.ks, self.t_joins, self.theta_ref, self.targets = ks, t_joins, theta_ref, targets
        self.probes = probes  # the helix's acceleration (x, z) JERK_PROBE_S after each join (for _smooth_join)
        self.reach: dict[tuple, tuple[int, int]] = {}  # ThreadCycle._may_reach's bisections

    def __len__(self) -> int:
        return self.ks.size

    def __getitem__(self, i: int) -> tuple[int, float, float, np.ndarray, tuple[Revolution, int]]:
        """The join and its place (this revolution, i)."""
        return int(self.ks[i]), float(self.t_joins[i]), self.theta_ref, self.targets[i], (self, i)

    def joins(self, lo: int = 0):
        """The joins from the lo-th on."""
        return (self[i] for i in range(lo, len(self)))

    __iter__ = joins
