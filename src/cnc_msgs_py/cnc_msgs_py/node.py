"""Running a node process: one clean start and shutdown for the planner and the bridge."""
from __future__ import annotations

import sys
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
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
