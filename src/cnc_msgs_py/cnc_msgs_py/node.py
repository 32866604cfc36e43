"""Running a node process: one clean start and shutdown for the planner and the bridge.

A node's executable behaves like a command-line tool first: ``--help`` prints its usage,
the ROS arguments it takes and its parameters, ``--version`` its package's version, and
an argument that is neither ROS's nor ours is an error; none of these starts a node, and
they are answered before rclpy (and, with ``make`` named as "module:Class", the node's own
module) is imported: cnc-planner --help took 0.6-0.9 s with them.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
import traceback
from typing import TYPE_CHECKING, Callable

from .tool import node_parser, without_ros_args

if TYPE_CHECKING:
    from rclpy.node import Node

    from .parameters import Param

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
SPIN_S = 0.1  # wall time per call into the executor: the longest a requested stop waits

def run_node(make: Callable[[], Node] | str, name: str, args: list[str] | None = None, *, description: str = "",
             package: str = "", parameters: dict[str, Param] | None = None) -> int:
    """Create the node (``make``, or the class that "module:Class" names, imported once the
    arguments are read) and spin it until Ctrl-C or shutdown; a bad parameter (e.g. an
    unknown machine) is one line on stderr and exit code 2, not a traceback.

    ``--help``, ``--version`` or an unknown argument among ``args`` (sys.argv without the
    program, if None) is answered by argparse without starting the node or importing rclpy.
    """
    argv = sys.argv[1:] if args is None else list(args)
    prog = os.path.basename(sys.argv[0]) if args is None and sys.argv[0] not in ("", "-c") else name
    if prog == "__main__.py" or prog.endswith(".py"):
        prog = name
    node_parser(prog, description, package or name, parameters or {}).parse_args(without_ros_args(argv))
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from .heap import keep_freed_memory
    from .machine import MachineError

    if isinstance(make, str):
        module, _, attr = make.partition(":")
        make = getattr(importlib.import_module(module), attr)
    # SIGINT/SIGTERM ask for a stop instead of raising KeyboardInterrupt wherever the
    # interpreter happens to be: raised inside rclpy's take_message it came out as
    # "Unable to convert call argument '0' to Python object" and the stop was lost.
    rclpy.init(args=[prog, *argv], signal_handler_options=SignalHandlerOptions.NO)
    keep_freed_memory()  # plans and drive simulations reuse freed arrays instead of faulting in fresh ones
    try:
        node = make()
    except (MachineError, ValueError) as err:
        print(f"{name}: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: request_stop(stop)) for sig in STOP_SIGNALS}
    try:
        spin(node, stop)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def request_stop(stop: threading.Event) -> None:
    """The first Ctrl-C or SIGTERM ends the spin within SPIN_S; a second Ctrl-C, for a
    node that does not stop, interrupts it the usual way."""
    stop.set()
    signal.signal(signal.SIGINT, signal.default_int_handler)


def spin(node: Node, stop: threading.Event | None = None) -> None:
    """Spin until ``stop`` is set or the context shuts down, surviving whatever a callback
    or the executor raises.

    rclpy's EventsExecutor: it takes a message in C++ and calls its callback, where the
    SingleThreadedExecutor rebuilt a wait set in Python for every wake-up (simulation over
    topics: the three processes' CPU per machine second 0.20-0.32 -> 0.11-0.16). An
    earlier trial lost goals that reached a freshly started planner before it joined the
    executor (2 of 19); with rclpy 7.1.6 such a message is delivered once the node joins
    (test_node_survival), and 50 goals sent the moment a new planner matched all arrived.

    An error mid-run (a bug in a callback, or rclpy's own "Unable to convert call argument
    '0' to Python object" from take_message) is logged with its traceback and the node
    spins on: its timers keep the drives under control. The same error while the context
    shuts down (ros/joint_state_publisher#117) ends the spin quietly.
    """
    from rclpy.executors import ExternalShutdownException
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future

    stop = stop or threading.Event()
    executor = EventsExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok() and not stop.is_set():
            try:
                # SPIN_S at a time in C++ (a future never done), not a Python call per callback
                executor.spin_until_future_complete(Future(), timeout_sec=SPIN_S)
            except (KeyboardInterrupt, ExternalShutdownException):
                return
            except Exception:  # noqa: BLE001 - survive anything, see above
                if not node.context.ok():
                    return
                node.get_logger().error(f"kept running after an error in a callback:\n{traceback.format_exc()}")
    finally:
        executor.shutdown(timeout_sec=0)
