"""cnc-run: one job through both nodes over real topics, recorded, then analysed.

Starts the bridge (simulation mode, the clock source) and the planner (on sim time) as
separate processes under a namespace, records every CNC topic to an MCAP rosbag2 from
this process, submits the job on job_goal, follows job_status and stops everything once
the job is final. DDS stays on this host with a domain of its own.
"""
from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import rclpy
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from cnc_msgs_py import qos, topics
from cnc_msgs_py.status import FINAL_STATES
from cnc_servo_bridge.recording import RECORDED, BagWriter

QOS = {
    "job_goal": qos.JOB_GOAL, "job_cancel": qos.JOB_CANCEL, "job_status": qos.JOB_STATUS,
    "job_events": qos.JOB_EVENTS, "joint_trajectory": qos.JOINT_TRAJECTORY,
    "joint_states": qos.JOINT_STATES, "/diagnostics": qos.DIAGNOSTICS, "/clock": qos.CLOCK,
}
SETTLE_S = 0.2  # sim time recorded after the final status, so the drives' settling shows


class RunError(RuntimeError):
    """The run could not be carried out (nodes did not start, timeout)."""


def local_dds_env(domain_id: int | None = None) -> dict[str, str]:
    """Environment for ROS processes: discovery on localhost only, a domain of our own."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if domain_id is None:
        domain_id = int(env.get("ROS_DOMAIN_ID") or 0) or (os.getpid() % 100) + 1
    env["ROS_DOMAIN_ID"] = str(domain_id)
    return env


def node_command(module: str, namespace: str, params: dict[str, object]) -> list[str]:
    args = [sys.executable, "-m", module, "--ros-args", "-r", f"__ns:={namespace}"]
    for key, value in params.items():
        args += ["-p", f"{key}:={str(value).lower() if isinstance(value, bool) else value}"]
    return args


def message_class(msgtype: str) -> type:
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _stamp_ns(msg) -> int:
    return msg.clock.sec * 1_000_000_000 + msg.clock.nanosec


class Recorder(Node):
    """Records every CNC topic to the bag (raw CDR) and follows the job's status."""

    def __init__(self, bag: BagWriter, namespace: str) -> None:
        super().__init__("cnc_run_recorder", namespace=namespace)
        self.bag = bag
        self.statuses: list[dict] = []
        self.sim_ns = 0
        self.goal_pub = self.create_publisher(String, topics.JOB_GOAL, qos.JOB_GOAL)
        for topic, msgtype in RECORDED.items():
            name = topic if topic.startswith("/") else f"{namespace}/{topic}"
            self.create_subscription(message_class(msgtype), topic, self._writer(name, topic), QOS[topic], raw=True)

    def _writer(self, name: str, topic: str) -> Callable[[bytes], None]:
        def write(data: bytes) -> None:
            if topic == "/clock":
                self.sim_ns = _stamp_ns(deserialize_message(data, message_class(RECORDED["/clock"])))
            self.bag.write(name, self.sim_ns, data)
            if topic == "job_status":
                self.statuses.append(json.loads(deserialize_message(data, String).data))
        return write

    def ready(self) -> bool:
        """Planner listening for goals and bridge publishing the clock."""
        return self.goal_pub.get_subscription_count() >= 2 and self.sim_ns > 0


def run_job(text: str, job_id: str, machine: str, bag_dir: Path, *, namespace: str = "/cnc",
            timeout: float = 900.0, progress: Callable[[dict], None] | None = None,
            env: dict[str, str] | None = None) -> dict:
    """Run one job document (JSON text) through both nodes, recording to ``bag_dir``.

    Returns the job's final status document.

    Raises:
        RunError: the nodes did not come up, or the job did not end within ``timeout``.
    """
    env = env or local_dds_env()
    os.environ.update({k: env[k] for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID")})
    procs = [
        subprocess.Popen(node_command("cnc_servo_bridge.bridge_node", namespace, {"machine": machine, "simulation": True}), env=env),
        subprocess.Popen(node_command("cnc_planner.planner_node", namespace, {"machine": machine, "use_sim_time": True}), env=env),
    ]
    bag = BagWriter(bag_dir, {(t if t.startswith("/") else f"{namespace}/{t}"): m for t, m in RECORDED.items()})
    rclpy.init()
    recorder = Recorder(bag, namespace)
    try:
        _spin_until(recorder, recorder.ready, 30.0, procs, "the planner and bridge did not come up")
        recorder.goal_pub.publish(String(data=text))

        def final() -> dict | None:
            for status in recorder.statuses:
                if progress is not None and status.get("_shown") is None:
                    status["_shown"] = True
                    progress(status)
            return next((s for s in recorder.statuses if s["job_id"] == job_id and s["state"] in FINAL_STATES), None)

        _spin_until(recorder, lambda: final() is not None, timeout, procs, f"job '{job_id}' did not end within {timeout:.0f} s")
        status = final()
        end = recorder.sim_ns + int(SETTLE_S * 1e9)
        if status["state"] != "rejected":
            _spin_until(recorder, lambda: recorder.sim_ns >= end, 10.0, procs, "the bridge stopped publishing")
        return {k: v for k, v in status.items() if k != "_shown"}
    finally:
        recorder.destroy_node()
        rclpy.try_shutdown()
        for proc in procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
        bag.close()


def _spin_until(node: Node, done: Callable[[], bool], timeout: float, procs, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        if time.monotonic() > deadline:
            raise RunError(what)
        dead = [p for p in procs if p.poll() is not None]
        if dead:
            raise RunError(f"{what}: a node exited with code {dead[0].returncode}")
        rclpy.spin_once(node, timeout_sec=0.05)
