"""joint_states and /clock published as bytes read back as the messages they stand for, by
rclpy and by the bag reader (rosbags), at every joint count of the shipped machines."""
import subprocess
import sys

import numpy as np
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cnc_servo_bridge.feedback_msg import ClockBytes, FeedbackBytes


def test_bytes_read_back_as_the_sample() -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    for joints in (["x", "z", "spindle"], ["x", "y", "z", "spindle"], ["a_long_joint_name", "b"]):
        feedback = FeedbackBytes(joints)
        for stamp_ns in (0, 1_234_567_890_123):
            positions, velocities = np.linspace(-1.0, 2.0, len(joints)), np.arange(len(joints)) * 0.25
            data = feedback.fill(stamp_ns, positions, velocities)
            msg = deserialize_message(data, JointState)
            assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(stamp_ns, 1_000_000_000)
            assert msg.name == joints and list(msg.position) == positions.tolist()
            assert list(msg.velocity) == velocities.tolist() and len(msg.effort) == 0
            bag_msg = store.deserialize_cdr(data, "sensor_msgs/msg/JointState")
            assert bag_msg.position.tolist() == positions.tolist() and bag_msg.name == joints


def test_a_sample_is_the_same_bytes_in_every_process() -> None:
    """The template's padding is zeroed: a sample does not carry whatever rclpy's buffer
    held, so its bytes do not depend on the process that wrote them."""
    writer = ("from cnc_servo_bridge.feedback_msg import FeedbackBytes\n"
              "junk = [bytearray(b'\\xff' * 4096 * k) for k in range(1, 64)]\n"  # a heap unlike this one's
              "print(FeedbackBytes(['x', 'y', 'z', 'spindle']).fill(7, [0.1, 0.2, 0.3, 0.4], [0.0] * 4).hex())")
    there = subprocess.run([sys.executable, "-c", writer], capture_output=True, text=True, check=True).stdout.strip()
    here = FeedbackBytes(["x", "y", "z", "spindle"]).fill(7, np.array([0.1, 0.2, 0.3, 0.4]), np.zeros(4))
    assert bytes.fromhex(there) == here


def test_clock_bytes_read_back_as_the_time() -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    clock = ClockBytes()
    for stamp_ns in (0, 999_999_999, 1_234_567_890_123):
        data = clock.fill(stamp_ns)
        msg = deserialize_message(data, Clock)
        assert (msg.clock.sec, msg.clock.nanosec) == divmod(stamp_ns, 1_000_000_000)
        bag_msg = store.deserialize_cdr(data, "rosgraph_msgs/msg/Clock")
        assert (bag_msg.clock.sec, bag_msg.clock.nanosec) == divmod(stamp_ns, 1_000_000_000)
