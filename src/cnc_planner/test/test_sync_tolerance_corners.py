"""G33 passes and G33.1 rigid taps on drives that are not their description: a small pass
(with a 45 degree exit) on the lathe and a tap on mill3, each planned once on the described
machine, hold their lock to the spindle within the judge's 0.02 mm on the predicted
feedback of every corner of the drives' tolerance (the k-th corner of every joint together,
as bench/program_corners.py pairs them), judged by the real judge (build_report); and the
margin is the planner's: without it (ease 1) corners stray. A move too short for the ramps
that would hold it is refused."""
from __future__ import annotations

import functools

import pytest

from cnc_analysis.spindle_sync import LOCK_TOLERANCE
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.plant import Plant, tolerance_corners
from cnc_msgs_py.schema import JobError
from cnc_planner.kinds.sync import margin
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

PASS = {"machine": "lathe", "spindle_rpm": 600, "sync": [
    {"rapid": {"x": 12, "z": 5}}, {"sync": {"z": -5}, "lead": 2.0},
    {"sync": {"x": 14, "z": -7}, "lead": 2.0 * 2.0**0.5}, {"rapid": {"x": 15}}]}
TAP = {"machine": "mill3", "spindle_rpm": 500, "sync": [
    {"rapid": {"x": 10, "y": 5, "z": 2}}, {"tap": {"z": -6}, "lead": 1.25}, {"rapid": {"z": 10}}]}
CASES = {"pass": (PASS, ("x", "z", "spindle")), "tap": (TAP, ("z", "spindle"))}


def _doc(case: dict) -> dict:
    return {"schema": "cnc_job/1", "job_id": "sync-corners", "kind": "sync", "tool": {}, **case}


def _corners(machine, joints: tuple[str, ...]) -> list[Plant]:
    each = [tolerance_corners(machine.drives[j]) for j in joints]
    return [Plant(f"corner {k}", {**machine.drives, **{j: c[k % len(c)] for j, c in zip(joints, each)}})
            for k in range(max(len(c) for c in each))]


@functools.cache
def _verdicts(name: str) -> list[tuple[str, dict]]:
    case, joints = CASES[name]
    doc = _doc(case)
    machine = load_machine(doc["machine"])
    plan = plan_job(parse_job(doc), machine)
    return [(plant.name, build_report(predicted_run(doc, plan, machine, plant=plant), machine)["spindle_sync"])
            for plant in _corners(machine, joints)]


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_tolerance_corner_holds_the_lock_on_its_predicted_feedback(name):
    verdicts = _verdicts(name)
    assert len(verdicts) == 16
    for corner, section in verdicts:
        assert section["verdict"]["passed"], f"{corner}: {section['verdict']['says']}"
        found = section["passes"] if name == "pass" else section["taps"]
        assert len(found) == 1, corner
        # the planner's own margin: within LOCK_SHARE of the tolerance (a little above, where
        # its wider band and the judge's windows differ, never past the tolerance)
        assert section["max_lock_error_mm"] <= 0.02 * (margin.LOCK_SHARE + 0.05), corner


def test_without_the_margin_corners_stray(monkeypatch):
    """The shortest ramps the limits allow (ease 1 whatever the prediction says) lose the lock
    on some corners, the pass's and the tap's: the margin, not the judge, is what holds."""
    monkeypatch.setattr(margin, "EASES", (1.0,))
    monkeypatch.setattr(margin, "LOCK_SHARE", 1e9)
    _verdicts.cache_clear()
    try:
        failed = {name: [c for c, s in _verdicts(name) if not s["verdict"]["passed"]] for name in CASES}
    finally:
        _verdicts.cache_clear()
    assert all(failed.values()), failed


def test_the_planner_holds_the_judges_tolerance():
    """The planning core does not load the judge: its copy of the tolerance must be the judge's."""
    assert margin.LOCK_TOLERANCE == LOCK_TOLERANCE


def test_a_move_too_short_for_the_ramps_that_would_hold_its_lock_is_refused():
    """0.6 mm at K2 S600: the shortest ramps fit (0.27 mm) but stray past the margin on some
    corner, and ramps long enough to hold do not fit the move."""
    short = {**PASS, "sync": [{"rapid": {"x": 12, "z": 5}}, {"sync": {"z": 4.4}, "lead": 2.0}]}
    with pytest.raises(JobError) as err:
        plan_job(parse_job(_doc(short)), load_machine("lathe"))
    assert str(err.value).startswith("sync[1].sync: no ramp holds the lock on every drive inside the tolerance")
    assert "longer ones do not fit (too short to be locked to the spindle" in str(err.value)
