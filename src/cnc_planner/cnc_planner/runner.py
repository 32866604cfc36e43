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
import subprocess
import time
from pathlib import Path
from typing import Callable

import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.task import Future
from builtin_interfaces.msg import Time
from std_msgs.msg import String

from cnc_msgs_py import qos, topics
from cnc_msgs_py.discovery import DDS_VARIABLES
from cnc_msgs_py.header_bytes import read_stamp
from cnc_msgs_py.heard import NodesHeard
from cnc_msgs_py.status import FINAL_STATES
from cnc_msgs_py.units import NS
from cnc_analysis.recording import RECORDED, BagWriter

from cnc_planner.nodes import Nodes, RunError, local_dds_env, node_command, topic_name  # noqa: F401 (the runner's API)
from cnc_planner.pauses import Pauses

QOS = {
    "job_goal": qos.JOB_GOAL, "job_cancel": qos.JOB_CANCEL, "job_status": qos.JOB_STATUS,
    "job_events": qos.JOB_EVENTS, "joint_trajectory": qos.JOINT_TRAJECTORY,
    "joint_states": qos.JOINT_STATES, "/diagnostics": qos.DIAGNOSTICS, "/clock": qos.CLOCK,
}
HEARTBEAT_WAIT_S = 1.5  # wall time to hear a planner's heartbeat (each 1 s) from nodes named as ours
SETTLE_S = 0.2  # sim time recorded after the final status, so the drives' settling shows
PROCESS_CHECK_S = 0.1  # wall time between checks of the deadline and the node processes
SPIN_S = 0.05  # wall time a spin waits for a reason to return (the recorder's wake)
ACK_EVERY_NS = 25_000_000  # tell the bridge what has been written every 25 ms of its time:
# a quarter of its window (RECORDER_WINDOW_NS), each acknowledgement a DDS write (~0.1 ms)


