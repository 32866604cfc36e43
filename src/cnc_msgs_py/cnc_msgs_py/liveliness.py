"""How many planners DDS holds alive, counted from liveliness events that may miss one.

rclpy arms a subscription's liveliness event after the subscription exists, so a writer
that DDS found alive in between is never announced: the changes then add up one short
(measured: -1 on the loss of the only planner), and the absolute ``alive_count`` DDS
reports is short the same way. A count of writers cannot go below zero, so every time the
running sum of the changes reaches a new low, that many "alive" events were missed before.

A status received is no event: it says the planner is heard, not how many are, and it may
be taken before or after the planner's "alive" (DDS raises it on the first message or
liveliness assertion, whichever comes first). Counting a status as one writer made two of
one planner when its "alive" came after, and the planner's loss went unreported (CI, 1 run).
"""
from __future__ import annotations


class AliveWriters:
    """The number of alive writers of a topic, from DDS's ``alive_count_change`` values."""

    def __init__(self) -> None:
        self._sum = 0  # of the changes seen
        self._missed = 0  # "alive" events that came before the event was armed

    def change(self, alive_count_change: int) -> int:
        """Apply one liveliness event's change; returns the writers alive after it."""
        self._sum += alive_count_change
        self._missed = max(self._missed, -self._sum)
        return self.count

    @property
    def count(self) -> int:
        return self._sum + self._missed
