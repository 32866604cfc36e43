"""A report's baselines (cnc_planner.baselines): planned in a child process while a run goes,
the report takes them from there when the run started where cnc-run expected, and gives the
same numbers as when it plans them itself."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner import baselines, planning
from cnc_planner.baselines import Beside, plan_beside
from cnc_planner.kinds.drill.report import other_cycles
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"


@pytest.fixture(autouse=True)
def nothing_kept(monkeypatch):
    monkeypatch.setattr(baselines, "_KEPT", {})
    monkeypatch.setattr(baselines, "_PENDING", [])


def _run(name: str):
    doc = load_job_file(JOBS / f"{name}.yaml")
    job = parse_job(doc)
    machine = load_machine(job.machine)
    return doc, machine, predicted_run(doc, plan_job(job, machine, dict(zip(machine.joint_names,
                                                                             machine.home_position))), machine)


def _start(run) -> dict[str, float]:
    return {j: float(run.feedback[0, run.column(j)]) for j in run.joints}


def _no_planning(*_args, **_kwargs):
    raise AssertionError("the report planned a baseline it was given")


def test_the_report_takes_the_baselines_planned_beside_and_they_equal_its_own(monkeypatch):
    doc, machine, run = _run("drill_row")
    own = other_cycles.__wrapped__(parse_job(doc), machine, _start(run))["conventional_cycle_time_s"]
    beside = plan_beside(doc, machine)
    assert beside.child is not None  # computed in a child process
    monkeypatch.setattr(planning, "plan_job", _no_planning)
    drill = build_report(run)["drill"]
    assert drill["conventional_cycle_time_s"] == own > drill["cycle_time_s"] > 0  # overlapped beats conventional
    assert baselines._PENDING == []  # collected by the report


def test_a_run_that_started_elsewhere_gets_its_own_baselines():
    doc, machine, run = _run("drill_row")
    plan_beside(doc, machine).collect()
    run.feedback[:, run.column("x")] += 1e-6  # not the home cnc-run's bridge starts at
    build_report(run)
    assert len(baselines._KEPT) == 2  # the one for home, and the one build_report had planned beside
    assert any(dict(key[3])["x"] == _start(run)["x"] for key in baselines._KEPT)


def test_a_report_plans_its_baselines_beside_and_gives_the_same_numbers_without(monkeypatch):
    _, _, run = _run("drill_row")
    beside_report = build_report(run)
    monkeypatch.setattr(baselines, "_KEPT", {})
    monkeypatch.delattr(baselines.os, "fork")  # no child: computed in place
    assert build_report(run) == beside_report


def test_a_failing_child_leaves_nothing_and_the_report_computes_it():
    def broken(job, machine, start):
        raise RuntimeError("no")
    broken.__wrapped__ = broken
    doc, machine, _ = _run("drill_row")
    beside = Beside([broken], parse_job(doc), machine, {"x": 0.0})
    beside.collect()
    assert baselines._KEPT == {}


def test_a_cancelled_child_is_gone_and_keeps_nothing():
    doc, machine, _ = _run("drill_row")
    job = parse_job(doc)
    beside = Beside([other_cycles], job, machine, dict(zip(machine.joint_names, np.zeros(4).tolist())))
    pid = beside.child.pid
    beside.cancel()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, 0)
    assert baselines._KEPT == {}


def test_a_kind_without_baselines_starts_no_child():
    doc, machine, _ = _run("turn_stepped")
    assert plan_beside(doc, machine).child is None
