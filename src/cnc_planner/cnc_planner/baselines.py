"""What a report compares a run with that the recording does not change: the same job
planned another way (the conventional drilling cycle, the other hole order) from where the
run started, on the drive model.

A baseline costs as much as planning the job again (0.75 s for a 300-hole plate, more than
reading its recording), and depends only on the job, the machine and the start. So it is
kept per (job, machine, start) once computed (``baseline``), and computed in a child
process (``Beside``) while other work goes on: cnc-run starts it with the job
(``plan_beside``), at the lowest priority, on the share of the two cores that the
simulation leaves idle; build_report starts it before it judges the rest. A baseline asked
for waits for the children started and takes their value if it is the one asked for (the
run did start where cnc-run expected); else it is computed in place: the same numbers
either way.
"""
from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_planner.forked import Forked

Baseline = Callable[[SimpleNamespace, Machine, dict[str, float]], dict]

_KEPT: dict[tuple[str, str, str, tuple], dict] = {}  # computed baselines by (function, job, machine, start)
_PENDING: list["Beside"] = []  # children computing some


def _plain(value: Any) -> Any:
    """A job's values as JSON can write them, for a key."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    return vars(value) if hasattr(value, "__dict__") else repr(value)


def _key(fn: Baseline, job: SimpleNamespace, machine: Machine, start: dict[str, float]) -> tuple:
    return (f"{fn.__module__}:{fn.__qualname__}", json.dumps(job, default=_plain, sort_keys=True), repr(machine),
            tuple(sorted(start.items())))


def baseline(fn: Baseline) -> Baseline:
    """``fn`` (job, machine, start) -> dict, computed once per job, machine and start, or
    taken from what ``plan_beside`` computed."""
    @functools.wraps(fn)
    def kept(job: SimpleNamespace, machine: Machine, start: dict[str, float]) -> dict:
        key = _key(fn, job, machine, start)
        while key not in _KEPT and _PENDING:
            _PENDING[0].collect()
        if key not in _KEPT:
            _KEPT[key] = fn(job, machine, start)
        return _KEPT[key]
    return kept


class Beside:
    """Baselines computed in a forked child process (cnc_planner.forked) at ``nice``
    priority, those not kept already; their values are kept once a baseline asks for them
    (or on ``collect``)."""

    def __init__(self, functions: list[Baseline], job: SimpleNamespace, machine: Machine,
                 start: dict[str, float], nice: int = 0) -> None:
        coming = set(_KEPT).union(*(b.keys for b in _PENDING))
        wanted = [fn for fn in functions if _key(fn.__wrapped__, job, machine, start) not in coming]
        self.keys = {_key(fn.__wrapped__, job, machine, start) for fn in wanted}

        def compute() -> dict:
            return {_key(fn.__wrapped__, job, machine, start): fn.__wrapped__(job, machine, start) for fn in wanted}
        self.child = Forked(compute, nice=nice) if wanted and hasattr(os, "fork") else None
        if self.child is not None:
            _PENDING.append(self)

    def collect(self) -> None:
        """Wait for the child and keep what it computed (nothing if it failed: the report
        then computes its baselines itself)."""
        if self.child is not None:
            done, values = self.child.result()
            self._forget()
            if done:
                _KEPT.update(values)

    def cancel(self) -> None:
        """Stop the child (the run failed: no report will want its values)."""
        if self.child is not None:
            self.child.cancel()
            self._forget()

    def _forget(self) -> None:
        self.child = None
        _PENDING.remove(self)


def drop_pending() -> None:
    """Stop the children still computing baselines that nothing asked for."""
    for pending in list(_PENDING):
        pending.cancel()


def beside(section: Any, job: SimpleNamespace, machine: Machine, start: dict[str, float],
           nice: int = 0) -> Beside:
    """Start computing a report section's baselines (its ``baselines_at``) beside."""
    from cnc_planner.kinds.kind import resolve

    functions = [resolve(ref) for ref in section.baselines_at] if section is not None else []
    return Beside(functions, job, machine, start, nice)


def plan_beside(doc: dict, machine: Machine) -> Beside:
    """Start computing the baselines of job ``doc``'s report section, at the lowest
    priority, from where cnc-run's bridge starts: at rest at the machine's home, as its
    encoders read it.

    Raises:
        cnc_msgs_py.schema.JobError: the job is not valid (checked before, by the caller).
    """
    from cnc_msgs_py.job import parse_job
    from cnc_servo_bridge.drive import DriveModel

    from cnc_planner.kinds import KINDS
    from cnc_planner.motion import SERVO_PERIOD

    job = parse_job(doc)
    home = DriveModel(machine, SERVO_PERIOD).quantise(np.asarray(machine.home_position, dtype=float))
    return beside(KINDS[job.kind].report, job, machine, dict(zip(machine.joint_names, home.tolist())), nice=19)
