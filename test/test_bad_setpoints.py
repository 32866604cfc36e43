"""Malformed setpoint chunks reaching the bridge are refused whole (issue 7, "Bad input").

A real bridge process (mill3, simulation mode) gets JointTrajectory chunks published
straight onto its joint_trajectory topic, each breaking one of joint_trajectory_controller's
rules: times that do not increase, a stamp in the past, an unknown or a missing joint, NaN
or infinity, a point outside the travel, a jump, a velocity or acceleration beyond the
limits, a start away from where the axes stand. Each must be answered by an ERROR on
/diagnostics naming the reason, and the joint_states feedback must not move at all. A
valid chunk at the end shows that the same bridge still executes good setpoints.
"""
from __future__ import annotations

import math
import signal
import subprocess
import time

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from cnc_msgs_py import qos, topics
from cnc_msgs_py.machine import load_machine
from cnc_planner.runner import local_dds_env, node_command

NS = 1_000_000_000
MACHINE = load_machine("mill3")
JOINTS = list(MACHINE.joint_names)  # x, y, z, spindle
N = 50  # points per chunk, 1 ms apart
PERIOD = 1_000_000
LEAD_NS = 1_000_000_000  # chunks start this far ahead of the bridge's time (a chunk starting in
# the past is refused for that first), read from the newest joint_states: the probe's 1 kHz record
# was read up to 0.96 s late beside two busy processes, while the idle bridge keeps pace with the wall


