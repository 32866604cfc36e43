"""A node spun by cnc_msgs_py.node survives what its callbacks or the executor raise."""
from __future__ import annotations

import os
import signal
import threading

import pytest
import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import String

from cnc_msgs_py import qos
from cnc_msgs_py.node import run_node, spin

RCLPY_ERROR = "Unable to convert call argument '0' to Python object"  # as take_message raised it


@pytest.fixture
def node():
    rclpy.init()
    node = Node("survivor")
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def test_an_error_mid_run_is_logged_and_the_node_spins_on(node):
    ticks = []

    def tick() -> None:
        ticks.append(len(ticks))
        if len(ticks) in (2, 3):
            raise RuntimeError(RCLPY_ERROR)
        if len(ticks) == 6:
            rclpy.shutdown()

    node.create_timer(0.001, tick)
    spin(node)
    assert len(ticks) == 6  # two errors, then three more callbacks until the shutdown


def test_an_error_while_shutting_down_ends_the_spin_quietly(node):
    ticks = []

    def tick() -> None:
        ticks.append(len(ticks))
        rclpy.shutdown()
        raise RuntimeError(RCLPY_ERROR)

    node.create_timer(0.001, tick)
    spin(node)  # returns, does not raise
    assert len(ticks) == 1


def test_ctrl_c_asks_for_a_stop_and_never_interrupts_a_callback():
    """SIGINT raised as KeyboardInterrupt inside rclpy's take_message came out as the
    RuntimeError above and the stop was lost; now it only ends the spin."""
    finished = []

    def make() -> Node:
        node = Node("stoppable")

        def tick() -> None:
            os.kill(os.getpid(), signal.SIGINT)
            finished.append(sum(range(1000)))  # the callback runs to its end

        node.create_timer(0.001, tick)
        return node

    before = signal.getsignal(signal.SIGINT)
    assert run_node(make, "stoppable", [], package="cnc_msgs_py") == 0
    assert finished and finished[0] == 499500
    assert signal.getsignal(signal.SIGINT) is before  # the caller's handler is back


def test_a_message_that_arrived_before_the_spin_is_delivered(node):
    """A goal can reach a freshly started planner before its node joins the executor; an
    earlier trial of the EventsExecutor lost such goals (2 of 19 starts)."""
    sender = Node("early_sender")
    got = []

    def keep(msg: String) -> None:
        got.append(msg.data)
        rclpy.shutdown()

    node.create_subscription(String, "early", keep, qos.JOB_GOAL)
    publisher = sender.create_publisher(String, "early", qos.JOB_GOAL)
    while publisher.get_subscription_count() == 0:
        rclpy.spin_once(sender, timeout_sec=0.01)
    publisher.publish(String(data="goal"))
    assert publisher.wait_for_all_acked(Duration(seconds=10))  # in the node's queue, no executor yet
    timer = threading.Timer(10.0, rclpy.shutdown)  # the spin's end, if it never comes
    timer.start()
    spin(node)
    timer.cancel()
    sender.destroy_node()
    assert got == ["goal"]
