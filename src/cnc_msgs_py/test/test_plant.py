"""Plant files and drive tolerances: parsed whole, errors naming the field, and the corners
the planner checks its timing against."""
from __future__ import annotations

import dataclasses

import pytest

from cnc_msgs_py.machine import EXACT, MachineError, Tolerance, exactly_as_described, load_machine, parse_machine
from cnc_msgs_py.plant import DESCRIPTION, load_plant, outside_tolerance, parse_plant, tolerance_corners

from support import ROOT

MILL = load_machine("mill3")


def test_a_plant_overrides_only_what_it_names():
    plant = parse_plant({"name": "p", "seed": 3, "drive": {"z": {"kp": 35.0, "delay": 0.002, "noise": 1e-7}}}, MILL)
    assert plant.seed == 3
    assert plant.drives["z"] == dataclasses.replace(MILL.drives["z"], kp=35.0, delay=0.002, noise=1e-7)
    assert plant.drives["x"] == MILL.drives["x"]


def test_an_empty_path_is_the_description():
    plant = load_plant("", MILL)
    assert plant.name == DESCRIPTION and plant.drives == MILL.drives


def test_the_shipped_plants_load():
    for path in sorted((ROOT / "config" / "plants").glob("*.yaml")):
        machine = load_machine(path.stem.split("_")[0])
        assert load_plant(str(path), machine).drives.keys() == machine.drives.keys()


@pytest.mark.parametrize("doc, message", [
    ({"drive": {"w": {"kp": 1.0}}}, "p: drive.w: not an axis of machine 'mill3'"),
    ({"drive": {"x": {"gain": 1.0}}}, "p: drive.x.gain: unknown key"),
    ({"drive": {"x": {"kp": -1.0}}}, "p: drive.x.kp: must be > 0"),
    ({"drive": {"x": {"friction": -1.0}}}, "p: drive.x.friction: must be >= 0"),
    ({"drive": {"x": {"tolerance": {}}}}, "p: drive.x.tolerance: unknown key"),
    ({"seed": -1}, "p: seed: expected a whole number >= 0"),
    ({"drives": {}}, "p: drives: unknown key"),
])
def test_a_bad_plant_names_its_field(doc, message):
    with pytest.raises(MachineError, match=message.replace(".", r"\.")):
        parse_plant(doc, MILL, "p")


def machine_with_tolerance(spec: object) -> dict:
    doc = {"name": "m", "layout": "mill3",
           "axes": {"x": {"type": "linear", "min": -1, "max": 1, "max_velocity": 1, "max_acceleration": 1,
                          "max_jerk": 1}},
           "drive": {"x": {"kp": 50.0, "velocity_ff": 1.0, "accel_ff": 0.0, "velocity_lag": 0.001,
                           "resolution": 1e-7, "following_error_limit": 0.002, "tolerance": spec}}}
    return doc


def test_a_tolerance_keeps_the_defaults_it_does_not_name():
    machine = parse_machine(machine_with_tolerance({"kp": [0.9, 1.1], "backlash": 1e-6}))
    assert machine.drives["x"].tolerance == Tolerance(kp=(0.9, 1.1), backlash=1e-6)


@pytest.mark.parametrize("spec, message", [
    ({"kp": 0.9}, r"tolerance\.kp: expected \[low, high\]"),
    ({"kp": [1.1, 0.9]}, r"tolerance\.kp: expected low <= high"),
    ({"delay": [-0.001, 0.0]}, r"tolerance\.delay: expected 0 <= low <= high"),
    ({"gain": [1, 1]}, r"tolerance\.gain: unknown key"),
    ({"friction": -1.0}, r"tolerance\.friction: must be >= 0"),
])
def test_a_bad_tolerance_names_its_field(spec, message):
    with pytest.raises(MachineError, match=message):
        parse_machine(machine_with_tolerance(spec))


def test_outside_tolerance_says_which_key_and_by_how_much():
    inside = parse_plant({"drive": {"x": {"kp": 36.0, "velocity_lag": 0.003, "delay": 0.002}}}, MILL)
    assert outside_tolerance(MILL, inside) == []
    outside = parse_plant({"drive": {"x": {"kp": 30.0, "delay": 0.003}, "z": {"backlash": 1e-6}}}, MILL)
    assert outside_tolerance(MILL, outside) == ["x.kp: 30 outside 35..65", "x.delay: 0.003 s outside 0..0.002",
                                                "z.backlash: 1e-06 above 0"]


def test_corners_span_the_tolerance_and_close_with_it():
    corners = tolerance_corners(MILL.drives["x"])
    assert len(corners) == 16  # gain, velocity loop, feed-forward, delay at either end
    assert {c.kp for c in corners} == {35.0, 65.0} and {c.delay for c in corners} == {0.0, 0.002}
    exact = exactly_as_described(MILL).drives["x"]
    assert exact.tolerance == EXACT and tolerance_corners(exact) == [exact]
