"""The planner node's entry point (console scripts ``planner`` and ``cnc-planner``) and its
parameters: light, so that --help and --version answer from this table alone; rclpy and the
planner (cnc_planner.planner_node) are imported once the arguments call for a node.
"""
from __future__ import annotations

from collections.abc import Callable

from cnc_msgs_py.node import run_node
from cnc_msgs_py.parameters import Param
from cnc_msgs_py.units import NS

from cnc_planner.settings import Settings

NODE = "cnc_planner.planner_node:PlannerNode"

PARAMETERS = {
    "machine": Param("mill3", "machine description config/machines/<name>.yaml (or a path), the one "
                              "the bridge drives", read_only=True),
    # the defaults are the executive's Settings: written once
    "interpolation_period": Param(Settings.period_ns / NS, "time between setpoints (the bridge's servo_period)",
                                  "s", (1e-4, 0.01), read_only=True),
    "chunk_points": Param(Settings.chunk_points, "setpoints per joint_trajectory chunk", "points", (1, 10000),
                          read_only=True),
    "lookahead": Param(Settings.lookahead_ns / NS, "setpoints kept ahead of the feedback, and the longest a "
                                                   "cancel waits", "s", (0.05, 5.0)),
    "planning_lookahead": Param(Settings.planning_lookahead_ns / NS, "setpoints kept ahead of the feedback while "
                                "a goal is planned beside the running job (planning slows the stream's thread), "
                                "and the longest a cancel then waits", "s", (0.05, 5.0)),
    "feedback_period": Param(0.02, "wall time between reads of the latest joint_states (progress, the stream's "
                                   "top-up, the end of the job, the feedback watchdog); the bridge publishes "
                                   "them at 1 kHz, and each is only kept until the next arrives", "s",
                             (0.001, 0.1),
                             read_only=True),
    "feedback_timeout": Param(2.0, "wall time without joint_states before a running job aborts", "s",
                              (0.1, 60.0)),
}


def main(args: list[str] | None = None, make: Callable | str = NODE) -> int:
    return run_node(make, "cnc_planner", args, package="cnc_planner", parameters=PARAMETERS,
                    description="The CNC planner node: job goals in (job_goal), jerk-limited joint setpoints out "
                                "(joint_trajectory), statuses and phase marks back (job_status, job_events).")
