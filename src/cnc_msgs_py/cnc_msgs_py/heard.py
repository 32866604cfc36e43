"""What a session knows of its nodes from their /diagnostics: which processes talk under
its namespace (a run tells its own nodes from another run's by pid), which planners have
heard their bridge, and how many planner heartbeats came.

Plain Python over diagnostic_msgs' fields (``status``: name, hardware_id, values of
key/value): no ROS import, so a cell's controller can use it on any transport.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from cnc_msgs_py import topics


class NodesHeard:
    """The nodes heard under ``namespace`` (their diagnostics' hardware_id)."""

    def __init__(self, namespace: str) -> None:
        self.namespace = namespace
        self.pids: set[int] = set()  # processes whose diagnostics name this namespace
        self.ready: set[int] = set()  # planners among them that have heard their bridge
        self.planner_heartbeats = 0  # planner diagnostics (it is up and talking)

    def hear(self, statuses: Iterable[Any]) -> None:
        """Take one DiagnosticArray's statuses."""
        statuses = list(statuses)
        self.planner_heartbeats += any(status.name.startswith("cnc_planner") for status in statuses)
        for status in statuses:
            if status.hardware_id != self.namespace:
                continue
            values = {kv.key: kv.value for kv in status.values}
            if topics.PID_KEY not in values:
                continue
            pid = int(values[topics.PID_KEY])
            self.pids.add(pid)
            if values.get(topics.READY_KEY) == topics.READY:
                self.ready.add(pid)
