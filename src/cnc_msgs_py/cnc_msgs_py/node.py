"""Running a node process: one clean start and shutdown for the planner and the bridge."""
from __future__ import annotations

import sys
import traceback
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .machine import MachineError


def run_node(make: Callable[[], Node], name: str, args: list[str] | None = None) -> int:
    """Create the node and spin it until Ctrl-C or shutdown; a bad parameter (e.g. an
    unknown machine) is one line on stderr and exit code 2, not a traceback."""
    # Ctrl-C (SIGINT) becomes KeyboardInterrupt in spin, so the node is destroyed cleanly.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = make()
    except (MachineError, ValueError) as err:
        print(f"{name}: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        spin(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def spin(node: Node) -> None:
    """Spin until Ctrl-C or shutdown, surviving whatever a callback or the executor raises.

    An error mid-run (a bug in a callback, or rclpy's own "Unable to convert call argument
    '0' to Python object" from take_message under load) is logged with its traceback and
    the node spins on: its timers keep the drives under control. The same error while the
    context shuts down (where rclpy raises it under load, ros/joint_state_publisher#117)
    ends the spin quietly.

    Not rclpy's EventsExecutor, although it takes messages several times cheaper (the
    recorder in runner.py uses it): in rclpy 7.1.5 a message that arrives between a
    subscription's creation and the executor's registration of the node is never
    delivered (measured: 2 of 19 goals sent to a freshly started planner were lost; 0 of
    15 when sent after its first heartbeat).
    """
    while True:
        try:
            rclpy.spin(node)
            return
        except (KeyboardInterrupt, ExternalShutdownException):
            return
        except Exception:  # noqa: BLE001 - survive anything, see above
            if not node.context.ok():
                return
            node.get_logger().error(f"kept running after an error in a callback:\n{traceback.format_exc()}")
