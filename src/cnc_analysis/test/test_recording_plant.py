"""What a recording says about its drives: the plant the bridge named in its diagnostics, and
the setpoints' accelerations (the drive model's feed-forward input), read back from a bag
written by hand."""
from __future__ import annotations

import numpy as np

from cnc_analysis.recording import RECORDED, TYPESTORE, BagWriter, read_run
from cnc_msgs_py.topics import PLANT_KEY

T = TYPESTORE.types
JOINTS = ["x", "z"]


def _stamp(ns: int):
    return T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _diagnostics(ns: int, plant: str) -> bytes:
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0, name="cnc_servo_bridge: drives", message="ok", hardware_id="/cnc",
        values=[T["diagnostic_msgs/msg/KeyValue"](key="buffer_s", value="0.000"),
                T["diagnostic_msgs/msg/KeyValue"](key=PLANT_KEY, value=plant)])
    msg = T["diagnostic_msgs/msg/DiagnosticArray"](header=T["std_msgs/msg/Header"](stamp=_stamp(ns), frame_id=""),
                                                   status=[status])
    return TYPESTORE.serialize_cdr(msg, "diagnostic_msgs/msg/DiagnosticArray")


def _chunk(ns: int, rows: np.ndarray) -> bytes:
    """Setpoints every ms from ns: rows of (position, velocity, acceleration) per joint."""
    points = [T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=row[0], velocities=row[1], accelerations=row[2], effort=np.zeros(0),
        time_from_start=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=i * 10**6)) for i, row in enumerate(rows)]
    msg = T["trajectory_msgs/msg/JointTrajectory"](header=T["std_msgs/msg/Header"](stamp=_stamp(ns), frame_id=""),
                                                  joint_names=JOINTS, points=points)
    return TYPESTORE.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory")


def _bag(path, diagnostics: list[str]) -> np.ndarray:
    """A bag with two overlapping chunks of setpoints and the given plant names; the
    setpoints' rows as the bridge executes them (the second chunk replaces from its stamp)."""
    topics = {"/cnc/joint_trajectory": RECORDED["joint_trajectory"], "/diagnostics": RECORDED["/diagnostics"]}
    writer = BagWriter(path, topics)
    first = np.arange(5 * 3 * 2, dtype=float).reshape(5, 3, 2)  # 5 points at 0..4 ms
    second = -np.arange(4 * 3 * 2, dtype=float).reshape(4, 3, 2)  # 4 points from 3 ms
    writer.write("/cnc/joint_trajectory", 1, _chunk(10**9, first))
    writer.write("/cnc/joint_trajectory", 2, _chunk(10**9 + 3 * 10**6, second))
    for i, plant in enumerate(diagnostics):
        writer.write("/diagnostics", 3 + i, _diagnostics(10**9, plant))
    writer.close()
    return np.concatenate([first[:3], second])


def test_the_plant_named_in_the_diagnostics_and_the_accelerations_are_read(tmp_path):
    rows = _bag(tmp_path / "bag", ["description", "soft_gain"])
    run = read_run(tmp_path / "bag")
    assert run.plant == "soft_gain"  # the last one the bridge named
    assert np.allclose(run.command_t, 1.0 + np.arange(7) * 1e-3)
    assert np.array_equal(run.command, rows[:, 0]) and np.array_equal(run.command_velocity, rows[:, 1])
    assert np.array_equal(run.command_acceleration, rows[:, 2])


def test_a_recording_without_a_plant_says_none(tmp_path):
    _bag(tmp_path / "bag", [])
    assert read_run(tmp_path / "bag").plant is None
