"""joint_trajectory chunks as bytes: what the planner writes reads back as the message it
stands for (rclpy, and the bag reader rosbags), and the bridge's reader returns the same
setpoints for these bytes as for any JointTrajectory, which it deserializes as usual."""
import subprocess
import sys

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_msgs_py import trajectory_bytes

NS = 1_000_000_000
JOINT_SETS = (("x", "z", "spindle"), ("x", "y", "z", "spindle"), ("a_long_joint_name", "b"), ("x", "y", "z", "a", "c"))


def chunk(count: int, joints: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return tuple(rng.normal(size=(count, joints)) * scale for scale in (0.3, 0.05, 2.0))


@pytest.mark.parametrize("joints", JOINT_SETS)
@pytest.mark.parametrize("count", (1, 2, 37, 100))
def test_bytes_read_back_as_the_chunk(joints, count) -> None:
    p, v, a = chunk(count, len(joints), count)
    stamp_ns, period_ns = 1_234_567_890_123, 1_000_000
    data = trajectory_bytes.encode(joints, stamp_ns, period_ns, p, v, a)
    msg = deserialize_message(data, JointTrajectory)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(stamp_ns, NS) and msg.header.frame_id == ""
    assert msg.joint_names == list(joints) and len(msg.points) == count
    for i, point in enumerate(msg.points):
        assert list(point.positions) == p[i].tolist() and list(point.velocities) == v[i].tolist()
        assert list(point.accelerations) == a[i].tolist() and len(point.effort) == 0
        assert (point.time_from_start.sec, point.time_from_start.nanosec) == divmod(i * period_ns, NS)
    bag_msg = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(data, "trajectory_msgs/msg/JointTrajectory")
    assert bag_msg.points[-1].positions.tolist() == p[-1].tolist()
    # The bridge's reader: in place, and through rclpy for the same message published as such.
    for read in (trajectory_bytes.decode(data, joints), trajectory_bytes.decode(serialize_message(msg), joints)):
        assert read.joints == list(joints)
        assert read.times_ns.tolist() == [stamp_ns + i * period_ns for i in range(count)]
        assert np.array_equal(read.positions, p) and np.array_equal(read.velocities, v)
        assert np.array_equal(read.accelerations, a)


def test_any_other_trajectory_is_read_through_rclpy() -> None:
    """Joints in another order, a frame_id, efforts, uneven times: not the planner's layout."""
    joints = ("x", "y", "z", "spindle")
    msg = JointTrajectory(joint_names=["z", "x", "y", "spindle"])
    msg.header.frame_id = "base"
    msg.header.stamp.sec, msg.header.stamp.nanosec = 5, 7
    msg.points = [JointTrajectoryPoint(positions=[0.1 * i, 1.0, 2.0, 3.0], velocities=[0.0] * 4,
                                       accelerations=[0.0] * 4, effort=[1.0] * 4,
                                       time_from_start=Duration(sec=0, nanosec=3_000_000 * i)) for i in range(3)]
    read = trajectory_bytes.decode(serialize_message(msg), joints)
    assert read.joints == ["z", "x", "y", "spindle"]
    assert read.times_ns.tolist() == [5 * NS + 7 + 3_000_000 * i for i in range(3)]
    assert read.positions[:, 0].tolist() == [0.0, 0.1, 0.2]


def test_ragged_points_are_refused() -> None:
    msg = JointTrajectory(joint_names=["x", "z"])
    msg.points = [JointTrajectoryPoint(positions=[0.0, 1.0]), JointTrajectoryPoint(positions=[0.0])]
    with pytest.raises(ValueError):
        trajectory_bytes.decode(serialize_message(msg), ("x", "z"))


def test_the_planners_chunks_are_read_in_place(monkeypatch) -> None:
    """The point of the bytes: no rclpy message is made for them on either side."""
    def refuse(*_):
        raise AssertionError("deserialized through rclpy")

    monkeypatch.setattr(trajectory_bytes, "deserialize_message", refuse)
    for joints in JOINT_SETS:
        for count in (1, 2, 100):
            p, v, a = chunk(count, len(joints), 7)
            read = trajectory_bytes.decode(trajectory_bytes.encode(joints, 10, 1000, p, v, a), joints)
            assert np.array_equal(read.accelerations, a) and read.times_ns[-1] == 10 + (count - 1) * 1000


def test_chunks_written_in_another_process_are_read_in_place(monkeypatch) -> None:
    """The planner and the bridge are two processes: the template each builds must be the
    same bytes (rclpy's alignment padding held whatever its buffer did before, so the
    bridge read most chunks through rclpy)."""
    counts = (2, 3, 50, 100, 101)
    writer = ("import sys, numpy as np; from cnc_msgs_py import trajectory_bytes as tb\n"
              "junk = [bytearray(b'\\xff' * 4096 * k) for k in range(1, 64)]\n"  # a heap unlike this one's
              f"for n in {counts}:\n"
              "    p = np.arange(n * 4, dtype=float).reshape(n, 4)\n"
              "    print(tb.encode(('x', 'y', 'z', 'spindle'), 10, 1000, p, -p, 2 * p).hex())")
    out = subprocess.run([sys.executable, "-c", writer], capture_output=True, text=True, check=True).stdout.split()

    def refuse(*_):
        raise AssertionError("deserialized through rclpy")

    monkeypatch.setattr(trajectory_bytes, "deserialize_message", refuse)
    for n, text in zip(counts, out, strict=True):
        read = trajectory_bytes.decode(bytes.fromhex(text), ("x", "y", "z", "spindle"))
        assert read.positions.ravel().tolist() == list(range(n * 4)) and read.times_ns[-1] == 10 + (n - 1) * 1000


def test_an_empty_trajectory_is_read_through_rclpy() -> None:
    read = trajectory_bytes.decode(serialize_message(JointTrajectory(joint_names=["x"])), ("x",))
    assert read.joints == ["x"] and len(read.times_ns) == 0
