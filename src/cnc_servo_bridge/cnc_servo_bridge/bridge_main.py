"""The bridge node's entry point (console scripts ``bridge`` and ``cnc-bridge``) and its
parameters: light, so that --help and --version answer from this table alone; rclpy and the
node (cnc_servo_bridge.bridge_node) are imported once the arguments call for a node.
"""
from __future__ import annotations

from collections.abc import Callable

from cnc_msgs_py.node import run_node
from cnc_msgs_py.parameters import Param, Unset

NODE = "cnc_servo_bridge.bridge_node:BridgeNode"

PARAMETERS = {
    "autostart": Param(True, "configure and activate at start-up, as a lifecycle manager would; "
                             "false: stay unconfigured until change_state", read_only=True),
    "machine": Param("mill3", "machine description config/machines/<name>.yaml (or a path), "
                              "the one the planner reads", at_configure=True),
    "plant": Param("", "plant file (YAML): drives that differ from the description, emulated while "
                       "the planner keeps planning for the description (empty: the description itself)",
                   at_configure=True),
    "servo_period": Param(0.001, "drive-model step", "s", (1e-4, 0.01), at_configure=True),
    "simulation": Param(True, "publish /clock and run faster than real time; false: step on "
                              "the wall clock", at_configure=True),
    "joint_state_rate": Param(1000.0, "joint_states rate (of sim time in simulation), at most "
                                      "one per servo step", "Hz", (1.0, 10000.0), at_configure=True),
    "clock_rate": Param(100.0, "/clock rate in simulation", "Hz", (1.0, 10000.0), at_configure=True),
    "steps_per_callback": Param(100, "servo steps per timer callback in simulation, taken in blocks: "
                                     "bounded, so that setpoint chunks (a stop) are taken between them",
                                "steps", (1, 1000), at_configure=True),
    "start_position": Param(Unset("DOUBLE_ARRAY"), "where the axes stand at configure, one value "
                                                         "per joint in the machine's order (unset: its home)",
                            "m or rad", at_configure=True),
    "wake_period": Param(0.02, "real time: wall time between the servo loop's wake-ups; each takes the "
                               "steps the wall clock has passed and publishes every sample, stamped at its "
                               "own step (a Python wake-up per 1 ms step cost 0.45 of a CPU)", "s",
                         (1e-4, 0.05), at_configure=True),
    "underrun_timeout": Param(1.0, "wall time to wait for setpoints while the axes move before the "
                                   "buffer-ran-dry alarm (simulation)", "s", (0.01, 60.0)),
}


def main(args: list[str] | None = None, make: Callable | str = NODE) -> int:
    return run_node(make, "cnc_servo_bridge", args, package="cnc_servo_bridge", parameters=PARAMETERS,
                    description="The servo bridge node (lifecycle): setpoints in (joint_trajectory), a drive model "
                                "per axis, joint_states, /diagnostics and, in simulation, /clock out.")
