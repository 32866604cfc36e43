"""The goals a planner has received, and the latest it said of each job: repeats are
answered, never run twice.

A goal is sent once on a volatile topic, so a planner that is not yet listening when it
is sent (its side of the DDS match still to come, on a loaded host) never sees it, and the
cell controller waits for a status that cannot come. The client therefore sends a goal
again while no status for it has been heard (cnc_msgs_py.client). A goal identical to one
received before, byte for byte, is such a repeat: it is answered with its job's latest
status (nothing yet while the first copy is being prepared) and not planned again. A goal
that differs but reuses a job_id is not a repeat: the executive rejects it, naming job_id.
"""
from __future__ import annotations

import hashlib

from cnc_msgs_py.status import Status

KEPT = 10_000  # goals and jobs remembered (the newest): a client resends for seconds only, and
# a repeat of a goal forgotten since is rejected by the executive (its job_id was used), not run


class GoalLedger:
    """Goals by digest, what each came to, and each job's latest status."""

    def __init__(self) -> None:
        # goal digest -> None while it is prepared, then its job_id (admitted) or its rejection
        self._goals: dict[bytes, str | Status | None] = {}
        self._latest: dict[str, Status] = {}  # job_id -> its latest status

    @staticmethod
    def key(text: str) -> bytes:
        """A goal's identity: the digest of its exact text."""
        return hashlib.sha256(text.encode("utf-8", "surrogatepass")).digest()

    def is_repeat(self, key: bytes) -> bool:
        return key in self._goals

    def receive(self, key: bytes) -> None:
        """A new goal, to be prepared."""
        _remember(self._goals, key, None)

    def admitted(self, key: bytes, status: Status) -> None:
        """The goal's status on admission: a rejection answers its repeats as it stands
        (another goal may hold the job_id it named); otherwise they get the job's latest."""
        _remember(self._goals, key, status if status.state == "rejected" else status.job_id)

    def published(self, status: Status) -> None:
        if status.state != "rejected":  # a rejection is its goal's, not the job_id holder's
            _remember(self._latest, status.job_id, status)

    def answer(self, key: bytes) -> Status | None:
        """What to say to a repeat of the goal ``key``: its rejection or its job's latest
        status, or None while the first copy is still being prepared."""
        goal = self._goals.get(key)
        if goal is None or isinstance(goal, Status):
            return goal
        return self._latest.get(goal)


def _remember(kept: dict, key: object, value: object) -> None:
    """Set ``key`` as the newest entry of ``kept``, which holds at most KEPT."""
    kept.pop(key, None)
    kept[key] = value
    if len(kept) > KEPT:
        del kept[next(iter(kept))]
