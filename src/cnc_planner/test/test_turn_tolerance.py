"""Rough turning on drives that are not their description: on no plant drawn inside the
description's tolerance, nor at any corner of it, does the tool tip enter the final part on
feedback; the finishing allowance takes the servo lag. The example jobs are planned once on
the described lathe and their setpoints run through each plant's drive model."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.plant import tolerance_corners
from cnc_planner.kinematics import Kinematics
from cnc_planner.kinds.turn.judge import max_gouge
from cnc_planner.planning import plan_job
from cnc_servo_bridge.drive import DriveModel

import drawn_plants

LATHE = load_machine("lathe")
PERIOD = 1e-3
JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
NAMES = ["turn_stepped", "turn_arc", "turn_cone"]


@functools.cache
def planned(name: str):
    """(job, t, setpoints) of the example job planned on the described lathe."""
    job = parse_job(load_job_file(JOBS / f"{name}.yaml"))
    plan = plan_job(job, LATHE)
    t = np.arange(0.0, plan.duration + PERIOD / 2, PERIOD)
    return job, t, plan.sample(t)


def gouges(name: str, drives: dict) -> tuple[float, float]:
    """How far the tip went on the plant's feedback into the final part and into the part
    plus its finishing allowances (m), judged as the turn report judges it."""
    job, _, command = planned(name)
    fb = DriveModel(LATHE, PERIOD, drives={**LATHE.drives, **drives}).simulate(*command)[0]
    radius, z = Kinematics(LATHE, job.setup, job.tool).tip_radius_z(
        fb[:, LATHE.joint_names.index("x")], fb[:, LATHE.joint_names.index("z")])
    tips, profile = np.stack([z, radius], axis=1), [tuple(p) for p in job.turn.profile]
    return (max_gouge(tips, profile, 0.0),
            max_gouge(tips, profile, job.turn.finish_allowance, job.turn.finish_allowance_z))


@settings(max_examples=30, deadline=None)
@given(plant=drawn_plants.plants_within(LATHE, ("x", "z"), PERIOD), name=st.sampled_from(NAMES))
def test_no_plant_inside_the_tolerance_turns_into_the_part(plant, name):
    part, allowance = gouges(name, plant)
    assert part == 0.0
    job, _, _ = planned(name)
    assert allowance <= job.turn.finish_allowance  # the lag stays within the allowance it eats into


@pytest.mark.parametrize("name", NAMES)
def test_no_corner_of_the_tolerance_turns_into_the_part(name):
    for x, z in zip(tolerance_corners(LATHE.drives["x"]), tolerance_corners(LATHE.drives["z"])):
        assert gouges(name, {"x": x, "z": z})[0] == 0.0, x
