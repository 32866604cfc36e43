"""The planner reads joint_states and /clock when it needs them (poll), never one message
at a time: in simulation both come many thousand times a second, and a Python callback
for each was CPU the simulation's speed paid for. What it reads must still be the newest,
under the machine's own names (a cell remaps /clock per machine). And what it makes once
(the chunks' serialized form) it makes at start, not in the first job's way."""
from __future__ import annotations

import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from cnc_msgs_py import qos, topics
from cnc_msgs_py.units import NS
from cnc_planner.planner_node import PlannerNode
from cnc_servo_bridge.bridge_node import stamp


@pytest.mark.parametrize("clock_topic", ["/clock", "/cell/m1/clock"])
def test_the_planner_takes_the_newest_feedback_and_clock_without_a_callback_each(clock_topic):
    remap = [] if clock_topic == "/clock" else ["-r", f"/clock:={clock_topic}"]
    rclpy.init(args=["--ros-args", "-r", "__ns:=/cnc", "-p", "use_sim_time:=true", *remap])
    planner = PlannerNode()
    machine = rclpy.create_node("machine", namespace="/cnc")
    executor = SingleThreadedExecutor()
    executor.add_node(planner)
    executor.add_node(machine)
    try:
        assert not [s for s in planner.subscriptions if s.topic_name in ("/cnc/joint_states", clock_topic)]
        states = machine.create_publisher(JointState, topics.JOINT_STATES, qos.JOINT_STATES)
        clock = machine.create_publisher(Clock, clock_topic, qos.CLOCK)
        deadline = time.monotonic() + 20
        while states.get_subscription_count() == 0 or clock.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "the planner's readers never matched"
            executor.spin_once(timeout_sec=0.02)
        for k in range(1, 501):  # half a second of machine time at 1 kHz
            t_ns = 7 * NS + k * 1_000_000
            msg = JointState(name=list(planner.joints), position=[0.001 * k] * 4, velocity=[0.0] * 4)
            msg.header.stamp = stamp(t_ns)
            states.publish(msg)
            clock.publish(Clock(clock=stamp(t_ns)))
        last_ns = 7 * NS + 500 * 1_000_000
        deadline = time.monotonic() + 20
        while planner.latest_feedback_ns != last_ns or planner.clock_ns() != last_ns:
            assert time.monotonic() < deadline, (planner.latest_feedback_ns, planner.clock_ns())
            executor.spin_once(timeout_sec=0.02)
            planner.poll()
        assert planner.executive.position["x"] == pytest.approx(0.5)  # the newest sample's position
    finally:
        executor.shutdown()
        planner.destroy_node()
        machine.destroy_node()
        rclpy.try_shutdown()


def test_the_planners_first_chunk_finds_its_serialized_form_made_at_start():
    """The chunks' serialized form (rosbags' types and generated code, 0.1 s) is made when
    the planner starts: the first job's first chunk does not wait for it."""
    import numpy as np

    from cnc_msgs_py import trajectory_bytes

    trajectory_bytes.layout.cache_clear()
    rclpy.init(args=["--ros-args", "-r", "__ns:=/cnc"])
    planner = PlannerNode()
    try:
        made = trajectory_bytes.layout.cache_info().misses
        points = planner.executive.settings.chunk_points
        trajectory_bytes.encode(tuple(planner.joints), 0, 1_000_000, *np.zeros((3, points, len(planner.joints))))
        assert made >= 1 and trajectory_bytes.layout.cache_info().misses == made
    finally:
        planner.destroy_node()
        rclpy.try_shutdown()
