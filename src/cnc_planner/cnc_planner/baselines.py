"""What a report compares a run with that the recording does not change: the same job
planned another way (the conventional drilling cycle, the other hole order) from where the
run started, on the drive model.

A baseline costs as much as planning the job again (1 s for a 300-hole plate, more than
reading its recording), and depends only on the job, the machine and the start. So it is
kept per (job, machine, start) once computed (``baseline``), and cnc-run computes it in a
child process while the job runs (``plan_beside``), at the lowest priority: on the share of
the two cores that the simulation leaves idle. The report takes it from there if the run
did start where cnc-run expected, and computes it itself otherwise: the same numbers either
way.
"""
from __future__ import annotations

import functools
import json
import os
import pickle
import signal
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np

from cnc_msgs_py.machine import Machine

Baseline = Callable[[SimpleNamespace, Machine, dict[str, float]], dict]

_KEPT: dict[tuple[str, str, str, tuple], dict] = {}  # computed baselines by (function, job, machine, start)


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
        if key not in _KEPT:
            _KEPT[key] = fn(job, machine, start)
        return _KEPT[key]
    return kept


class Beside:
    """Baselines computed in a forked child process; ``collect`` keeps its values."""

    def __init__(self, functions: list[Baseline], job: SimpleNamespace, machine: Machine,
                 start: dict[str, float]) -> None:
        self.pid = 0
        if not functions or not hasattr(os, "fork"):
            return
        self.read, write = os.pipe()
        self.pid = os.fork()
        if self.pid == 0:  # the child: compute, hand the values over, leave without cleaning up the parent's
            status = 1
            try:
                os.close(self.read)
                os.nice(19)
                values = {_key(fn.__wrapped__, job, machine, start): fn.__wrapped__(job, machine, start)
                          for fn in functions}
                with os.fdopen(write, "wb") as out:
                    pickle.dump(values, out)
                status = 0
            finally:
                os._exit(status)
        os.close(write)

    def collect(self) -> None:
        """Wait for the child and keep what it computed (nothing if it failed: the report
        then computes its baselines itself)."""
        if not self.pid:
            return
        with os.fdopen(self.read, "rb") as source:
            data = source.read()
        _, status = os.waitpid(self.pid, 0)
        self.pid = 0
        if status == 0:
            _KEPT.update(pickle.loads(data))

    def cancel(self) -> None:
        """Stop the child (the run failed: no report will want its values)."""
        if self.pid:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            os.close(self.read)
            self.pid = 0


def plan_beside(doc: dict, machine: Machine) -> Beside:
    """Start computing the baselines of job ``doc``'s report section (its kind's
    ``baselines_at``) from where cnc-run's bridge starts: at rest at the machine's home,
    as its encoders read it.

    Raises:
        cnc_msgs_py.schema.JobError: the job is not valid (checked before, by the caller).
    """
    from cnc_msgs_py.job import parse_job
    from cnc_servo_bridge.drive import DriveModel

    from cnc_planner.kinds import KINDS
    from cnc_planner.kinds.kind import resolve
    from cnc_planner.motion import SERVO_PERIOD

    job = parse_job(doc)
    section = KINDS[job.kind].report
    functions = [resolve(ref) for ref in section.baselines_at] if section is not None else []
    home = DriveModel(machine, SERVO_PERIOD).quantise(np.asarray(machine.home_position, dtype=float))
    return Beside(functions, job, machine, dict(zip(machine.joint_names, home.tolist())))
