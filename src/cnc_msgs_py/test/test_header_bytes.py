"""The stamp of a serialized message read and written in place agrees with rclpy's own
serialization, for the messages it is used on: joint_states, chunks and /clock."""
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from cnc_msgs_py.header_bytes import read_stamp, write_stamp

NS = 1_000_000_000
STAMPS = (0, 1, NS - 1, NS, 1_234_567_890_123, (2**31 - 1) * NS + NS - 1)


@pytest.mark.parametrize("stamp_ns", STAMPS)
def test_read_stamp_of_a_header_and_of_the_clock(stamp_ns: int) -> None:
    time = Time(sec=stamp_ns // NS, nanosec=stamp_ns % NS)
    state = JointState(name=["x", "z"], position=[0.1, 0.2])
    state.header.stamp = time
    chunk = JointTrajectory(joint_names=["x"])
    chunk.header.stamp = time
    for msg in (state, chunk, Clock(clock=time)):
        assert read_stamp(serialize_message(msg)) == stamp_ns


@pytest.mark.parametrize("stamp_ns", STAMPS)
def test_write_stamp_reads_back_through_rclpy(stamp_ns: int) -> None:
    state = JointState(name=["x"], position=[0.5], velocity=[0.0])
    data = bytearray(serialize_message(state))
    write_stamp(data, stamp_ns)
    back = deserialize_message(bytes(data), JointState)
    assert back.header.stamp.sec * NS + back.header.stamp.nanosec == stamp_ns
    assert back.name == ["x"] and back.position.tolist() == [0.5]
