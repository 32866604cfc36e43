"""Plants inside and outside the description's tolerance, judged by the report as a
recording would be (report.predicted_run on the plant's drives): inside it every verdict
holds; outside it a miss on the feedback always fails a verdict (cnc-run and cnc-analyze
exit 4), never a silent success."""
from __future__ import annotations

import dataclasses
import functools

from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_msgs_py.gcode.document import load_job_file
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.plant import Plant, outside_tolerance
from cnc_planner.cli import failed_verdicts
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

from support import ROOT

PERIOD = 1e-3
JOBS = ("drill_row", "thread_m12", "lathe_feed_vibration")


@functools.cache
def planned(name: str):
    doc = load_job_file(ROOT / "config" / "jobs" / f"{name}.yaml")
    job = parse_job(doc)
    machine = load_machine(job.machine)
    return doc, machine, plan_job(job, machine, machine.home_joints)


def judged(name: str, factors: dict) -> dict:
    """The report of the job run on a plant: every axis but the spindle changed by ``factors``."""
    doc, machine, plan = planned(name)
    drives = {j: d if j == SPINDLE else dataclasses.replace(
        d, kp=d.kp * factors["kp"], velocity_lag=d.velocity_lag * factors["lag"],
        velocity_ff=d.velocity_ff * factors["ff"], delay=factors["delay"]) for j, d in machine.drives.items()}
    plant = Plant("drawn", drives)
    report = build_report(predicted_run(doc, plan, machine, PERIOD, plant), machine)
    report["outside"] = outside_tolerance(machine, plant)
    return report


inside = st.fixed_dictionaries({"kp": st.floats(0.7, 1.3), "lag": st.floats(1.0, 3.0), "ff": st.floats(0.95, 1.0),
                                "delay": st.sampled_from([0.0, 0.001, 0.002])})
outside = st.fixed_dictionaries({"kp": st.floats(0.25, 0.6), "lag": st.floats(4.0, 12.0), "ff": st.floats(0.8, 0.9),
                                 "delay": st.sampled_from([0.004, 0.006, 0.008])})


def misses(report: dict) -> list[str]:
    """What the judge's own figures say went wrong, read apart from the verdicts."""
    found = []
    drill, thread, aircut = report.get("drill") or {}, report.get("thread") or {}, report.get("aircut") or {}
    if drill.get("safety_violations"):
        found.append("X/Y below R")
    if thread and (thread["overcut_mm"] > 0.005 or not thread["chips_broken"]):
        found.append("thread over depth or chips")
    if aircut and aircut["max_chip_revs"] > 1.5:  # lathe_feed_vibration: D 1.5, a chip of at most a window
        found.append("long chip")
    return found


@settings(max_examples=6, deadline=None)
@given(name=st.sampled_from(JOBS), factors=inside)
def test_inside_the_tolerance_every_verdict_holds(name, factors):
    report = judged(name, factors)
    assert report["outside"] == []
    assert failed_verdicts(report) == [], {k: v["verdict"] for k, v in report.items()
                                           if isinstance(v, dict) and "verdict" in v}


@settings(max_examples=6, deadline=None)
@given(name=st.sampled_from(JOBS), factors=outside)
def test_outside_the_tolerance_a_miss_always_fails_a_verdict(name, factors):
    report = judged(name, factors)
    assert report["outside"]
    if misses(report):
        assert failed_verdicts(report)


def test_a_plant_far_outside_fails_drilling_on_feedback():
    """Half the gain, a loop eight times slower and 6 ms of delay: X/Y moves below R."""
    report = judged("drill_row", {"kp": 0.3, "lag": 8.0, "ff": 0.85, "delay": 0.006})
    assert report["drill"]["safety_violations"] > 0 and "drill" in failed_verdicts(report)