def _chunk(start_ns: int, names=None, p=None, v=None, a=None, offsets=None, home=None) -> JointTrajectory:
    """A chunk holding every joint at rest where the axes stand (``home``), unless told
    otherwise; ``p`` is added to that position."""
    names = JOINTS if names is None else names
    zero = np.zeros((N, len(names)))
    p, v, a = (zero if x is None else np.asarray(x, float) for x in (p, v, a))
    if home is not None:
        p = p + np.array([home[JOINTS.index(n)] if n in JOINTS else 0.0 for n in names])
    offsets = np.arange(N) * PERIOD if offsets is None else offsets
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp = Time(sec=int(start_ns // NS), nanosec=int(start_ns % NS))
    for i, dt in enumerate(offsets):
        msg.points.append(JointTrajectoryPoint(
            positions=p[i].tolist(), velocities=v[i].tolist(), accelerations=a[i].tolist(),
            time_from_start=Duration(sec=int(dt // NS), nanosec=int(dt % NS))))
    return msg


def with_value(column: str, row: int, value: float, which: str = "p") -> dict:
    arr = np.zeros((N, len(JOINTS)))
    arr[row, JOINTS.index(column)] = value
    return {which: arr}


def malformed(now_ns: int, home: np.ndarray) -> list[tuple[str, JointTrajectory, tuple[str, ...]]]:
    """(what is wrong, the chunk, words the diagnostic must hold)."""
    start = now_ns + LEAD_NS

    def chunk(*args, **kwargs) -> JointTrajectory:
        return _chunk(*args, home=home, **kwargs)

    flat = np.arange(N) * PERIOD
    repeated = flat.copy()
    repeated[10:] -= PERIOD  # point 10 at the same time as point 9
    backwards = flat[::-1].copy()
    ramp = np.zeros((N, len(JOINTS)))
    ramp[:, 0] = np.linspace(0.0, 0.1, N)  # 100 mm in 49 ms: 2 mm per 1 ms step, x reaches 0.84 mm
    outside = np.zeros((N, len(JOINTS)))
    outside[:, 0] = 0.6 - home[0]  # x travel ends at 0.5 m
    shifted = np.zeros((N, len(JOINTS)))
    shifted[:, 0] = 0.005  # this starts 5 mm away from where the axes stand
    fast = np.zeros((N, len(JOINTS)))
    fast[5:, 2] = 2.0  # z at 2 m/s, its limit is 0.6 m/s
    harsh = np.zeros((N, len(JOINTS)))
    harsh[5:, 1] = 50.0  # y at 50 m/s^2, its limit is 9.8 m/s^2
    return [
        ("repeated time", chunk(start, offsets=repeated), ("strictly increase",)),
        ("times running backwards", chunk(start, offsets=backwards), ("strictly increase",)),
        ("stamp in the past", chunk(now_ns - 500_000_000), ("in the past",)),
        ("unknown joint", chunk(start, names=JOINTS + ["w"]), ("unknown joint 'w'",)),
        ("joint named twice", chunk(start, names=["x", "x", "z", "spindle"]), ("every joint once",)),
        ("missing joint", chunk(start, names=["x", "y", "z"]), ("every joint once", "spindle")),
        ("NaN position", chunk(start, **with_value("y", 20, math.nan)), ("NaN",)),
        ("infinite velocity", chunk(start, **with_value("z", 3, math.inf, "v")), ("NaN or infinite",)),
        ("NaN acceleration", chunk(start, **with_value("spindle", 49, math.nan, "a")), ("NaN",)),
        ("point outside the travel", chunk(start, p=outside), ("x setpoint", "outside its travel")),
        ("jump beyond the axis limits", chunk(start, p=ramp), ("x jumps",)),
        ("velocity beyond the limit", chunk(start, v=fast), ("z velocity", "beyond its limit")),
        ("acceleration beyond the limit", chunk(start, a=harsh), ("y acceleration", "beyond its limit")),
        ("start away from the axes", chunk(start, p=shifted), ("must start at rest",)),
        ("no points", chunk(start, offsets=np.arange(0)), ("refused setpoints",)),
        ("a point short of a joint", ragged(chunk(start)), ("refused setpoints",)),
    ]


def fatal(now_ns: int, home: np.ndarray) -> list[tuple[str, JointTrajectory, tuple[str, ...]]]:
    """Chunks that today kill the bridge (IndexError out of SetpointBuffer.validate)."""
    start = now_ns + LEAD_NS
    return [
        ("positions only, no velocities", positions_only(_chunk(start, home=home)), ("refused setpoints",)),
        ("every point one value short", short(_chunk(start, home=home)), ("refused setpoints",)),
    ]


def ragged(msg: JointTrajectory) -> JointTrajectory:
    msg.points[7].positions = msg.points[7].positions[:3]
    return msg


def positions_only(msg: JointTrajectory) -> JointTrajectory:
    """Legal for joint_trajectory_controller; this bridge needs all three, so: refused."""
    for point in msg.points:
        point.velocities, point.accelerations = [], []
    return msg


def short(msg: JointTrajectory) -> JointTrajectory:
    for point in msg.points:
        point.positions, point.velocities, point.accelerations = (
            point.positions[:3], point.velocities[:3], point.accelerations[:3])
    return msg


def valid(now_ns: int, home: np.ndarray) -> tuple[JointTrajectory, int]:
    """1 mm out and back on x in 0.4 s (smooth, within every limit), from rest to rest."""
    n, amplitude, period_s = 401, 0.001, 0.4
    t = np.arange(n) * PERIOD / NS
    w = 2 * math.pi / period_s
    p, v, a = (np.zeros((n, len(JOINTS))) for _ in range(3))
    p[:] = home
    p[:, 0] += amplitude * (1 - np.cos(w * t)) / 2
    v[:, 0] = amplitude * w * np.sin(w * t) / 2
    a[:, 0] = amplitude * w**2 * np.cos(w * t) / 2
    msg = JointTrajectory(joint_names=JOINTS)
    start = now_ns + LEAD_NS
    msg.header.stamp = Time(sec=int(start // NS), nanosec=int(start % NS))
    for i in range(n):
        dt = i * PERIOD
        msg.points.append(JointTrajectoryPoint(positions=p[i].tolist(), velocities=v[i].tolist(),
                                               accelerations=a[i].tolist(),
                                               time_from_start=Duration(sec=dt // NS, nanosec=dt % NS)))
    return msg, start


class Probe(Node):
    def __init__(self, context) -> None:
        super().__init__("bad_setpoints_probe", namespace="/cnc", context=context)
        self.pub = self.create_publisher(JointTrajectory, topics.JOINT_TRAJECTORY, qos.JOINT_TRAJECTORY)
        self.feedback: list[tuple[int, list[float]]] = []
        self.errors: list[tuple[int, str]] = []  # (index of the feedback when it came, message)
        self.create_subscription(JointState, topics.JOINT_STATES, self.on_state, qos.JOINT_STATES)
        self.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, self.on_diag, qos.DIAGNOSTICS)
        # the bridge's time: the newest sample only (depth 1), never queued behind the record
        self.clock_ns = 0
        self.create_subscription(JointState, topics.JOINT_STATES, self.on_clock, qos.LATEST)

    def on_state(self, msg: JointState) -> None:
        assert list(msg.name) == JOINTS
        self.feedback.append((msg.header.stamp.sec * NS + msg.header.stamp.nanosec, list(msg.position)))

    def on_clock(self, msg: JointState) -> None:
        self.clock_ns = max(self.clock_ns, msg.header.stamp.sec * NS + msg.header.stamp.nanosec)

    def on_diag(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.level >= DiagnosticStatus.ERROR and status.name.startswith("cnc_servo_bridge"):
                self.errors.append((len(self.feedback), status.message))

    @property
    def now_ns(self) -> int:
        """The stamp of the latest sample in the record."""
        return self.feedback[-1][0] if self.feedback else 0


@pytest.fixture
def bridge():
    env = local_dds_env()
    proc = subprocess.Popen(node_command("cnc_servo_bridge.bridge_node", "/cnc",
                                         {"machine": "mill3", "simulation": True}), env=env)
    context = rclpy.Context()
    rclpy.init(context=context)
    probe = Probe(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(probe)

    def spin_until(done, timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            assert proc.poll() is None, f"the bridge exited with code {proc.returncode}"
            assert time.monotonic() < deadline, what
            executor.spin_once(timeout_sec=0.02)

    try:
        spin_until(lambda: probe.pub.get_subscription_count() > 0 and min(probe.now_ns, probe.clock_ns) > NS, 30,
                   "the bridge did not come up")
        yield probe, spin_until, proc
    finally:
        executor.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def refuse_all(probe, spin_until, cases) -> int:
    """Publish each case (stamped from the bridge's time) and check its ERROR diagnostic;
    returns the time by which the last one would have ended had it run."""
    start = np.array(probe.feedback[-1][1])
    last_end = 0
    for k in range(len(cases(0, start))):
        what, msg, words = cases(probe.clock_ns, start)[k]
        last_end = probe.clock_ns + LEAD_NS + N * PERIOD
        seen = len(probe.errors)
        probe.pub.publish(msg)
        spin_until(lambda: len(probe.errors) > seen, 10, f"no ERROR diagnostic for {what}")
        message = probe.errors[seen][1]
        assert message.startswith("refused setpoints: "), (what, message)
        assert all(w in message for w in words), (what, message)
        # The feedback keeps running and keeps standing exactly where it stood.
        mark = len(probe.feedback)
        spin_until(lambda: len(probe.feedback) > mark + 50, 10, f"joint_states stopped after {what}")
    return last_end


def test_malformed_chunks_are_refused_and_never_move_the_axes(bridge):
    probe, spin_until, proc = bridge
    start = np.array(probe.feedback[-1][1])
    assert np.all(np.array([p for _, p in probe.feedback]) == start)  # standing still before
    last_end = refuse_all(probe, spin_until, malformed)
    # Until past the end of where the last chunk would have run.
    spin_until(lambda: probe.now_ns > last_end + 100_000_000, 10, "sim time stalled")
    positions = np.array([p for _, p in probe.feedback])
    assert np.all(positions == start), f"the axes moved: max {np.abs(positions - start).max(axis=0)}"
    assert len(probe.feedback) > 500 and proc.poll() is None

    # The same bridge still executes a good chunk: the feedback goes out 1 mm and back.
    msg, t0 = valid(probe.clock_ns, start)
    errors = len(probe.errors)
    probe.pub.publish(msg)
    spin_until(lambda: probe.now_ns > t0 + 600_000_000, 20, "the valid chunk did not run")
    assert len(probe.errors) == errors, probe.errors[errors:]
    x = np.array([p[0] for t, p in probe.feedback if t >= t0]) - start[0]
    assert x.max() == pytest.approx(0.001, abs=5e-5)
    assert abs(x[-1]) < 1e-6


def test_chunks_with_missing_values_are_refused_not_fatal(bridge):
    probe, spin_until, proc = bridge
    start = np.array(probe.feedback[-1][1])
    refuse_all(probe, spin_until, fatal)
    assert proc.poll() is None
    assert np.all(np.array([p for _, p in probe.feedback]) == start)
