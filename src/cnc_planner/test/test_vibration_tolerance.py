"""Chip-breaking vibration on drives that are not their description: every vibrated feed of
the example jobs still breaks its chip within its window (cnc_analysis.aircut, on feedback)
on every plant drawn inside the description's tolerance and at every corner of it. The
jobs are planned once on the described machines and their setpoints run through each
plant's drive model, the spindle as described."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.plant import tolerance_corners
from cnc_analysis.aircut import analyze_aircut, chip_limit_revs
from cnc_planner.planning import plan_job
from cnc_servo_bridge.drive import DriveModel

import drawn_plants

PERIOD = 1e-3
JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
MACHINES = {"lathe_feed_vibration": load_machine("lathe"), "drill_vibration": load_machine("mill3")}


def axes(name: str) -> tuple[str, ...]:
    """The job's machine's feed axes: every joint but the spindle."""
    return tuple(j for j in MACHINES[name].joint_names if j != SPINDLE)


@functools.cache
def planned(name: str):
    """(plan, t, setpoints) of the example job planned on its described machine."""
    plan = plan_job(parse_job(load_job_file(JOBS / f"{name}.yaml")), MACHINES[name])
    t = np.arange(0.0, plan.duration + PERIOD / 2, PERIOD)
    return plan, t, plan.sample(t)


def chips(name: str, drives: dict) -> list[tuple[float, float, int]]:
    """Per vibrated feed on the plant's feedback: (longest chip, its waveform's limit, both in
    revolutions, revolutions analysed), the feed read as the vibration report reads it."""
    machine = MACHINES[name]
    plan, t, command = planned(name)
    fb = DriveModel(machine, PERIOD, drives={**machine.drives, **drives}).simulate(*command)[0]
    starts = [e for e in plan.events if e.name == "vibration_feed"]
    ends = [e.time for e in plan.events if e.name == "vibration_end"]
    assert starts and len(starts) == len(ends)
    out = []
    for start, end in zip(starts, ends):
        inside = (t >= start.time) & (t <= end)
        cols = [machine.joint_names.index(j) for j in start.data["joints"]]
        progress = (fb[:, cols] - np.array(start.data["start"])) @ np.array(start.data["direction"])
        report = analyze_aircut(fb[inside, machine.joint_names.index(SPINDLE)], progress[inside])
        out.append((report.max_chip_revs, chip_limit_revs(start.data.get("vibration")), report.revolutions))
    return out


@st.composite
def jobs_and_plants(draw) -> tuple[str, dict]:
    name = draw(st.sampled_from(sorted(MACHINES)))
    return name, draw(drawn_plants.plants_within(MACHINES[name], axes(name), PERIOD))


@settings(max_examples=20, deadline=None)
@given(case=jobs_and_plants())
def test_every_plant_inside_the_tolerance_breaks_the_chip(case):
    name, plant = case
    for chip, limit, revolutions in chips(name, plant):
        assert revolutions >= 5 and chip <= limit


@pytest.mark.parametrize("name", sorted(MACHINES))
def test_every_corner_of_the_tolerance_breaks_the_chip(name):
    machine = MACHINES[name]
    corners = {j: tolerance_corners(machine.drives[j]) for j in axes(name)}
    for i in range(len(corners["x"])):
        plant = {j: corners[j][i] for j in axes(name)}
        assert all(chip <= limit for chip, limit, _ in chips(name, plant)), plant["x"]
