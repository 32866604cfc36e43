"""cnc_servo_bridge node: setpoint chunks in, emulated drives, joint_states out.

In simulation mode the bridge owns time: it publishes /clock in lockstep with its servo
steps, runs as fast as setpoints allow while axes move, waits for setpoints (up to
``underrun_timeout`` of wall time) rather than starving, and paces idle time to the wall
clock (lockstep.py). In real-time mode it steps on a wall timer and stamps with the system
clock.
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from cnc_msgs_py import qos, topics
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.node import run_node
from cnc_msgs_py.units import NS

from .lockstep import Lockstep
from .servo import Feedback, ServoLoop
from .setpoints import SetpointError


SINGLE_STEPS_PER_CALLBACK = 10  # steps outside a block (idle, stopping) per timer callback:
# idle sim time catches up with the wall clock at this pace after a late callback


def stamp(t_ns: int) -> Time:
    return Time(sec=t_ns // NS, nanosec=t_ns % NS)


class BridgeNode(Node):
    def __init__(self) -> None:
        super().__init__("cnc_servo_bridge")
        machine = load_machine(self.declare_parameter("machine", "mill3").value)
        self.period_ns = round(self.declare_parameter("servo_period", 0.001).value * NS)
        self.simulation = self.declare_parameter("simulation", True).value
        rate = self.declare_parameter("joint_state_rate", 1000.0).value
        self.publish_every = max(1, round(NS / rate / self.period_ns))
        clock_rate = self.declare_parameter("clock_rate", 100.0).value
        self.clock_every = max(1, round(NS / clock_rate / self.period_ns))
        # Bounded machine time per callback (0.1 s) so that setpoint chunks (a stop!) are
        # taken between batches; the loop steps them in blocks (ServoLoop.run).
        self.max_steps = self.declare_parameter("steps_per_callback", 100).value
        start = self.declare_parameter("start_position", list(machine.home_position)).value
        self.loop = ServoLoop(machine, self.period_ns, np.asarray(start, dtype=float))
        self.joints = list(machine.joint_names)
        self.state_pub = self.create_publisher(JointState, topics.JOINT_STATES, qos.JOINT_STATES)
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS)
        self.clock_pub = self.create_publisher(Clock, topics.CLOCK, qos.CLOCK) if self.simulation else None
        self.create_subscription(JointTrajectory, topics.JOINT_TRAJECTORY, self.on_trajectory, qos.JOINT_TRAJECTORY)
        # Fault injection for tests and commissioning: {"joint": "x", "offset": 0.005} (m or rad).
        self.create_subscription(String, topics.INJECT_FAULT, self.on_inject, qos.INJECT_FAULT)
        self.create_subscription(String, topics.ALARM_RESET, self.on_reset, qos.ALARM_RESET)
        self.create_subscription(Time, topics.RECORDED_UNTIL, self.on_recorded, qos.RECORDED_UNTIL)
        self.reported_alarm = ""
        self.t_ns = 0 if self.simulation else self.get_clock().now().nanoseconds // self.period_ns * self.period_ns
        self.steps = 0
        self.rejected = ""
        self.lockstep = Lockstep(self.period_ns, self.declare_parameter("underrun_timeout", 1.0).value,
                                 self.t_ns, time.monotonic())
        self.create_timer(0.001, self.run)
        self.get_logger().info(f"driving '{machine.name}' ({'simulation' if self.simulation else 'real time'})")

    def on_trajectory(self, msg: JointTrajectory) -> None:
        head = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        times = np.array([head + p.time_from_start.sec * NS + p.time_from_start.nanosec for p in msg.points], dtype=np.int64)
        try:
            p, v, a = (np.array([getattr(pt, k) for pt in msg.points], dtype=float)
                       for k in ("positions", "velocities", "accelerations"))
            self.loop.accept(list(msg.joint_names), times, p, v, a, self.t_ns)
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
            while self.t_ns + self.period_ns <= now:
                self._steps((now - self.t_ns) // self.period_ns)

    def _steps(self, count: int) -> int:
        """Take up to ``count`` servo steps (a block where the loop can) and publish every
        sample they produced; returns how many were taken."""
        taken = self.loop.run(self.t_ns, count)
        for i, feedback in enumerate(taken, start=1 - len(taken)):
            if self.clock_pub is not None and self.steps % self.clock_every == 0:
                self.clock_pub.publish(Clock(clock=stamp(feedback.stamp_ns)))
            if self.steps % self.publish_every == 0:
                self.publish_feedback(feedback)
            # An alarm can only come from a block's last step (i == 0).
            if self.steps % 100 == 0 or (i == 0 and self.loop.alarm != self.reported_alarm):
                self.publish_diagnostics()
            self.steps += 1
            self.t_ns += self.period_ns
        return len(taken)

    def publish_feedback(self, feedback: Feedback) -> None:
        msg = JointState(name=self.joints, position=feedback.positions.tolist(), velocity=feedback.velocities.tolist())
        msg.header.stamp = stamp(feedback.stamp_ns)
        self.state_pub.publish(msg)

    def publish_diagnostics(self) -> None:
        alarm = self.loop.alarm or self.rejected
        status = DiagnosticStatus(
            # Refused setpoints are an error too: the trajectory they belonged to cannot run.
            level=DiagnosticStatus.ERROR if alarm else DiagnosticStatus.OK,
            name="cnc_servo_bridge: drives", hardware_id=self.get_namespace(),
            message=alarm or "ok",
            values=[KeyValue(key="buffer_s", value=f"{self.loop.buffer.level_s(self.t_ns):.3f}")]
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


def main(args: list[str] | None = None) -> int:
    return run_node(BridgeNode, "cnc_servo_bridge", args)


if __name__ == "__main__":
    sys.exit(main())
