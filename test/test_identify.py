"""Commissioning (issue 41): every layout has a calibration job that excites each linear axis
as a servo tuning routine does, and `cnc-identify` on a bag of it, run on a plant that is not
the description, writes a description that loads, holds the plant's drive and plans."""
from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_analysis.identify import Trace, identify
from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import LAYOUTS, load_machine
from cnc_planner.planning import plan_job
from cnc_servo_bridge.drive import DriveModel

from support import JOBS, ROOT, cnc

CREEP = 1e-3  # m/s: under this an axis creeps, where Coulomb friction shows
PERIOD = 1e-3


@lru_cache(maxsize=None)
def planned(layout: str) -> tuple:
    """A layout's calibration job planned offline and sampled every servo period from rest."""
    job = parse_job(load_job_file(JOBS / f"identify_{layout}.yaml"))
    machine = load_machine(job.machine)
    plan = plan_job(job, machine)
    return machine, plan.joints, plan.sample(np.arange(-0.05, plan.duration + 0.2, PERIOD).clip(0.0))


@pytest.mark.parametrize("layout", LAYOUTS)
def test_calibration_job_excites_every_linear_axis(layout):
    job = parse_job(load_job_file(JOBS / f"identify_{layout}.yaml"))
    machine = load_machine(job.machine)
    assert machine.layout == layout
    plan = plan_job(job, machine)
    t = np.arange(0.0, plan.duration, 1e-3)
    _, v, _ = plan.sample(t)
    for axis in machine.linear_axes:
        speed = v[:, plan.joints.index(axis)]
        top = machine.axes[axis].max_velocity
        assert speed.max() > 0.5 * top and speed.min() < -0.5 * top, axis  # rapids both ways
        creeping = (np.abs(speed) > 1e-5) & (np.abs(speed) < CREEP)
        assert np.sum(creeping & (speed > 0)) > 200 and np.sum(creeping & (speed < 0)) > 200, axis


@settings(max_examples=8, deadline=None)
@given(kp=st.floats(0.6, 1.4), lag=st.floats(1.0, 3.0), ff=st.floats(0.9, 1.0), delay=st.integers(0, 3),
       noise=st.floats(0.0, 2e-7), seed=st.integers(0, 100))
def test_drawn_lathe_plants_are_identified_from_the_planned_calibration_job(kp, lag, ff, delay, noise, seed):
    """Plants inside and somewhat beyond the default tolerance, on the lathe's calibration job
    as the planner samples it: kp and velocity_lag within 5 %, the delay exact."""
    machine, joints, reference = planned("lathe")
    plant = {j: dataclasses.replace(d, kp=d.kp * kp, velocity_lag=d.velocity_lag * lag, velocity_ff=ff,
                                    delay=delay * PERIOD, noise=noise)
             for j, d in machine.drives.items() if j in machine.linear_axes}
    feedback = DriveModel(machine, PERIOD, joints, drives={**machine.drives, **plant}, seed=seed).simulate(*reference)
    fits = identify([Trace.of(PERIOD, joints, reference, feedback)], machine)
    for joint, drive in plant.items():
        fitted = fits[joint].drive
        assert fitted is not None, fits[joint].note
        assert fitted.kp == pytest.approx(drive.kp, rel=0.05)
        assert fitted.velocity_lag == pytest.approx(drive.velocity_lag, rel=0.05)
        assert fitted.delay == pytest.approx(drive.delay, abs=1e-12)
        assert fitted.velocity_ff == pytest.approx(ff, abs=0.01)


def test_identify_recovers_the_slow_loop_and_plans_with_it(tmp_path, monkeypatch):
    plant = ROOT / "config" / "plants" / "mill3_slow_loop.yaml"
    run = cnc("cnc-run", JOBS / "identify_mill3.yaml", "--plant", plant, "--out", tmp_path / "cal", timeout=180)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    identified = cnc("cnc-identify", tmp_path / "cal" / "bag", "--out", tmp_path / "fit", timeout=120)
    assert identified.returncode == 0, identified.stderr
    written = tmp_path / "fit" / "mill3.yaml"
    header = [line for line in written.read_text().splitlines() if line.startswith("#")]
    assert any(str(tmp_path / "cal" / "bag") in line and "mill3_slow_loop" in line for line in header)
    assert any(line.startswith("#   z: 0.000 / 0.000 fitted") for line in header), header
    machine = load_machine(str(written))
    for axis in ("x", "y", "z"):
        drive = machine.drives[axis]
        assert drive.velocity_lag == pytest.approx(0.003, rel=0.05)
        assert drive.delay == pytest.approx(0.002, abs=1e-9)
        assert drive.kp == pytest.approx(50.0, rel=0.05)
        assert drive.tolerance.delay == (0.0, 0.0)
    assert machine.drives["spindle"] == load_machine("mill3").drives["spindle"]
    assert "velocity_lag ms" in identified.stdout and "residual max um" in identified.stdout
    monkeypatch.setenv("CNC_MACHINE_PATH", str(tmp_path / "fit"))
    assert load_machine("mill3").drives["z"].velocity_lag == pytest.approx(0.003, rel=0.05)