def message_class(msgtype: str) -> type:
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class Recorder(Node):
    """Records every CNC topic to the bag (raw CDR) and follows the job's status."""

    def __init__(self, bag: BagWriter, namespace: str) -> None:
        super().__init__("cnc_run_recorder", namespace=namespace)
        self.bag = bag
        self.statuses: list[dict] = []
        self.finals: dict[str, dict] = {}  # job_id -> its final status (looked up per message)
        self.sim_ns, self.feedback_ns = 0, 0  # the last /clock and joint_states recorded
        self.heard = NodesHeard(self.get_namespace())  # the nodes' diagnostics
        self.goal_pub = self.create_publisher(String, topics.JOB_GOAL, qos.JOB_GOAL)
        # Backpressure: a simulated bridge does not run more than a bounded window ahead of this.
        self.ack_pub = self.create_publisher(Time, topics.RECORDED_UNTIL, qos.RECORDED_UNTIL)
        self.acked_ns = 0
        self.wake = Future()  # done when the session has something to check or acknowledge
        for topic, msgtype in RECORDED.items():
            name = topic_name(topic, namespace)
            self.create_subscription(message_class(msgtype), name, self._writer(name, topic), QOS[topic], raw=True)

    def _writer(self, name: str, topic: str) -> Callable[[bytes], None]:
        def write(data: bytes) -> None:
            if topic == "/clock":  # rosgraph_msgs/Clock: its Time where a Header's stamp is
                self.sim_ns = read_stamp(data)
            elif topic == "joint_states":
                self.feedback_ns = read_stamp(data)
            # Bag time: the machine's time (sim time, or the wall clock in real-time mode).
            self.bag.write(name, max(self.sim_ns, self.feedback_ns), data)
            if topic == "job_status":
                status = json.loads(deserialize_message(data, String).data)
                self.statuses.append(status)
                if status["state"] in FINAL_STATES:
                    self.finals.setdefault(status["job_id"], status)
            elif topic == "/diagnostics":
                self.heard.hear(deserialize_message(data, message_class(RECORDED["/diagnostics"])).status)
            # A job's state and the nodes' liveness are what the session's conditions read.
            if (topic in ("job_status", "/diagnostics") or self.ack_due) and not self.wake.done():
                self.wake.set_result(topic)
        return write

    def acknowledge(self) -> None:
        """Tell the bridge what has been written (recorded_until), between spins only: the
        caller's condition (a job's end, an instant to cancel at) is checked first, so
        no acknowledgement lets the clock run on past it."""
        if self.ack_due:
            self.acked_ns = self.feedback_ns
            self.ack_pub.publish(Time(sec=self.feedback_ns // NS, nanosec=self.feedback_ns % NS))

    @property
    def ack_due(self) -> bool:
        """ACK_EVERY_NS recorded since the last acknowledgement (or the bridge's clock went
        back: a restarted bridge starts it again)."""
        return not 0 <= self.feedback_ns - self.acked_ns < ACK_EVERY_NS

    def ready(self, own: set[int]) -> bool:
        """Planner listening for goals and talking, and bridge publishing feedback, both
        heard from the processes ``own`` (not another run's nodes in the same domain), and
        the planner having heard the bridge.

        The goal publisher seeing the planner's subscription is not enough: the planner's
        side of that match may come later, and a volatile reader drops what was sent before
        it matched (a goal lost on a loaded host: the planner stayed idle and cnc-run waited
        out its timeout). The planner's heartbeat saying ready (its pid among ``own``) shows
        both participants have discovered each other's endpoints, and that it has heard the
        bridge: a goal sent before waited for the bridge's next report, at idle sim time's
        wall pace."""
        return (own <= self.heard.pids and bool(own & self.heard.ready)
                and self.goal_pub.get_subscription_count() >= 2 and self.feedback_ns > 0)


class Session:
    """Planner and bridge processes under one namespace, recorded to one bag.

    The shape of a task API: ``submit`` a job, ``cancel`` it, ``wait`` for its final
    status; progress arrives through the ``progress`` callback.
    """

    def __init__(self, machine: str, bag_dir: Path, *, namespace: str = "/cnc",
                 env: dict[str, str] | None = None, progress: Callable[[dict], None] | None = None,
                 bridge_params: dict[str, object] | None = None, simulation: bool = True,
                 nodes: Nodes | None = None) -> None:
        """``nodes``: the machine's processes if already started (cnc-run starts them first),
        else they are started here."""
        self.nodes = nodes or Nodes(machine, namespace=namespace, env=env, bridge_params=bridge_params,
                                    simulation=simulation)
        self.env = self.nodes.env
        os.environ.update({k: self.env[k] for k in DDS_VARIABLES if k in self.env})  # the recorder's
        self.progress = progress
        self.bag = BagWriter(bag_dir, {topic_name(t, namespace): m for t, m in RECORDED.items()})
        rclpy.init()
        self.recorder = Recorder(self.bag, namespace)
        # One executor for the whole session, event driven: rclpy's SingleThreadedExecutor
        # rebuilds its wait set in Python for every message, about 0.3 ms each, which set
        # the pace of a simulation running faster than real time (1 kHz feedback). It
        # misses a message that arrives before the node is added (see cnc_msgs_py.node):
        # the recorder is added before it publishes a goal, and the feedback it might miss
        # then comes before any job.
        self.executor = EventsExecutor()
        self.executor.add_node(self.recorder)
        self.cancel_pub = self.recorder.create_publisher(String, topics.JOB_CANCEL, qos.JOB_CANCEL)
        self.resume_pub = self.recorder.create_publisher(String, topics.JOB_RESUME, qos.JOB_RESUME)
        self.fault_pub = self.recorder.create_publisher(String, topics.INJECT_FAULT, qos.INJECT_FAULT)
        self._shown = 0

    def __enter__(self) -> "Session":
        try:
            self.spin_until(self.ready, 30.0, "the planner and bridge did not come up")
            # Two runs in one domain and namespace would take each other's goals. On this host
            # the nodes' Claim has refused a second run; nodes of another host (or started by
            # other means) are found here, as far as discovery has got: up to 1.6 s after
            # ready on a busy host, so this is a guard, not a proof. Once the other nodes are
            # in the graph under our names, wait for their heartbeat (a node that has just
            # died stays in the graph a while, silent).
            if self._doubled():
                deadline = time.monotonic() + HEARTBEAT_WAIT_S
                self.spin_until(lambda: bool(self.recorder.heard.pids - self.own_pids())
                                or time.monotonic() > deadline, 2 * HEARTBEAT_WAIT_S, "the nodes went quiet")
            if others := sorted(self.recorder.heard.pids - self.own_pids()):
                raise RunError(f"other nodes (pid {', '.join(map(str, others))}) already run at "
                               f"{self.recorder.get_namespace()} in ROS_DOMAIN_ID {self.env.get('ROS_DOMAIN_ID', '0')} "
                               f"(another cnc-run?): set ROS_DOMAIN_ID to a free domain")
        except RunError:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _doubled(self) -> bool:
        """A planner or bridge of another process under this namespace, in the DDS graph."""
        names = self.recorder.get_node_names_and_namespaces()
        namespace = self.recorder.get_namespace()
        return any(sum(1 for n, ns in names if n == node and ns == namespace) > 1
                   for node in (topics.PLANNER_NODE, topics.BRIDGE_NODE))

    @property
    def procs(self) -> dict[str, "subprocess.Popen"]:
        """The node processes by name ("bridge", "planner")."""
        return self.nodes.procs

    def own_pids(self) -> set[int]:
        return self.nodes.pids()

    def ready(self) -> bool:
        """This session's planner and bridge are up and talking (see Recorder.ready)."""
        return self.recorder.ready(self.own_pids())

    def kill(self, name: str) -> None:
        """Kill a node the hard way (SIGKILL), as a crash would."""
        self.nodes.kill(name)

    def restart(self, name: str) -> None:
        """Start a killed node again, with the same parameters, and wait until it talks."""
        self.nodes.start(name)
        if name == "planner":
            heard, seen = self.recorder.heard, self.recorder.heard.planner_heartbeats
            self.spin_until(lambda: heard.planner_heartbeats >= seen + 2, 30, "the planner did not come back")

    def submit(self, text: str) -> None:
        self.recorder.goal_pub.publish(String(data=text))

    def cancel(self, job_id: str) -> None:
        self.cancel_pub.publish(String(data=job_id))

    def resume(self, job_id: str) -> None:
        """Resume a program held at M0/M1 (job_resume)."""
        self.resume_pub.publish(String(data=job_id))

    def held(self, job_id: str) -> dict | None:
        """The job's latest status if it says the job is held (M0/M1), else None."""
        latest = next((s for s in reversed(self.recorder.statuses) if s["job_id"] == job_id), None)
        return latest if latest is not None and latest["state"] == "held" else None

    def inject(self, joint: str, offset: float) -> None:
        """Displace one axis of the emulated drives (fault injection)."""
        self.fault_pub.publish(String(data=json.dumps({"joint": joint, "offset": offset})))

    def final_status(self, job_id: str) -> dict | None:
        return self.recorder.finals.get(job_id)

    def wait(self, job_id: str, timeout: float, pauses: Pauses | None = None) -> dict:
        """Spin until the job is final; returns its final status document. ``pauses`` acts
        on the job's holds (M0/M1); without, a held job waits for a resume (``resume``)."""
        self.spin_until(lambda: self.final_status(job_id) is not None or (pauses is not None and self._act(pauses)),
                        timeout, f"job '{job_id}' did not end within {timeout:.0f} s")
        return self.final_status(job_id)

    def _act(self, pauses: Pauses) -> bool:
        """Resume or cancel the job at a hold when ``pauses`` says so; never ends the wait (False)."""
        due = pauses.due(self.held(pauses.job_id), self.recorder.feedback_ns)
        if due is not None:
            action, said = due
            print(said, flush=True)
            getattr(self, action)(pauses.job_id)
        return False

    def settle(self, status: dict, seconds: float = SETTLE_S) -> None:
        """Record until a little after a final status: the recorder may still be working
        through queued feedback, and the drives' settling should show in the bag."""
        end = max(status.get("stamp_ns", 0), self.recorder.feedback_ns) + int(seconds * 1e9)
        self.spin_until(lambda: self.recorder.feedback_ns >= end, 60.0, "the bridge stopped publishing")

    def spin_until(self, done: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        next_check = 0.0
        while not done():
            if (now := time.monotonic()) >= next_check:
                if now > deadline:
                    raise RunError(what)
                if exited := self.nodes.exited():
                    raise RunError(f"{what}: {exited}")
                next_check = now + PROCESS_CHECK_S
            # Messages until the recorder wakes (an ack due, a status), not one per call.
            self.recorder.wake = Future()
            self.executor.spin_until_future_complete(self.recorder.wake, timeout_sec=SPIN_S)
            if self.progress is not None:
                for status in self.recorder.statuses[self._shown:]:
                    self.progress(status)
                self._shown = len(self.recorder.statuses)
            if not done():  # once it holds, no ack lets the clock run on past it
                self.recorder.acknowledge()

    def close(self) -> None:
        self.executor.remove_node(self.recorder)
        self.recorder.destroy_node()
        rclpy.try_shutdown()
        self.nodes.stop()
        self.bag.close()


def run_job(text: str, job_id: str, machine: str, bag_dir: Path, *, timeout: float = 900.0,
            progress: Callable[[dict], None] | None = None, namespace: str = topics.NAMESPACE,
            plant: str = "", nodes: Nodes | None = None, resume_after: float | None = None) -> dict:
    """Run one job document (JSON text) through both nodes, recording to ``bag_dir``; the
    bridge emulates ``plant`` (a plant file) if given. ``nodes``: the nodes if already
    started (with that machine, namespace and plant), which the run stops at its end.
    ``resume_after``: a program held at M0/M1 goes on after that many s of machine time
    (None: it is canceled at its first hold).

    Returns the job's final status document.

    Raises:
        RunError: the nodes did not come up, or the job did not end within ``timeout``.
    """
    bridge = {"plant": plant} if plant else None
    with Session(machine, bag_dir, progress=progress, namespace=namespace, bridge_params=bridge,
                 nodes=nodes) as session:
        session.submit(text)
        status = session.wait(job_id, timeout, Pauses(job_id, resume_after))
        if status["state"] != "rejected":
            session.settle(status)
        return status
