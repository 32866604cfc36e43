"""cnc_servo_bridge node: setpoint chunks in, emulated drives, joint_states out.

A managed (lifecycle) node, like a ros2_control hardware component: configure loads and
checks the machine description and creates the drive model (the axes then report
joint_states, drives disabled), activate enables the drives (setpoints accepted),
deactivate is a jerk-limited stop with setpoints refused, cleanup releases the drive
model, shutdown ends it. With ``autostart`` (the default) it brings itself up to active.

In simulation mode the bridge owns time: it publishes /clock in lockstep with its servo
steps, runs as fast as setpoints allow while axes move, waits for setpoints (up to
``underrun_timeout`` of wall time) rather than starving, and paces idle time to the wall
clock (lockstep.py). In real-time mode it steps on a wall timer (lockstep.WallPacing) and stamps with the system
clock.
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from cnc_msgs_py import qos, topics, trajectory_bytes
from cnc_msgs_py.machine import MachineError, load_machine
from cnc_msgs_py.parameters import declare, value
from cnc_msgs_py.plant import load_plant, outside_tolerance
from cnc_msgs_py.units import NS

from .bridge_main import PARAMETERS, main
from .feedback_msg import ClockBytes, FeedbackBytes
from .lockstep import Lockstep, WallPacing
from .servo import DRIVES_DISABLED, Feedback, ServoLoop
from .setpoints import SetpointError

AT_CONFIGURE = {name for name, param in PARAMETERS.items() if param.at_configure}
DEACTIVATED = "bridge deactivated: the drives stop (jerk-limited) and refuse setpoints until it is activated"
SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


SINGLE_STEPS_PER_CALLBACK = 10  # steps outside a block (idle, stopping) per timer callback:
# idle sim time catches up with the wall clock at this pace after a late callback


def stamp(t_ns: int) -> Time:
    return Time(sec=t_ns // NS, nanosec=t_ns % NS)


class BridgeNode(LifecycleNode):
    def __init__(self) -> None:
        super().__init__(topics.BRIDGE_NODE)
        declare(self, PARAMETERS)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.loop: ServoLoop | None = None  # the drive model, from configure to cleanup
        self.t_ns: int | None = None  # the next servo step; sim time runs on across cleanup
        self.failure = ""
        if value(self, "autostart"):
            for transition in (self.trigger_configure, self.trigger_activate):
                if transition() != SUCCESS:
                    raise ValueError(self.failure or "autostart failed")

    # -- lifecycle transitions -------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load and check the machine description, create the drive model (drives disabled)."""
        try:
            machine = load_machine(value(self, "machine"))
            plant = load_plant(value(self, "plant"), machine)
            self.period_ns = round(value(self, "servo_period") * NS)
            start = value(self, "start_position") or machine.home_position
            self.loop = ServoLoop(machine, self.period_ns, np.asarray(start, dtype=float), enabled=False, plant=plant)
        except (MachineError, ValueError) as err:
            self.failure = f"configure: {err}"
            self.get_logger().error(self.failure)
            return FAILURE
        self.simulation = value(self, "simulation")
        self.publish_every = max(1, round(NS / value(self, "joint_state_rate") / self.period_ns))
        self.clock_every = max(1, round(NS / value(self, "clock_rate") / self.period_ns))
        # Bounded machine time per callback (0.1 s) so that setpoint chunks (a stop!) are
        # taken between batches; the loop steps them in blocks (ServoLoop.run).
        self.max_steps = value(self, "steps_per_callback")
        self.joints = tuple(machine.joint_names)
        self.state_pub = self.create_publisher(JointState, topics.JOINT_STATES, qos.JOINT_STATES)
        # One serialized message refilled for every sample (feedback_msg.py); the chunks'
        # form read in place made now too, not while the first job's first chunk waits.
        self.state_msg = FeedbackBytes(self.joints)
        trajectory_bytes.layout(self.joints, 2)
        # At once to each new listener, not only every 100 steps: a planner starts no job before it hears it.
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS,
                                              event_callbacks=PublisherEventCallbacks(matched=self.on_listener))
        self.clock_pub = self.create_publisher(Clock, topics.CLOCK, qos.CLOCK) if self.simulation else None
        self.clock_msg = ClockBytes() if self.simulation else None
        self.inputs = [
            self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY, self.on_trajectory, qos.JOINT_TRAJECTORY,
                                     raw=True),  # read in place (trajectory_bytes.py)
            # Fault injection for tests and commissioning: {"joint": "x", "offset": 0.005} (m or rad).
            self.create_subscription(String, topics.INJECT_FAULT, self.on_inject, qos.INJECT_FAULT),
            self.create_subscription(String, topics.ALARM_RESET, self.on_reset, qos.ALARM_RESET),
            self.create_subscription(Time, topics.RECORDED_UNTIL, self.on_recorded, qos.RECORDED_UNTIL),
        ]
        self.reported_alarm = ""
        if not self.simulation:
            self.t_ns = self.get_clock().now().nanoseconds // self.period_ns * self.period_ns
        elif self.t_ns is None:
            self.t_ns = 0
        else:  # configured again: sim time goes on from the last step, on the new grid
            self.t_ns = -(-self.t_ns // self.period_ns) * self.period_ns
        self.steps = 0
        self.rejected = ""
        self.lockstep = Lockstep(self.period_ns, value(self, "underrun_timeout"), self.t_ns, time.monotonic())
        self.pacing = WallPacing(self.period_ns)
        self.timer = self.create_timer(0.001 if self.simulation else value(self, "wake_period"), self.run)
        self.get_logger().info(f"configured for '{machine.name}' ({'simulation' if self.simulation else 'real time'})"
                               f", plant {plant.name}, drives disabled")
        self.beyond_tolerance = outside_tolerance(machine, plant)
        if self.beyond_tolerance:
            self.get_logger().warning(f"plant {plant.name} lies outside the description's tolerance: "
                                      f"{'; '.join(self.beyond_tolerance)}")
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Drives on: setpoints are accepted."""
        self.loop.enable()
        self.get_logger().info("active: drives enabled")
        self.publish_diagnostics()
        return SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Drives off: a jerk-limited stop, setpoints refused; the planner hears why."""
        self.loop.disable(self.t_ns)
        self.get_logger().warning(DEACTIVATED)
        self.publish_diagnostics(event=DEACTIVATED)
        return SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.get_logger().error(f"error in transition from '{state.label}': drive model released")
        self.release()
        return SUCCESS

    def release(self) -> None:
        """Drop the drive model, its timer, topics and subscriptions (back to unconfigured)."""
        if self.loop is None:
            return
        self.destroy_timer(self.timer)
        for subscription in self.inputs:
            self.destroy_subscription(subscription)
        for publisher in (self.state_pub, self.diag_pub, self.clock_pub):
            if publisher is not None:
                self.destroy_publisher(publisher)
        self.loop = None

    # -- parameters ------------------------------------------------------------------------

    def on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Parameters read at configure may change only while unconfigured (ranges and
        read-only are rclpy's own checks, from the descriptors)."""
        late = [p.name for p in parameters if p.name in AT_CONFIGURE]
        if late and self.loop is not None:
            return SetParametersResult(successful=False, reason=f"{', '.join(late)}: read at configure; "
                                                                "deactivate and cleanup the bridge first")
        return SetParametersResult(successful=True)

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == "underrun_timeout" and self.loop is not None:
                self.lockstep.underrun_timeout_s = parameter.value

    # -- topics ----------------------------------------------------------------------------

    def on_trajectory(self, data: bytes) -> None:
        try:
            chunk = trajectory_bytes.decode(data, self.joints)
            self.loop.accept(chunk.joints, chunk.times_ns, chunk.positions, chunk.velocities, chunk.accelerations,
                             self.t_ns)
        except (SetpointError, ValueError) as err:
            self.rejected = f"refused setpoints: {err}"
            self.get_logger().error(self.rejected)
            self.publish_diagnostics()

    def on_recorded(self, msg: Time) -> None:
        self.lockstep.recorded(msg.sec * NS + msg.nanosec, time.monotonic())

    def on_inject(self, msg: String) -> None:
        try:
            fault = json.loads(msg.data)
            self.loop.inject(str(fault["joint"]), float(fault["offset"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
            self.get_logger().error(f"inject_fault: expected {{\"joint\": name, \"offset\": number}} ({err})")

    def on_reset(self, msg: String) -> None:
        if self.loop.alarm and self.loop.reset_alarm():
            self.get_logger().info(f"alarm reset by {msg.data or 'request'}")
            self.publish_diagnostics()

    def run(self) -> None:
        """Step the servo loop as far as time (sim: setpoints; real time: the wall) allows."""
        if self.simulation:
            budget, singles = self.max_steps, SINGLE_STEPS_PER_CALLBACK
            while budget > 0 and singles > 0 and self.lockstep.may_step(self.loop, self.t_ns, time.monotonic()):
                taken = self._steps(budget)
                budget -= taken
                singles -= taken == 1
        else:
            now = self.get_clock().now().nanoseconds
            while (due := self.pacing.steps_due(self.loop, self.t_ns, now)) > 0:
                self._steps(due)

    def _steps(self, count: int) -> int:
        """Take up to ``count`` servo steps (a block where the loop can) and publish every
        sample they produced; returns how many were taken."""
        taken = self.loop.run(self.t_ns, count, hold_in_blocks=not self.simulation)
        for i, feedback in enumerate(taken, start=1 - len(taken)):
            if self.clock_pub is not None and self.steps % self.clock_every == 0:
                self.clock_pub.publish(self.clock_msg.fill(feedback.stamp_ns))
            if self.steps % self.publish_every == 0:
                self.publish_feedback(feedback)
            # An alarm can only come from a block's last step (i == 0).
            if self.steps % 100 == 0 or (i == 0 and self.loop.alarm != self.reported_alarm):
                self.publish_diagnostics()
            self.steps += 1
            self.t_ns += self.period_ns
        return len(taken)

    def on_listener(self, info: QoSPublisherMatchedInfo) -> None:
        if info.current_count_change > 0 and self.loop is not None:  # not an event queued before release
            self.publish_diagnostics()

    def publish_feedback(self, feedback: Feedback) -> None:
        self.state_pub.publish(self.state_msg.fill(feedback.stamp_ns, feedback.positions, feedback.velocities))

    def publish_diagnostics(self, event: str = "") -> None:
        """The drives' state; ``event``: an error to report once (a deactivation)."""
        alarm = self.loop.alarm or self.rejected or event
        enabled = self.loop.enabled
        status = DiagnosticStatus(
            # Refused setpoints are an error too: the trajectory they belonged to cannot run.
            # Drives disabled without an error is a warning: the bridge works, but will not move.
            level=DiagnosticStatus.ERROR if alarm else DiagnosticStatus.OK if enabled else DiagnosticStatus.WARN,
            name="cnc_servo_bridge: drives", hardware_id=self.get_namespace(),
            message=alarm or ("ok" if enabled else DRIVES_DISABLED),
            values=[KeyValue(key=topics.PID_KEY, value=str(os.getpid())),
                    KeyValue(key=topics.DRIVES_KEY, value=topics.DRIVES_ON if enabled else topics.DRIVES_OFF),
                    KeyValue(key="buffer_s", value=f"{self.loop.buffer.level_s(self.t_ns):.3f}"),
                    KeyValue(key=topics.PLANT_KEY, value=self.loop.plant.name),
                    KeyValue(key=topics.PLANT_OUTSIDE_KEY, value="; ".join(self.beyond_tolerance))]
            + [KeyValue(key=f"max_following_error.{j}", value=f"{e:.9f}")
               for j, e in zip(self.joints, self.loop.max_following_error)],
        )
        if self.loop.alarm and self.loop.alarm != self.reported_alarm:
            self.get_logger().error(f"alarm: {self.loop.alarm}")
        self.reported_alarm = self.loop.alarm
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = stamp(self.t_ns)
        self.diag_pub.publish(msg)
        self.rejected = ""


if __name__ == "__main__":  # python -m cnc_servo_bridge.bridge_node (cnc-run, the tests): the class is here
    sys.exit(main(make=BridgeNode))
