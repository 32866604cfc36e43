"""The planner and bridge of one machine as processes: their command lines, their DDS
environment, starting, watching and stopping them. ROS-free, so that cnc-run starts the
nodes before it imports rclpy or its report: the nodes come up while it loads.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys

from cnc_msgs_py import topics
from cnc_msgs_py.discovery import dds_environment

STOP_S = 10.0  # wall time a node gets to exit on SIGINT before it is killed


def local_dds_env(domain_id: int | None = None) -> dict[str, str]:
    """Environment for ROS processes: what the user chose for DDS (ROS_DOMAIN_ID,
    ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_DISCOVERY_SERVER) is kept; otherwise discovery stays
    on localhost, in ``domain_id`` or a domain of our own."""
    if domain_id is None:
        domain_id = (os.getpid() % 100) + 1
    return dds_environment(os.environ, domain_id)


def topic_name(topic: str, namespace: str) -> str:
    """The full name of a recorded topic. Outside the default namespace (a machine in a
    cell) /clock and /diagnostics become the machine's own, so that several simulated
    machines in one DDS domain keep their clocks and alarms apart."""
    if not topic.startswith("/"):
        return f"{namespace}/{topic}"
    return topic if namespace == topics.NAMESPACE else f"{namespace}{topic}"


def node_command(module: str, namespace: str, params: dict[str, object]) -> list[str]:
    args = [sys.executable, "-m", module, "--ros-args", "-r", f"__ns:={namespace}"]
    for topic in (topics.CLOCK, topics.DIAGNOSTICS):
        if topic_name(topic, namespace) != topic:
            args += ["-r", f"{topic}:={topic_name(topic, namespace)}"]
    for key, value in params.items():
        args += ["-p", f"{key}:={str(value).lower() if isinstance(value, bool) else value}"]
    return args


class Nodes:
    """A machine's bridge (simulation mode: the clock source) and planner (on its time)
    under one namespace, each a process started at once."""

    def __init__(self, machine: str, *, namespace: str = topics.NAMESPACE, env: dict[str, str] | None = None,
                 bridge_params: dict[str, object] | None = None, simulation: bool = True) -> None:
        self.namespace = namespace
        self.env = env or local_dds_env()
        self.commands = {
            "bridge": node_command("cnc_servo_bridge.bridge_node", namespace,
                                   {"machine": machine, "simulation": simulation, **(bridge_params or {})}),
            "planner": node_command("cnc_planner.planner_node", namespace,
                                    {"machine": machine, "use_sim_time": simulation}),
        }
        self.procs = {name: subprocess.Popen(cmd, env=self.env) for name, cmd in self.commands.items()}

    def pids(self) -> set[int]:
        return {proc.pid for proc in self.procs.values()}

    def exited(self) -> str | None:
        """The first node that has exited, as "the <node> exited with code N"; None if all run."""
        dead = [name for name, p in self.procs.items() if p.poll() is not None]
        return f"the {dead[0]} exited with code {self.procs[dead[0]].returncode}" if dead else None

    def kill(self, name: str) -> None:
        """Kill a node the hard way (SIGKILL), as a crash would."""
        proc = self.procs.pop(name)
        proc.kill()
        proc.wait(timeout=STOP_S)

    def start(self, name: str) -> None:
        """Start a killed node again, with the same parameters."""
        self.procs[name] = subprocess.Popen(self.commands[name], env=self.env)

    def stop(self) -> None:
        """SIGINT to every node (a clean shutdown), SIGKILL to any still running after STOP_S."""
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in self.procs.values():
            try:
                proc.wait(timeout=STOP_S)
            except subprocess.TimeoutExpired:
                proc.kill()
