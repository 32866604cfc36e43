"""The planner and bridge of one machine as processes: their command lines, their DDS
environment, starting, watching and stopping them. ROS-free, so that cnc-run starts the
nodes before it imports rclpy or its report: the nodes come up while it loads.
"""
from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from cnc_msgs_py import topics
from cnc_msgs_py.discovery import dds_environment

STOP_S = 10.0  # wall time a node gets to exit on SIGINT before it is killed


class RunError(RuntimeError):
    """The run could not be carried out (nodes did not start, another run's nodes, timeout)."""


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


class Claim:
    """This host's claim on a namespace in a DDS domain, held while one run's nodes live.

    Two runs under one namespace in one domain would take each other's goals and feedback.
    Seeing the other run's nodes in the DDS graph takes discovery, which on a busy host
    came up to 1.6 s after the recorder was ready: a second cnc-run then sent its goal to
    both planners. A lock file (flock, released by the kernel when its holder dies) refuses
    a second run on this host at once, before it starts anything; runs on other hosts are
    still found in the graph (``runner.Session``). The nodes inherit the lock's descriptor
    (``fds``): nodes left running by a run that was killed keep their namespace claimed.
    """

    def __init__(self, env: dict[str, str], namespace: str) -> None:
        domain = env.get("ROS_DOMAIN_ID", "0")
        self.path = Path(tempfile.gettempdir()) / f"cnc-domain-{domain}{namespace.replace('/', '-')}.lock"
        while True:
            self.file = self.path.open("a+")
            try:
                fcntl.flock(self.file, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                self.file.seek(0)
                holder = self.file.read().strip() or "unknown"
                self.file.close()
                raise RunError(f"another run (pid {holder}) already runs nodes at {namespace} in ROS_DOMAIN_ID "
                               f"{domain} on this host: set ROS_DOMAIN_ID to a free domain") from None
            try:
                if os.fstat(self.file.fileno()).st_ino == os.stat(self.path).st_ino:
                    break
            except FileNotFoundError:
                pass
            self.file.close()  # locked a file its holder had just removed: take the path's new one
        self.file.truncate(0)
        self.file.write(f"{os.getpid()}\n")
        self.file.flush()

    @property
    def fds(self) -> tuple[int, ...]:
        """The descriptor a node process inherits, sharing the lock until it exits too."""
        return (self.file.fileno(),)

    def release(self) -> None:
        """Give the namespace up (removing the file while still holding its lock)."""
        if not self.file.closed:
            self.path.unlink(missing_ok=True)
            self.file.close()


def free_domain(namespace: str) -> tuple[dict[str, str], Claim]:
    """A domain of our own, as none was chosen: the pid's (1..100), or the next one free of
    runs at ``namespace`` on this host (two runs whose pids agree mod 100 both go ahead)."""
    first = os.getpid() % 100
    for k in range(100):
        env = local_dds_env(1 + (first + k) % 100)
        try:
            return env, Claim(env, namespace)
        except RunError:
            continue
    raise RunError(f"every ROS_DOMAIN_ID from 1 to 100 has a run's nodes at {namespace} on this host")


class Nodes:
    """A machine's bridge (simulation mode: the clock source) and planner (on its time)
    under one namespace, each a process started at once, once this host's claim on the
    namespace is taken (else RunError, and nothing starts)."""

    def __init__(self, machine: str, *, namespace: str = topics.NAMESPACE, env: dict[str, str] | None = None,
                 bridge_params: dict[str, object] | None = None, simulation: bool = True) -> None:
        self.namespace = namespace
        if env is None and not os.environ.get("ROS_DOMAIN_ID"):
            self.env, self.claim = free_domain(namespace)
        else:
            self.env = env or local_dds_env()
            self.claim = Claim(self.env, namespace)
        self.commands = {
            "bridge": node_command("cnc_servo_bridge.bridge_node", namespace,
                                   {"machine": machine, "simulation": simulation, **(bridge_params or {})}),
            "planner": node_command("cnc_planner.planner_node", namespace,
                                    {"machine": machine, "use_sim_time": simulation}),
        }
        self.procs = {name: self._popen(cmd) for name, cmd in self.commands.items()}

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
        self.procs[name] = self._popen(self.commands[name])

    def _popen(self, command: list[str]) -> subprocess.Popen:
        return subprocess.Popen(command, env=self.env, pass_fds=self.claim.fds)

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
                proc.wait()
        self.claim.release()
