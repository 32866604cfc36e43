"""cnc_planner node: job topics in, setpoint chunks out. Wiring only; logic in Executive."""
from __future__ import annotations

import json
import os
import sys
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time as RosTime
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from cnc_msgs_py import qos, topics, trajectory_bytes
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.parameters import declare, value
from cnc_msgs_py.status import Status, decode_cancel, decode_resume
from cnc_msgs_py.units import NS

from cnc_planner.executive import Executive, Output, Settings
from cnc_planner.goal_ledger import GoalLedger
from cnc_planner.planner_main import PARAMETERS, main


def ignore(_msg: object) -> None:
    """The callback of a subscription read with take_latest (never called: not spun)."""


def take_latest(subscription):
    """The newest message waiting in a subscription (None if none)."""
    latest = None
    with subscription.handle:
        while (taken := subscription.handle.take_message(subscription.msg_type, subscription.raw)) is not None:
            latest = taken[0]
    return latest


class PlannerNode(Node):
    def __init__(self) -> None:
        super().__init__(topics.PLANNER_NODE)
        declare(self, PARAMETERS)
        machine = load_machine(value(self, "machine"))
        settings = Settings(
            period_ns=round(value(self, "interpolation_period") * NS),
            chunk_points=value(self, "chunk_points"),
            lookahead_ns=round(value(self, "lookahead") * NS),
            planning_lookahead_ns=round(value(self, "planning_lookahead") * NS),
        )
        self.feedback_timeout = value(self, "feedback_timeout")
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.executive = Executive(machine, settings)
        self.joints = machine.joint_names
        self.status_pub = self.create_publisher(String, topics.JOB_STATUS, qos.JOB_STATUS)
        self.events_pub = self.create_publisher(String, topics.JOB_EVENTS, qos.JOB_EVENTS)
        self.trajectory_pub = self.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, qos.JOINT_TRAJECTORY)
        # The chunks' serialized form (rosbags' types and generated code: 0.1 s) made now,
        # not while the first job's first chunk waits for it.
        trajectory_bytes.layout(tuple(self.joints), settings.chunk_points)
        self.reset_pub = self.create_publisher(String, topics.ALARM_RESET, qos.ALARM_RESET)
        self.create_subscription(String, topics.JOB_GOAL, self.on_goal, qos.JOB_GOAL)
        self.create_subscription(String, topics.JOB_CANCEL, self.on_cancel, qos.JOB_CANCEL)
        self.create_subscription(String, topics.JOB_RESUME, self.on_resume, qos.JOB_RESUME)
        # joint_states come at 1 kHz (many times that in simulation), and /clock with them;
        # the latest of each is read every feedback_period of wall time and at each bridge
        # report (poll), which is all progress, the stream's lookahead and the watchdog need.
        # They are read from a hidden node that no executor spins: DDS keeps the newest
        # message (depth 1) and no message costs a Python callback. The job's end is exact
        # regardless: its status carries the stream's own end time, not the feedback's.
        self.readers = Node("_cnc_planner_readers", context=self.context, start_parameter_services=False,
                            enable_rosout=False,  # the same remappings; no time source of its own
                            parameter_overrides=[Parameter("use_sim_time", Parameter.Type.BOOL, False)])
        self.feedback_sub = self.readers.create_subscription(JointState, topics.JOINT_STATES, ignore, qos.LATEST)
        self.clock_sub = None
        if self.get_parameter("use_sim_time").value:
            self.clock_sub = self.readers.create_subscription(ClockMsg, topics.CLOCK, ignore, qos.LATEST)
            for sub in [s for s in self.subscriptions if s.msg_type is ClockMsg]:
                self.destroy_subscription(sub)  # rclpy's time source's: a callback per /clock message
        self.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, self.on_diagnostics, qos.DIAGNOSTICS)
        self.latest_feedback_ns = 0
        self.announced_ready = False
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.last_feedback_wall = self.wall.now()
        # A heartbeat each second, and at once to each new listener (a recorder waits for it).
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS,
                                              event_callbacks=PublisherEventCallbacks(matched=self.on_listener))
        self.create_timer(1.0, self.heartbeat, clock=self.wall)
        # Goals are validated and planned on a thread of their own, so that a running job's
        # stream never waits for the next job's planning; they are admitted in arrival order.
        self.intake = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cnc_planner_intake")
        self.preparing: deque[tuple[bytes, Future]] = deque()  # (goal key, its preparation)
        self.ledger = GoalLedger()  # a client's resent goal is answered, not run twice
        self.create_timer(value(self, "feedback_period"), self.poll, clock=self.wall)
        self.get_logger().info(f"planning for machine '{machine.name}' joints {self.joints}")

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        """The parameters that may change at run time take effect at once."""
        for parameter in parameters:
            if parameter.name == "lookahead":
                self.executive.settings.lookahead_ns = round(parameter.value * NS)
            elif parameter.name == "planning_lookahead":
                self.executive.settings.planning_lookahead_ns = round(parameter.value * NS)
            elif parameter.name == "feedback_timeout":
                self.feedback_timeout = parameter.value

    def now_ns(self) -> int:
        """The bridge's time, as its latest joint_states says: setpoints are scheduled on
        the clock that executes them (sim or wall), never on a clock that may lag it."""
        return self.latest_feedback_ns

    def clock_ns(self) -> int:
        """The bridge's clock as read here now (real time: the wall; simulation: /clock)."""
        return self.get_clock().now().nanoseconds

    def advance(self, planning: bool, bridge_ns: int = 0) -> None:
        """Tick the executive on the feedback's time, setpoints kept ahead of the clock too
        (and of ``bridge_ns``, the bridge's time in a report that prompted this tick)."""
        self.publish(self.executive.tick(self.now_ns(), planning=planning,
                                         clock_ns=max(self.clock_ns(), bridge_ns)))

    def poll(self, bridge_ns: int = 0) -> None:
        """Take the latest feedback, admit what intake has prepared, and keep the running
        job's setpoints ahead of the bridge's clock (also while feedback is slow to arrive:
        real time under CPU load). ``bridge_ns``: see advance."""
        self.take_clock()
        if (feedback := take_latest(self.feedback_sub)) is not None:
            self.on_feedback(feedback)
        else:
            self.admit_prepared()
        if self.latest_feedback_ns and self.trajectory_pub.get_subscription_count():
            self.advance(planning=bool(self.preparing), bridge_ns=bridge_ns)
        self.watch_feedback()

    def take_clock(self) -> None:
        """In simulation, the latest /clock now (rclpy's time source would set it from a
        callback per message, which waits behind this one and behind planning)."""
        if self.clock_sub is not None and (msg := take_latest(self.clock_sub)) is not None:
            self.get_clock().set_ros_time_override(RosTime.from_msg(msg.clock))

    def publish(self, out: Output) -> None:
        # The bridge's clock now, not at the feedback this output was made for (real time:
        # the wall; simulation: /clock, both the node's clock), so a late start is re-timed.
        # /clock taken afresh: the tick that made ``out`` may have waited for planning.
        self.take_clock()
        self.executive.retime(out, max(self.latest_feedback_ns, self.clock_ns()))
        for chunk in out.chunks:
            self.trajectory_pub.publish(trajectory_bytes.encode(chunk.joints, chunk.stamp_ns, chunk.period_ns,
                                                                chunk.positions, chunk.velocities,
                                                                chunk.accelerations))
        for event in out.events:
            self.events_pub.publish(String(data=json.dumps(event)))
        for status in out.statuses:
            self.publish_status(status)

    def publish_status(self, status: Status) -> None:
        status.stamp_ns = self.latest_feedback_ns
        if status.state in ("rejected", "aborted", "canceled"):
            self.get_logger().warning(f"job '{status.job_id}' {status.state}: {status.reason}")
        elif status.state == "accepted":
            self.get_logger().info(f"job '{status.job_id}' accepted ({status.duration_s:.2f} s planned)")
        self.ledger.published(status)
        self.status_pub.publish(String(data=status.encode()))

    def on_goal(self, msg: String) -> None:
        key = self.ledger.key(msg.data)
        if self.ledger.is_repeat(key):  # sent again by a client that heard nothing yet
            if (answer := self.ledger.answer(key)) is not None:
                self.status_pub.publish(String(data=answer.encode()))
            return
        self.ledger.receive(key)
        # The running job's setpoints go further ahead before planning starts taking the GIL.
        self.advance(planning=True)
        self.preparing.append((key, self.intake.submit(self.executive.prepare, msg.data)))

    def admit_prepared(self) -> None:
        while self.preparing and self.preparing[0][1].done():
            key, prepared = self.preparing.popleft()
            status = self.executive.admit(prepared.result())
            self.ledger.admitted(key, status)
            self.publish_status(status)

    def on_cancel(self, msg: String) -> None:
        self.admit_prepared()
        for status in self.executive.cancel(decode_cancel(msg.data), self.now_ns(), preparing=bool(self.preparing)):
            self.publish_status(status)
        self.advance(planning=bool(self.preparing))

    def on_resume(self, msg: String) -> None:
        """A held program goes on; a resume for a job not held changes nothing but the log."""
        out, error = self.executive.resume(decode_resume(msg.data), self.now_ns())
        if error:
            self.get_logger().warning(error)
        self.publish(out)
        self.advance(planning=bool(self.preparing))

    def on_feedback(self, msg: JointState) -> None:
        """The latest joint_states (taken by ``poll``); nothing starts until a bridge listens
        for setpoints, which would be lost."""
        if ignored := self.executive.feedback(dict(zip(msg.name, msg.position)), dict(zip(msg.name, msg.velocity))):
            self.get_logger().error(ignored, throttle_duration_sec=5.0)
            return
        self.last_feedback_wall = self.wall.now()
        # Not max(): a restarted bridge starts its clock again, and its time is the one that counts.
        self.latest_feedback_ns = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        self.admit_prepared()
        self.announce_ready()

    def announce_ready(self) -> None:
        """A heartbeat at once when the planner first has heard the bridge (where the axes
        stand, and its report): a session submits its job only then, which would otherwise
        wait for the bridge's next report (100 steps of idle sim time at the wall's pace)."""
        if not self.announced_ready and self.executive.heard_bridge:
            self.announced_ready = True
            self.heartbeat()

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        stamp = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        for status in msg.status:
            mine = status.hardware_id == self.get_namespace()  # not another machine's bridge
            if not (mine and status.name.startswith("cnc_servo_bridge")):
                continue
            # The bridge reports every 100 steps: in simulation, where it waits for setpoints,
            # that is the cue to take its feedback and stream on, sooner than the wall timer,
            # ahead of the report's own stamp (best-effort feedback may lag it). Taken before
            # the report is acted on, as the feedback published before it: after an abort
            # the next job starts from feedback that comes later (the axes standing still).
            self.poll(bridge_ns=stamp)
            self.executive.bridge_report(status.message if status.level >= DiagnosticStatus.ERROR else "")
            self.announce_ready()
            if status.level >= DiagnosticStatus.ERROR:
                # The bridge stops the drives itself; the job ends here, unless the alarm
                # is an old one that the running job's first setpoints are clearing. Drives
                # disabled (bridge deactivated) end any job, however early its setpoints.
                disabled = KeyValue(key=topics.DRIVES_KEY, value=topics.DRIVES_OFF) in status.values
                self.publish(Output(statuses=self.executive.abort(status.message, self.now_ns(), stop=False,
                                                                  raised_ns=None if disabled else stamp)))
                if self.executive.active is None:
                    # The job it hit has ended (aborted): acknowledge, so the next one may run.
                    self.reset_pub.publish(String(data="cnc_planner"))

    def on_listener(self, info: QoSPublisherMatchedInfo) -> None:
        """A new diagnostics listener (a recorder waiting for the planner) hears it at once."""
        if info.current_count_change > 0:
            self.heartbeat()

    def heartbeat(self) -> None:
        """Tell the cell the planner is up, and what it is doing."""
        active = self.executive.active
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name="cnc_planner: executive", hardware_id=self.get_namespace(),
            message=f"{'held' if active.held else 'running'} {active.job_id}" if active else "idle",
            values=[KeyValue(key=topics.PID_KEY, value=str(os.getpid())),
                    KeyValue(key=topics.READY_KEY,
                             value=topics.READY if self.executive.heard_bridge else topics.NOT_READY),
                    KeyValue(key="queued", value=str(len(self.executive.queue))),
                    KeyValue(key="machine", value=self.executive.machine.name)])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = Time(sec=self.latest_feedback_ns // NS, nanosec=self.latest_feedback_ns % NS)
        self.diag_pub.publish(msg)

    def destroy_node(self) -> None:
        self.intake.shutdown(wait=False, cancel_futures=True)
        self.readers.destroy_node()
        super().destroy_node()

    def watch_feedback(self) -> None:
        silent = (self.wall.now() - self.last_feedback_wall).nanoseconds / NS
        if self.executive.active is not None and silent > self.feedback_timeout:
            reason = f"no joint_states from the bridge for {silent:.1f} s"
            self.publish(Output(statuses=self.executive.abort(reason, self.now_ns(), stop=False)))


if __name__ == "__main__":  # python -m cnc_planner.planner_node (cnc-run, the tests): the class is here
    sys.exit(main(make=PlannerNode))
