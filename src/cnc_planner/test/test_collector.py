"""The cyclic collector waits while a plan is made, and comes back however planning ends."""
from __future__ import annotations

import gc
import threading
from pathlib import Path

import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.motion import collector
from cnc_planner.planning import plan_job

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"


def test_paused_nests_and_restores_the_collector_even_after_an_error():
    assert gc.isenabled()
    with collector.paused():
        assert not gc.isenabled()
        with pytest.raises(RuntimeError):
            with collector.paused():
                raise RuntimeError("a planning error")
        assert not gc.isenabled()  # the outer pause still holds
    assert gc.isenabled()


def test_a_collector_switched_off_by_its_owner_stays_off():
    gc.disable()
    try:
        with collector.paused():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_pauses_on_two_threads_end_with_the_last():
    inside, release = threading.Event(), threading.Event()

    def plan_elsewhere() -> None:
        with collector.paused():
            inside.set()
            release.wait(10)

    other = threading.Thread(target=plan_elsewhere)
    with collector.paused():
        other.start()
        assert inside.wait(10)
    assert not gc.isenabled()  # the other thread still plans
    release.set()
    other.join(10)
    assert gc.isenabled()


def test_planning_leaves_the_collector_on():
    job = parse_job(load_job_file(JOBS / "drill_row.yaml"))
    assert plan_job(job, load_machine(job.machine)).duration > 0 and gc.isenabled()
