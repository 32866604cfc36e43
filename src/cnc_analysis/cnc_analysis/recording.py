"""Runs recorded as rosbag2 (MCAP, standard message types) and read back as arrays.

Writing takes the serialized CDR bytes exactly as they came off the wire; reading
rebuilds the commanded setpoints the bridge executed (later chunks replace buffered
points from their first stamp on, as the bridge does) and the feedback it published.
Each topic is read once; joint_states and joint_trajectory, nearly every byte of a
recording, are cut into arrays all at once (cdr_arrays.py), /clock is not read.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from cnc_msgs_py.topics import PLANT_KEY
from cnc_msgs_py.units import NS

from cnc_analysis.cdr_arrays import joint_states, trajectory_chunks
from cnc_analysis.mcap_scan import last_part, scan

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STAMPED = 12  # bytes of a stamped message up to the end of its header's stamp (CDR encapsulation, sec, nanosec)

# Topic (relative to the run's namespace, or absolute) -> message type.
RECORDED = {
    "job_goal": "std_msgs/msg/String",
    "job_cancel": "std_msgs/msg/String",
    "job_status": "std_msgs/msg/String",
    "job_events": "std_msgs/msg/String",
    "joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
    "joint_states": "sensor_msgs/msg/JointState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/clock": "rosgraph_msgs/msg/Clock",
}


class BagWriter:
    """Writes serialized messages of the recorded topics to an MCAP rosbag2."""

    def __init__(self, path: Path, topics: dict[str, str]) -> None:
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections = {t: self.writer.add_connection(t, m, typestore=TYPESTORE) for t, m in topics.items()}
        self.count = 0

    def write(self, topic: str, t_ns: int, data: bytes) -> None:
        self.writer.write(self.connections[topic], t_ns, data)
        self.count += 1

    def close(self) -> None:
        self.writer.close()


@dataclass
class Chunk:
    stamp_ns: int
    end_ns: int
    points: int
    moving_at_end: bool
    received_ns: int = 0  # bag time: when the recorder had it, on the machine's clock


@dataclass
class Run:
    """A recorded run as arrays (SI units, times in s of ROS time)."""

    joints: tuple[str, ...] = ()
    feedback_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    feedback: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    feedback_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    command_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    command: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    command_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    command_acceleration: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    chunks: list[Chunk] = field(default_factory=list)
    goals: list[str] = field(default_factory=list)
    statuses: list[dict] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    alarms: list[str] = field(default_factory=list)
    plant: str | None = None  # the drives the bridge emulated, as its diagnostics named them last

    def column(self, joint: str) -> int:
        return self.joints.index(joint)

    def feedback_at(self, window: np.ndarray) -> dict[str, float]:
        """Each joint's feedback at the first sample of ``window`` (a mask of feedback samples)."""
        first = int(np.argmax(window))
        return {j: float(self.feedback[first, i]) for i, j in enumerate(self.joints)}


def read_run(bag: Path) -> Run:
    """Read a recorded run.

    Raises:
        FileNotFoundError: no bag at that path.
        ValueError: the bag cannot be read as a rosbag2.
    """
    bag = Path(bag)
    if not bag.exists():
        raise FileNotFoundError(f"no recording at {bag}")
    run = Run()
    try:
        found = scan(bag, skip={"clock"})
        bulk = {name: found.of_topic(name) for name in ("joint_states", "joint_trajectory")}  # read as arrays
        rest = np.ones(len(found.channel), bool)
        for indices in bulk.values():
            rest[indices] = False
        statuses: dict[bytes, tuple[list[str], str | None]] = {}  # a diagnostics message's alarms and plant by its bytes
        for k in np.flatnonzero(rest).tolist():
            topic, msgtype = found.channels[int(found.channel[k])]
            topic, raw = last_part(topic), found.messages[k]
            if topic == "diagnostics":  # the same few reports over and over, but for their stamp
                if (body := raw[STAMPED:]) not in statuses:
                    msg = TYPESTORE.deserialize_cdr(raw, msgtype)
                    statuses[body] = ([s.message for s in msg.status if s.level >= 2],
                                      next((v.value for s in msg.status for v in s.values if v.key == PLANT_KEY), None))
                alarms, plant = statuses[body]
                run.alarms += alarms
                run.plant = run.plant if plant is None else plant
                continue
            msg = TYPESTORE.deserialize_cdr(raw, msgtype)
            if topic == "job_goal":
                run.goals.append(msg.data)
            elif topic == "job_status":
                run.statuses.append(json.loads(msg.data))
            elif topic == "job_events":
                run.events.append(json.loads(msg.data))
        types = {name: found.channels[int(found.channel[k[0]])][1] for name, k in bulk.items() if len(k)}
        feedback = joint_states(found.messages.take(bulk["joint_states"]),
                                lambda raw: TYPESTORE.deserialize_cdr(raw, types["joint_states"]))
        chunks = trajectory_chunks(found.messages.take(bulk["joint_trajectory"]),
                                   lambda raw: TYPESTORE.deserialize_cdr(raw, types["joint_trajectory"]))
        received = found.log_time[bulk["joint_trajectory"]].astype(np.int64).tolist()  # the chunks' bag times
    except (OSError, KeyError, ValueError, AnyReaderError) as err:
        raise ValueError(f"cannot read recording {bag}: {err}") from err
    if firsts := sorted((int(k[0]), name) for name, k in bulk.items() if len(k)):
        # the joint names of whichever of the two came first are the run's
        run.joints = tuple(feedback[0][0] if firsts[0][1] == "joint_states" else chunks[0][0])
    if len(machines := list(dict.fromkeys(tuple(names) for names, _, _, _ in feedback))) > 1:
        raise ValueError(f"cannot read recording {bag}: joint_states of two machines ("
                         f"{' and '.join(', '.join(m) for m in machines[:2])}): another bridge published there")
    if feedback:
        run.feedback_t = np.concatenate([t for _, t, _, _ in feedback]) / NS
        run.feedback = np.concatenate([p for _, _, p, _ in feedback])
        run.feedback_velocity = np.concatenate([v for _, _, _, v in feedback])
    setpoints = []
    for (names, times, pos, vel, acc), received_ns in zip(chunks, received):
        order = [names.index(j) for j in run.joints]
        setpoints.append((times, pos[:, order], vel[:, order], acc[:, order]))
        run.chunks.append(Chunk(int(times[0]), int(times[-1]), len(times), bool(np.any(vel[-1] != 0.0)),
                                received_ns))
    if setpoints:
        times, pos, vel, acc = _executed(setpoints)
        run.command_t, run.command, run.command_velocity, run.command_acceleration = times / NS, pos, vel, acc
    return run


def _executed(chunks: list[tuple[np.ndarray, ...]]):
    """Join chunks (times, then per-point arrays: positions, velocities, accelerations) the
    way the bridge buffers them: a chunk replaces points from its stamp."""
    kept: list[tuple[np.ndarray, ...]] = []
    for chunk in chunks:
        times = chunk[0]
        while kept and kept[-1][0][0] >= times[0]:
            kept.pop()
        if kept and kept[-1][0][-1] >= times[0]:
            keep = int(np.searchsorted(kept[-1][0], times[0]))
            kept[-1] = tuple(x[:keep] for x in kept[-1])
        kept.append(chunk)
    return tuple(np.concatenate([k[i] for k in kept]) for i in range(len(chunks[0])))
