"""joint_states and joint_trajectory read as arrays all at once give what rosbags gives
message by message, and messages that are not alike are read one by one."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_analysis.cdr_arrays import JOINT_STATE, JOINT_TRAJECTORY, joint_states, read_alike, trajectory_chunks
from cnc_analysis.recording import RECORDED, TYPESTORE, BagWriter, read_run

T = TYPESTORE.types
STATE, TRAJECTORY = RECORDED["joint_states"], RECORDED["joint_trajectory"]
RNG = np.random.default_rng(43)


def _stamp(ns: int):
    return T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _state(ns: int, names: list[str]) -> bytes:
    msg = T["sensor_msgs/msg/JointState"](header=T["std_msgs/msg/Header"](stamp=_stamp(ns), frame_id=""), name=names,
                                          position=RNG.normal(size=len(names)), velocity=RNG.normal(size=len(names)),
                                          effort=np.zeros(0))
    return bytes(TYPESTORE.serialize_cdr(msg, STATE))


def _chunk(ns: int, names: list[str], points: int, accelerations: bool = True) -> bytes:
    n = len(names)
    msg = T["trajectory_msgs/msg/JointTrajectory"](
        header=T["std_msgs/msg/Header"](stamp=_stamp(ns), frame_id=""), joint_names=names,
        points=[T["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=RNG.normal(size=n), velocities=RNG.normal(size=n),
            accelerations=RNG.normal(size=n) if accelerations else np.zeros(0), effort=np.zeros(0),
            time_from_start=T["builtin_interfaces/msg/Duration"](sec=i // 1000, nanosec=(i % 1000) * 10**6))
            for i in range(points)])
    return bytes(TYPESTORE.serialize_cdr(msg, TRAJECTORY))


def _one_by_one_states(messages: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    msgs = [TYPESTORE.deserialize_cdr(m, STATE) for m in messages]
    return (np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs]),
            np.array([m.position for m in msgs]), np.array([m.velocity for m in msgs]))


def _states(messages: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    runs = joint_states(messages, lambda raw: TYPESTORE.deserialize_cdr(raw, STATE))
    return tuple(np.concatenate([r[k] for r in runs]) for k in (1, 2, 3))


def test_alike_joint_states_are_cut_into_arrays_as_rosbags_reads_them():
    messages = [_state(10**9 + 7 * 10**5 * i + i % 3, ["x", "y", "z", "spindle"]) for i in range(500)]
    assert read_alike(messages, JOINT_STATE) is not None
    for ours, theirs in zip(_states(messages), _one_by_one_states(messages)):
        assert np.array_equal(ours, theirs)


def test_padding_is_not_compared_but_names_are():
    messages = [_state(10**9 + i, ["x", "y"]) for i in range(4)]
    stale = bytearray(messages[2])
    stale[18] = 0xAB  # padding after the empty frame_id: rclpy may leave stale bytes there
    messages[2] = bytes(stale)
    assert read_alike(messages, JOINT_STATE) is not None
    renamed = messages + [_state(10**9 + 9, ["x", "w"])]  # the same length, another joint
    assert read_alike(renamed, JOINT_STATE) is None
    for ours, theirs in zip(_states(renamed), _one_by_one_states(renamed)):
        assert np.array_equal(ours, theirs)  # read one by one instead


def test_chunks_of_every_length_and_without_accelerations_are_read_in_order():
    names = ["x", "z", "spindle"]
    messages = [_chunk(10**9 * (1 + i), names, points) for i, points in enumerate((100, 100, 7, 100))]
    messages.append(_chunk(10**9 * 9, names, 7, accelerations=False))
    assert read_alike(messages[:2], JOINT_TRAJECTORY) is not None
    chunks = trajectory_chunks(messages, lambda raw: TYPESTORE.deserialize_cdr(raw, TRAJECTORY))
    for (got_names, times, pos, vel, acc), raw in zip(chunks, messages):
        m = TYPESTORE.deserialize_cdr(raw, TRAJECTORY)
        head = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
        assert got_names == names
        assert np.array_equal(times, [head + p.time_from_start.sec * 10**9 + p.time_from_start.nanosec
                                      for p in m.points])
        assert np.array_equal(pos, [p.positions for p in m.points])
        assert np.array_equal(vel, [p.velocities for p in m.points])
        assert np.array_equal(acc, [p.accelerations if len(p.accelerations) else np.zeros(3) for p in m.points])


def test_a_recording_reads_its_feedback_and_setpoints_in_its_joint_order(tmp_path):
    writer = BagWriter(tmp_path / "bag", {"/cnc/joint_states": STATE, "/cnc/joint_trajectory": TRAJECTORY,
                                          "/clock": RECORDED["/clock"]})
    states = [_state(10**9 + 10**6 * i, ["x", "z"]) for i in range(50)]
    chunk = _chunk(10**9, ["z", "x"], 20)  # the planner's joint order may differ from the feedback's
    for i, raw in enumerate(states):
        writer.write("/cnc/joint_states", 10**9 + i, raw)
    writer.write("/cnc/joint_trajectory", 10**9 + 60, chunk)
    writer.close()
    run = read_run(tmp_path / "bag")
    t, pos, vel = _one_by_one_states(states)
    assert run.joints == ("x", "z")
    assert np.array_equal(run.feedback_t, t / 1e9) and np.array_equal(run.feedback, pos)
    assert np.array_equal(run.feedback_velocity, vel)
    m = TYPESTORE.deserialize_cdr(chunk, TRAJECTORY)
    assert np.array_equal(run.command, [p.positions[::-1] for p in m.points])
    assert [(c.points, c.received_ns) for c in run.chunks] == [(20, 10**9 + 60)]


def test_a_recording_with_two_machines_feedback_is_refused_by_name(tmp_path):
    """A second bridge in the namespace (another run's lathe beside our mill) is named,
    not concatenated into one feedback of mismatched widths."""
    writer = BagWriter(tmp_path / "bag", {"/cnc/joint_states": STATE, "/clock": RECORDED["/clock"]})
    for i in range(4):
        names = ["x", "y", "z", "spindle"] if i % 2 else ["x", "z", "spindle"]
        writer.write("/cnc/joint_states", 10**9 + i, _state(10**9 + i, names))
    writer.close()
    with pytest.raises(ValueError, match=r"joint_states of two machines \(x, z, spindle and x, y, z, spindle\): "
                                         r"another bridge published there$"):
        read_run(tmp_path / "bag")


def _write(path, plugin) -> list[tuple[str, int, bytes]]:
    """A bag of interleaved topics, log times out of order and tied; what it holds."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    topics = {"/cnc/joint_states": STATE, "/cnc/job_events": RECORDED["job_events"], "/clock": RECORDED["/clock"]}
    writer = Writer(path, version=9, storage_plugin=getattr(StoragePlugin, plugin))
    writer.open()
    connections = {t: writer.add_connection(t, m, typestore=TYPESTORE) for t, m in topics.items()}
    event = T["std_msgs/msg/String"](data='{"name": "S1"}')
    written = []
    for i, log_time in enumerate([5, 3, 3, 9, 1, 7, 7, 2]):
        topic = ("/cnc/joint_states", "/cnc/job_events", "/clock")[i % 3]
        raw = (_state(log_time, ["x"]) if topic == "/cnc/joint_states" else
               bytes(TYPESTORE.serialize_cdr(event, RECORDED["job_events"])) if topic == "/cnc/job_events" else
               bytes(TYPESTORE.serialize_cdr(T["rosgraph_msgs/msg/Clock"](clock=_stamp(log_time)), RECORDED["/clock"])))
        writer.write(connections[topic], log_time, raw)
        written.append((topic, log_time, raw))
    writer.close()
    return written


def test_one_pass_over_the_mcap_gives_what_rosbags_gives_and_other_bags_go_to_rosbags(tmp_path, monkeypatch):
    from cnc_analysis import mcap_scan
    from cnc_analysis.mcap_scan import messages

    rosbags_reader = mcap_scan.AnyReader
    for plugin in ("MCAP", "SQLITE3"):  # the recorder's own format, scanned; another, read by rosbags
        def only_sqlite(paths, plugin=plugin):
            assert plugin == "SQLITE3", "the MCAP file was not scanned"
            return rosbags_reader(paths)
        monkeypatch.setattr(mcap_scan, "AnyReader", only_sqlite)
        written = _write(tmp_path / plugin, plugin)
        expected = sorted(((t, n, raw) for t, n, raw in written if t != "/clock"), key=lambda m: m[1])  # stable
        got = [(topic, log_time, bytes(raw)) for topic, _, log_time, raw in messages(tmp_path / plugin, {"clock"})]
        assert got == expected
        types = {topic: msgtype for topic, msgtype, _, _ in messages(tmp_path / plugin)}
        assert types == {"/cnc/joint_states": STATE, "/cnc/job_events": RECORDED["job_events"],
                         "/clock": RECORDED["/clock"]}
