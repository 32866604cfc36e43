"""A cell controller's client for the CNC planner: submit, follow, wait for, cancel jobs.

``CncClient`` is a small task API over an rclpy node you own, in the manner of
nav2_simple_commander (in snake_case, without a polling loop or thread of its own)::

    import rclpy
    from cnc_msgs_py.client import CncClient

    rclpy.init()
    node = rclpy.create_node("cell_controller")
    client = CncClient(node, namespace="/cnc")
    client.on_progress(lambda s: print(s["job_id"], s["state"], f"{100 * s['progress']:.0f}%"))
    job_id = client.submit("config/jobs/drill_row.yaml")   # dict, YAML/JSON text or a file
    final = client.wait(job_id, timeout=120.0)              # spins the node until final
    print(final["state"], final["cycle_time_s"])

A program that pauses (M0, M1) is ``held`` until resumed: ``wait(job_id, held=True)`` returns
at the hold too (its status's reason says at which line), ``resume(job_id)`` goes on.

``bridge_transition("deactivate")`` (a controlled stop), ``("activate")`` and ``bridge_state()``
drive the bridge's standard lifecycle services.

A job is validated whole with the planner's own ``parse_job`` before it is sent, so a bad
job raises ``JobError`` naming the field and nothing reaches ``job_goal``. Statuses are
``cnc_status/1`` documents (as dicts); ``wait`` and ``submit`` spin the node (or the
executor given), everything else only reads what the node's callbacks have received.

On a shop floor (docs/shop-floor.md, planner on the machine's controller, client on the
cell controller) ``reachable`` and ``on_reachability`` say whether DDS still hears the
planner (liveliness of job_status, lease ``qos.PLANNER_LEASE_S``). A job runs on while its
machine is cut off, and its statuses, kept by the planner, arrive once it is reachable
again; ``follow(job_id)`` follows a job another controller sent (or one sent before a restart).

``cnc-submit JOB`` wraps the client for the shell, against nodes already running (``ros2
run`` from a colcon install, or the ``cnc-planner``/``cnc-bridge`` console scripts).

rclpy is imported only when a client is made: the rest of cnc_msgs_py stays ROS-free.
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any, Callable

from . import topics
from .bridge_lifecycle import BridgeLifecycle, CncClientError
from .job import load_job
from .liveliness import AliveWriters
from .status import FINAL_STATES, Status, encode_cancel, encode_resume, holds_passed

CONNECT_TIMEOUT_S = 10.0  # how long submit waits for a planner to listen on job_goal
RESEND_S = 2.0  # a goal no status has answered within this is sent again (see submit)
MATCH_OTHERS_S = 1.0  # then, at most this long for the other listeners on job_goal to match
LISTENER_WAIT_S = 2.0  # cancel, resume: at most this long for the planner to listen first
HISTORY_S = 0.5  # hear: the kept statuses that follow the first heard of a job (one burst)


class CncClient:
    """Submit jobs to the planner under ``namespace`` and follow them over job_status.

    Args:
        node: an rclpy Node you own; the client adds two publishers, a subscription and
            a timer (goal resends).
        namespace: the planner's namespace (topics ``<namespace>/job_goal`` etc.).
        executor: the executor ``node`` is spun by, if any; default rclpy's global one.
    """

    def __init__(self, node: Any, namespace: str = topics.NAMESPACE, executor: Any = None) -> None:
        from rclpy.clock import Clock, ClockType
        from rclpy.event_handler import SubscriptionEventCallbacks
        from std_msgs.msg import String

        from . import qos

        self.node = node
        self.executor = executor
        self.namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
        self.goal_topic = f"{self.namespace}/{topics.JOB_GOAL}"
        self.cancel_topic = f"{self.namespace}/{topics.JOB_CANCEL}"
        self.resume_topic = f"{self.namespace}/{topics.JOB_RESUME}"
        self.status_topic = f"{self.namespace}/{topics.JOB_STATUS}"
        self._string = String
        self._goal_pub = node.create_publisher(String, self.goal_topic, qos.JOB_GOAL)
        self._cancel_pub = node.create_publisher(String, self.cancel_topic, qos.JOB_CANCEL)
        self._resume_pub = node.create_publisher(String, self.resume_topic, qos.JOB_RESUME)
        self._status_sub = node.create_subscription(
            String, self.status_topic, self._on_status, qos.JOB_STATUS,
            event_callbacks=SubscriptionEventCallbacks(liveliness=self._on_liveliness))
        self._statuses: dict[str, dict] = {}  # latest status per job submitted here
        self._submitted: set[str] = set()
        self._resumed: dict[str, int] = {}  # job_id -> the holds it had passed when last resumed
        self._unanswered: dict[str, tuple[str, float]] = {}  # job_id -> (goal text, monotonic time sent)
        node.create_timer(RESEND_S / 4, self._resend_unanswered, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._others: dict[str, dict] = {}  # latest status of the other jobs heard (for follow)
        self._callbacks: list[Callable[[dict], None]] = []
        self._reachable: bool | None = None  # None until DDS has said anything
        self._alive = AliveWriters()  # planners (job_status writers) DDS holds alive
        self._reachability_callbacks: list[Callable[[bool], None]] = []
        self._bridge = BridgeLifecycle(node, f"{self.namespace}/{topics.BRIDGE_NODE}", self._spin_once)

    # -- the task API -------------------------------------------------------------------

    def submit(self, job: dict | str | Path, connect_timeout: float = CONNECT_TIMEOUT_S) -> str:
        """Validate a job and send it on job_goal; returns its job_id.

        Waits (spinning the node) up to ``connect_timeout`` s for a planner to listen.
        While no status for the job is heard, the goal is sent again every RESEND_S as the
        node spins: a planner whose side of the DDS match came after the goal never saw it,
        and one that did answers the copy with the job's latest status, never runs it twice.

        Raises:
            JobError: the job is invalid (nothing is sent); names the field.
            CncClientError: no planner listens on ``<namespace>/job_goal``.
        """
        doc = load_job(job)
        job_id = doc["job_id"]
        self.wait_for_planner(connect_timeout)
        self._statuses.pop(job_id, None)
        self._submitted.add(job_id)
        text = json.dumps(doc)
        self._unanswered[job_id] = (text, time.monotonic())
        self._goal_pub.publish(self._string(data=text))
        return job_id

    def wait(self, job_id: str, timeout: float | None = None, held: bool = False) -> dict:
        """Spin until the job is final (rejected, succeeded, aborted, canceled), or with
        ``held`` also until it is held at a program pause (M0/M1); its status.

        Raises:
            TimeoutError: the job was not final (nor held) within ``timeout`` seconds.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._final(job_id) and not (held and self._state(job_id) == "held"):
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                last = self._statuses.get(job_id)
                seen = f" (last seen: {last['state']}, {100 * last.get('progress', 0):.0f}%)" if last else ""
                seen += f": {last['reason']}" if last and last["state"] == "held" else ""
                lost = ", the planner unreachable" if self._reachable is False else ""
                raise TimeoutError(f"job '{job_id}' did not end within {timeout:g} s{seen}{lost}")
            self._spin_once(0.1 if left is None else min(0.1, left))
        return dict(self._statuses[job_id])

    def cancel(self, job_id: str) -> None:
        """Ask the planner to cancel a queued or running job (a jerk-limited stop)."""
        self._publish_when_heard(self._cancel_pub, encode_cancel(job_id))

    def _publish_when_heard(self, publisher, text: str) -> None:
        """Publish once a planner listens (up to LISTENER_WAIT_S): a request sent before the
        topic has matched would be lost."""
        deadline = time.monotonic() + LISTENER_WAIT_S
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            self._spin_once(0.05)
        publisher.publish(self._string(data=text))

    def resume(self, job_id: str) -> None:
        """Resume a program held at a pause (M0/M1): its job_id on job_resume. The statuses
        that follow are new (``wait`` waits for them, not the hold's).

        Raises:
            CncClientError: no held status of the job has been heard here (one line; nothing
                is sent). A job another controller sent is heard once ``follow``-ed.
        """
        state = self._state(job_id)
        if state != "held":
            heard = f"its latest status: {state}" if state else "no status heard for it"
            raise CncClientError(f"job '{job_id}' is not held ({heard}); only a program held at M0/M1 resumes")
        # this hold's statuses still on their way are old news (a later hold has passed one more mark)
        self._resumed[job_id] = holds_passed(self._statuses.pop(job_id))
        self._publish_when_heard(self._resume_pub, encode_resume(job_id))

    def _state(self, job_id: str) -> str:
        latest = self._statuses.get(job_id)
        return latest["state"] if latest is not None else ""

    def status(self, job_id: str) -> dict | None:
        """The latest status received for a job submitted here, or None (does not spin)."""
        latest = self._statuses.get(job_id)
        return dict(latest) if latest is not None else None

    def on_progress(self, callback: Callable[[dict], None]) -> None:
        """Call ``callback(status)`` with every status of the jobs submitted here."""
        self._callbacks.append(callback)

    def follow(self, job_id: str) -> None:
        """Follow a job this client did not submit (another controller's, or one sent before
        a restart): its statuses, including those the planner kept, count as for one
        submitted here (``status``, ``wait``, ``on_progress``)."""
        self._submitted.add(job_id)
        heard = self._others.pop(job_id, None)  # a status that came before (a latched one)
        if heard is not None and not self._final(job_id):
            self._statuses[job_id] = heard
            for callback in self._callbacks:
                callback(dict(heard))

    def hear(self, job_id: str, timeout: float) -> dict | None:
        """``follow`` the job and spin up to ``timeout`` s until a status of it is heard (the
        planner keeps its latest statuses on job_status), then HISTORY_S more for the rest of
        that history, which comes oldest first; the newest status, or None."""
        self.follow(job_id)
        deadline = time.monotonic() + timeout
        while job_id not in self._statuses and time.monotonic() < deadline:
            self._spin_once(0.05)
        deadline = min(deadline, time.monotonic() + HISTORY_S)
        while job_id in self._statuses and time.monotonic() < deadline:
            self._spin_once(0.05)
        return self.status(job_id)

    @property
    def reachable(self) -> bool | None:
        """Whether the planner is heard (DDS liveliness of its job_status, renewed within
        ``qos.PLANNER_LEASE_S``); None until DDS has said either. Does not spin."""
        return self._reachable

    def on_reachability(self, callback: Callable[[bool], None]) -> None:
        """Call ``callback(reachable)`` whenever the planner is lost (False: not heard for
        ``qos.PLANNER_LEASE_S``) or found again (True)."""
        self._reachability_callbacks.append(callback)

    def planner_listening(self) -> bool:
        """Whether the graph shows a planner here: a node that listens on job_goal (matched
        with our publisher) and publishes job_status. Does not spin."""
        if self._goal_pub.get_subscription_count() == 0:
            return False
        publishers = {(i.node_namespace, i.node_name) for i in self.node.get_publishers_info_by_topic(self.status_topic)}
        return any((i.node_namespace, i.node_name) in publishers
                   for i in self.node.get_subscriptions_info_by_topic(self.goal_topic))

    def wait_for_planner(self, timeout: float = CONNECT_TIMEOUT_S) -> None:
        """Spin until a planner listens on job_goal and publishes job_status.

        A recorder may listen on job_goal too, so the listener must be a node that also
        publishes job_status.

        Raises:
            CncClientError: none did within ``timeout`` seconds.
        """
        deadline = time.monotonic() + timeout
        while not self.planner_listening():
            if time.monotonic() > deadline:
                raise CncClientError(f"no planner listens on {self.goal_topic} (waited {timeout:g} s); "
                                     f"start one, or check --namespace and ROS_DOMAIN_ID")
            self._spin_once(0.05)
        # Best effort for the other listeners the graph already shows (a recorder):
        # job_goal keeps no history, so a goal sent before they are matched is missing
        # from their recording.
        deadline = time.monotonic() + MATCH_OTHERS_S
        while (self._goal_pub.get_subscription_count() < len(self.node.get_subscriptions_info_by_topic(self.goal_topic))
               and time.monotonic() < deadline):
            self._spin_once(0.02)

    def bridge_transition(self, transition: str, timeout: float = CONNECT_TIMEOUT_S) -> str:
        """Ask the bridge for a lifecycle transition by its label (configure, activate,
        deactivate, cleanup, shutdown), over ``<namespace>/cnc_servo_bridge/change_state``;
        returns the state it is in afterwards ('inactive', 'active', ...).

        Raises:
            CncClientError: no bridge answered within ``timeout`` s, or it refused the
                transition (not available from its state, or the transition failed).
        """
        return self._bridge.transition(transition, timeout)

    def bridge_state(self, timeout: float = CONNECT_TIMEOUT_S) -> str:
        """The bridge's lifecycle state: unconfigured, inactive, active or finalized.

        Raises:
            CncClientError: no bridge answered within ``timeout`` s.
        """
        return self._bridge.state(timeout)

    def _on_liveliness(self, info: Any) -> None:
        self._set_reachable(self._alive.change(info.alive_count_change) > 0)

    def _set_reachable(self, reachable: bool) -> None:
        if reachable != self._reachable:
            self._reachable = reachable
            for callback in self._reachability_callbacks:
                callback(reachable)

    def _final(self, job_id: str) -> bool:
        latest = self._statuses.get(job_id)
        return latest is not None and latest["state"] in FINAL_STATES

    def _on_status(self, msg: Any) -> None:
        # A status is word from the planner: reachable, even if DDS's first liveliness event
        # was missed. It changes no count (see liveliness.py).
        self._set_reachable(True)
        try:
            doc = dataclasses.asdict(Status.decode(msg.data))
        except (ValueError, TypeError):
            self.node.get_logger().warning(f"ignoring a malformed status on {self.status_topic}: {msg.data[:80]}")
            return
        job_id = doc["job_id"]
        if job_id not in self._submitted:  # another controller's job, or a latched status from before
            if self._others.get(job_id, {}).get("state") not in FINAL_STATES:
                self._others[job_id] = dict(doc)
            return
        self._unanswered.pop(job_id, None)
        if self._final(job_id):
            return  # a job is final once; later copies (re-delivered latched ones) change nothing
        if doc["state"] == "held" and holds_passed(doc) <= self._resumed.get(job_id, -1):
            return  # the hold resumed already
        self._statuses[job_id] = dict(doc)
        for callback in self._callbacks:
            callback(dict(doc))

    def _resend_unanswered(self) -> None:
        now = time.monotonic()
        for job_id, (text, sent) in list(self._unanswered.items()):
            if now - sent >= RESEND_S:
                self._unanswered[job_id] = (text, now)
                self._goal_pub.publish(self._string(data=text))

    def _spin_once(self, timeout: float) -> None:
        if self.executor is not None:
            self.executor.spin_once(timeout_sec=timeout)
        else:
            import rclpy

            rclpy.spin_once(self.node, timeout_sec=timeout)
