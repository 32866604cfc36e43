"""Machine descriptions: the shipped machines, and malformed ones naming the field."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from cnc_msgs_py.machine import JOINT_ORDER, SPINDLE, Axis, Drive, MachineError, load_machine, machine_dirs, parse_machine

CONFIG = Path(__file__).resolve().parents[3] / "config" / "machines"

GOOD = {
    "name": "tiny",
    "layout": "lathe",
    "axes": {
        # Deliberately out of joint order: the machine orders them x, z, spindle.
        "spindle": {"type": "continuous", "max_velocity": 100.0, "max_acceleration": 50.0, "max_jerk": 1000.0},
        "z": {"type": "linear", "min": -0.2, "max": 0.1, "max_velocity": 0.4, "max_acceleration": 5.0, "max_jerk": 100.0},
        "x": {"type": "linear", "min": 0.0, "max": 0.1, "max_velocity": 0.3, "max_acceleration": 4.0, "max_jerk": 90.0},
    },
    "drive": {
        j: {"kp": 40.0, "velocity_ff": 1.0, "accel_ff": 0.0, "velocity_lag": 0.001, "resolution": 1e-7,
            "following_error_limit": 0.001}
        for j in ("x", "z", "spindle")
    },
}


def good() -> dict:
    return copy.deepcopy(GOOD)


def refused(document, *words: str) -> str:
    with pytest.raises(MachineError) as info:
        parse_machine(document, source="tiny")
    message = str(info.value)
    for word in words:
        assert word in message, message
    return message


# --- shipped machines ---------------------------------------------------------------------

def test_mill3_joint_order_and_values():
    m = load_machine("mill3")
    assert m.name == "mill3" and m.layout == "mill3"
    assert m.joint_names == ("x", "y", "z", "spindle")
    assert m.linear_axes == ("x", "y", "z")
    assert m.axes["x"] == Axis("x", "linear", -0.5, 0.5, 0.8, 9.8, 200.0)
    assert m.axes["y"] == Axis("y", "linear", -0.3, 0.3, 0.8, 9.8, 200.0)
    assert m.axes["z"] == Axis("z", "linear", -0.3, 0.1, 0.6, 9.8, 200.0)
    assert m.axes[SPINDLE] == Axis("spindle", "continuous", None, None, 1047.0, 500.0, 1.0e5)
    assert m.drives["x"] == Drive(kp=50.0, velocity_ff=1.0, accel_ff=0.0, velocity_lag=0.001,
                                  resolution=1e-7, following_error_limit=0.005)
    assert m.drives[SPINDLE] == Drive(kp=50.0, velocity_ff=1.0, accel_ff=0.0, velocity_lag=0.002,
                                      resolution=1e-5, following_error_limit=6.5)
    assert tuple(m.drives) == m.joint_names


def test_lathe_joint_order_and_values():
    m = load_machine("lathe")
    assert m.name == "lathe" and m.layout == "lathe"
    assert m.joint_names == ("x", "z", "spindle")
    assert m.linear_axes == ("x", "z")
    assert m.axes["x"] == Axis("x", "linear", -0.01, 0.15, 0.5, 9.8, 500.0)
    assert m.axes["z"] == Axis("z", "linear", -0.3, 0.05, 0.5, 9.8, 500.0)
    assert m.axes[SPINDLE] == Axis("spindle", "continuous", None, None, 628.0, 300.0, 1.0e5)
    assert m.drives["z"].kp == 80.0 and m.drives["z"].following_error_limit == 0.0026
    assert m.drives[SPINDLE].velocity_lag == 0.002


def test_load_by_path_equals_load_by_name():
    assert load_machine(str(CONFIG / "mill3.yaml")) == load_machine("mill3")


def test_shipped_config_directory_is_found():
    assert any(d.resolve() == CONFIG.resolve() for d in machine_dirs())


def test_cnc_machine_path_comes_first(tmp_path, monkeypatch):
    doc = good()
    doc["name"] = "mill3"
    (tmp_path / "mill3.yaml").write_text(yaml.safe_dump(doc))
    monkeypatch.setenv("CNC_MACHINE_PATH", str(tmp_path))
    assert machine_dirs()[0] == tmp_path
    assert load_machine("mill3").joint_names == ("x", "z", "spindle")


def test_axis_helpers():
    m = load_machine("mill3")
    assert m.axis("z").max == 0.1
    assert m.axes["z"].within_travel(0.1) and not m.axes["z"].within_travel(0.1001)
    assert m.axes["z"].within_travel(0.1001, tolerance=0.001)
    assert m.axes[SPINDLE].within_travel(1e9)
    with pytest.raises(MachineError, match="no axis 'a'"):
        m.axis("a")


def test_parse_orders_joints_and_keeps_values():
    m = parse_machine(good(), source="tiny")
    assert m.joint_names == ("x", "z", "spindle")
    assert m.axes["x"].min == 0.0 and m.axes["x"].max_jerk == 90.0
    assert all(isinstance(v, float) for v in (m.axes["x"].min, m.axes["x"].max))
    assert m.name == "tiny"


def test_name_defaults_to_source():
    doc = good()
    del doc["name"]
    assert parse_machine(doc, source="from_file").name == "from_file"


# --- malformed descriptions ------------------------------------------------------------

def test_missing_drive_for_an_axis():
    doc = good()
    del doc["drive"]["z"]
    refused(doc, "drive.z", "drive model")


def test_missing_drive_section():
    doc = good()
    del doc["drive"]
    refused(doc, "drive", "mapping")


@pytest.mark.parametrize("lo, hi", [(0.1, 0.1), (0.2, 0.1)])
def test_min_not_below_max(lo, hi):
    doc = good()
    doc["axes"]["x"].update(min=lo, max=hi)
    refused(doc, "axes.x", "min", "below max")


def test_unknown_joint_name():
    doc = good()
    doc["axes"]["w"] = copy.deepcopy(doc["axes"]["x"])
    refused(doc, "axes.w", "joint names")


@pytest.mark.parametrize("key", ["min", "max", "max_velocity", "max_acceleration", "max_jerk"])
@pytest.mark.parametrize("value", ["fast", None, True, float("nan"), float("inf")])
def test_non_numeric_axis_limit(key, value):
    doc = good()
    doc["axes"]["z"][key] = value
    refused(doc, f"axes.z.{key}", "finite number")


@pytest.mark.parametrize("key", ["max_velocity", "max_acceleration", "max_jerk"])
def test_non_positive_axis_limit(key):
    doc = good()
    doc["axes"]["x"][key] = 0.0
    refused(doc, f"axes.x.{key}", "> 0")


@pytest.mark.parametrize("key", ["kp", "velocity_ff", "accel_ff", "velocity_lag", "resolution",
                                 "following_error_limit"])
def test_non_numeric_drive_value(key):
    doc = good()
    doc["drive"]["spindle"][key] = "1.0"
    refused(doc, f"drive.spindle.{key}", "finite number")


def test_missing_drive_value():
    doc = good()
    del doc["drive"]["x"]["following_error_limit"]
    refused(doc, "drive.x.following_error_limit")


def test_feed_forward_may_be_zero_but_gains_must_be_positive():
    doc = good()
    doc["drive"]["x"]["velocity_ff"] = 0.0
    assert parse_machine(doc).drives["x"].velocity_ff == 0.0
    doc["drive"]["x"]["kp"] = 0.0
    refused(doc, "drive.x.kp", "> 0")


@pytest.mark.parametrize("layout", ["mill4", None, 3])
def test_bad_layout(layout):
    doc = good()
    doc["layout"] = layout
    refused(doc, "layout", "mill3")


def test_bad_axis_type():
    doc = good()
    doc["axes"]["x"]["type"] = "prismatic"
    refused(doc, "axes.x.type", "linear")


def test_axis_spec_not_a_mapping():
    doc = good()
    doc["axes"]["x"] = [0, 1]
    refused(doc, "axes.x", "mapping")


def test_drive_spec_not_a_mapping():
    doc = good()
    doc["drive"]["x"] = 50.0
    refused(doc, "drive.x", "mapping")


@pytest.mark.parametrize("axes", [None, {}, [1, 2]])
def test_axes_missing_or_empty(axes):
    doc = good()
    doc["axes"] = axes
    refused(doc, "axes", "non-empty mapping")


def test_document_not_a_mapping():
    refused(["x"], "tiny", "mapping")


def test_missing_file_by_name():
    with pytest.raises(MachineError, match="no_such_machine.yaml"):
        load_machine("no_such_machine")


def test_missing_file_by_path(tmp_path):
    with pytest.raises(MachineError) as info:
        load_machine(str(tmp_path / "gone.yaml"))
    assert "gone.yaml" in str(info.value)


def test_invalid_yaml_file(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("axes: {x: [1, 2\n")
    with pytest.raises(MachineError, match="not valid YAML"):
        load_machine(str(path))


def test_malformed_file_names_the_file_and_field(tmp_path):
    doc = good()
    doc["axes"]["x"]["max_velocity"] = "high"
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(MachineError) as info:
        load_machine(str(path))
    assert str(info.value).startswith("broken: axes.x.max_velocity:")


def test_joint_order_constant():
    assert JOINT_ORDER[-1] == SPINDLE and JOINT_ORDER[:3] == ("x", "y", "z")
