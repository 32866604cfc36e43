"""joint_states and joint_trajectory messages of a recording read as arrays, all at once.

rosbags deserializes a message into Python objects: 10.9 of the 14.9 s that reading a
300-hole plate's bag took (196,000 joint_states at 1 kHz, 1,938 chunks of 100 points). A
recording's messages of one topic are alike, though: the same joint names and sequence
lengths, so the same bytes in the same places, with only the stamps and values differing.
Here the first message of each byte length is walked once (CDR, as rosbags and rclpy
write it), the messages of that length are stacked into one byte array, and every stamp
and value column is cut out with numpy.

A group is read this way only if every message's structural bytes (sequence lengths,
string lengths and characters) equal the walked one's and the walk's values of its first
and last message equal rosbags' own deserialization; otherwise None, and the caller
deserializes that group message by message as before. Padding is not compared: rclpy may
leave stale bytes there.
"""
from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cnc_analysis.mcap_scan import Messages

HEADER = 4  # the encapsulation header; CDR aligns relative to the bytes after it
LITTLE_ENDIAN = (b"\x00\x01", b"\x00\x03")  # CDR_LE, PL_CDR_LE

# The fields read, in CDR order: ("time", name), ("string", name), ("strings", name),
# ("doubles", name), or ("sequence", name, fields) for a sequence of structures.
HEADER_FIELDS = (("time", "stamp"), ("string", "frame_id"))
JOINT_STATE = (*HEADER_FIELDS, ("strings", "name"), ("doubles", "position"), ("doubles", "velocity"),
               ("doubles", "effort"))
TRAJECTORY_POINT = (("doubles", "positions"), ("doubles", "velocities"), ("doubles", "accelerations"),
                    ("doubles", "effort"), ("time", "time_from_start"))
JOINT_TRAJECTORY = (*HEADER_FIELDS, ("strings", "joint_names"), ("sequence", "points", TRAJECTORY_POINT))


@dataclass
class Layout:
    """Where one message's values sit: ``times`` and ``doubles`` map a field's path
    (e.g. "points.positions") to the offset of each occurrence (one per point in a
    sequence); ``counts`` gives each doubles field's length; ``fixed`` marks every
    structural byte."""

    size: int
    times: dict[str, list[int]] = field(default_factory=dict)
    doubles: dict[str, list[int]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    fixed: list[tuple[int, int]] = field(default_factory=list)  # (offset, length)


def _align(offset: int, size: int) -> int:
    return offset + (-(offset - HEADER)) % size


def _walk(data: bytes, offset: int, fields: tuple, layout: Layout, prefix: str) -> int:
    """Record where ``fields`` sit from ``offset``; the offset past them.

    Raises:
        ValueError: the bytes do not hold these fields (too short, or a doubles field
            whose length differs from an earlier occurrence's).
    """
    def count(at: int) -> tuple[int, int]:
        at = _align(at, 4)
        layout.fixed.append((at, 4))
        return struct.unpack_from("<I", data, at)[0], at + 4

    for kind, name, *inner in fields:
        path = prefix + name
        if kind == "time":
            offset = _align(offset, 4)
            layout.times.setdefault(path, []).append(offset)
            offset += 8
        elif kind in ("string", "strings"):
            strings, offset = (1, offset) if kind == "string" else count(offset)
            for _ in range(strings):
                length, offset = count(offset)
                layout.fixed.append((offset, length))
                offset += length
        elif kind == "doubles":
            n, offset = count(offset)
            if layout.counts.setdefault(path, n) != n:
                raise ValueError(f"{path}: sequences of {n} and {layout.counts[path]} in one message")
            if n:
                offset = _align(offset, 8)
            layout.doubles.setdefault(path, []).append(offset)
            offset += 8 * n
        else:  # a sequence of structures
            n, offset = count(offset)
            for _ in range(n):
                offset = _walk(data, offset, inner[0], layout, path + ".")
        if offset > len(data):
            raise ValueError("message shorter than its fields")
    return offset


def layout_of(data: bytes, fields: tuple) -> Layout:
    """The layout of one message (``fields``: JOINT_STATE or JOINT_TRAJECTORY).

    Raises:
        ValueError: not a little-endian CDR message of those fields.
    """
    if data[:2] not in LITTLE_ENDIAN:
        raise ValueError("not little-endian CDR")
    layout = Layout(len(data))
    end = _walk(data, HEADER, fields, layout, "")
    if len(data) - end >= 8:  # rclpy and rosbags pad the end to 4 bytes at most
        raise ValueError("bytes left after the message's fields")
    return layout


@dataclass(frozen=True)
class Columns:
    """A group of alike messages as arrays: each time field in ns (messages x occurrences)
    and each doubles field as (messages x occurrences x count)."""

    times_ns: dict[str, np.ndarray]
    doubles: dict[str, np.ndarray]


def read_alike(messages: Messages | list[bytes], fields: tuple) -> Columns | None:
    """Messages of one byte length as arrays; None if they are not alike (see the module)."""
    messages = Messages.of(messages)
    try:
        layout = layout_of(messages[0], fields)
    except (ValueError, struct.error):
        return None
    raw = messages.stack()
    fixed = np.concatenate([np.arange(at, at + n) for at, n in layout.fixed]) if layout.fixed else np.zeros(0, int)
    if not (raw[:, fixed] == raw[0, fixed]).all():
        return None

    def cut(offsets: list[int], width: int, dtype: str) -> np.ndarray:
        if width == 0:
            return np.zeros((len(messages), len(offsets), 0))
        at = np.asarray(offsets)[:, None] + np.arange(width)
        return np.ascontiguousarray(raw[:, at]).view(dtype).reshape(len(messages), len(offsets), -1)

    times = {}
    for path, offsets in layout.times.items():
        sec = cut(offsets, 4, "<i4")[..., 0].astype(np.int64)
        nsec = cut([o + 4 for o in offsets], 4, "<u4")[..., 0].astype(np.int64)
        times[path] = sec * 1_000_000_000 + nsec
    doubles = {path: cut(offsets, 8 * layout.counts[path], "<f8") for path, offsets in layout.doubles.items()}
    return Columns(times, doubles)


Deserialize = Callable[[bytes], Any]  # rosbags' deserialization of one message of the topic's type
Feedback = tuple[list[str], np.ndarray, np.ndarray, np.ndarray]  # joint names, stamps (ns), positions, velocities
Setpoints = tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # names, times (ns), pos, vel, acc


def _ns(stamp: Any) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _by_size(messages: Messages) -> list[np.ndarray]:
    """Indices of the messages of each byte length, in order of first appearance."""
    lengths = messages.lengths
    if len(lengths) == 0 or (lengths == lengths[0]).all():  # a recording's feedback: one length
        return [np.arange(len(lengths))] if len(lengths) else []
    sizes, first, which = np.unique(lengths, return_index=True, return_inverse=True)
    order = np.argsort(which, kind="stable")  # the messages grouped by size, each group in order
    groups = np.split(order, np.cumsum(np.bincount(which, minlength=len(sizes)))[:-1])
    return [groups[k] for k in np.argsort(first)]


def joint_states(messages: Messages | list[bytes], deserialize: Deserialize) -> list[Feedback]:
    """JointState messages in order as runs of alike ones (joint names, stamps in ns,
    positions, velocities); the joint names of the first run are the recording's."""
    messages = Messages.of(messages)
    out: list[tuple[int, Feedback]] = []
    for group in _by_size(messages):
        alike = read_alike(messages.take(group), JOINT_STATE)
        first, last = deserialize(messages[group[0]]), deserialize(messages[group[-1]])
        if alike is not None and all(
                alike.times_ns["stamp"][k, 0] == _ns(m.header.stamp)
                and np.array_equal(alike.doubles["position"][k, 0], m.position)
                and np.array_equal(alike.doubles["velocity"][k, 0], m.velocity) for k, m in ((0, first), (-1, last))):
            out.append((int(group[0]), (list(first.name), alike.times_ns["stamp"][:, 0],
                                   alike.doubles["position"][:, 0], alike.doubles["velocity"][:, 0])))
            continue
        for i in group.tolist():  # not alike: one by one, as rosbags reads them
            m = deserialize(messages[i])
            out.append((i, (list(m.name), np.array([_ns(m.header.stamp)]), np.asarray(m.position)[None],
                            np.asarray(m.velocity)[None])))
    return [runs for _, runs in sorted(out, key=lambda item: item[0])]


def _chunk(m: Any) -> Setpoints:
    """One JointTrajectory deserialized by rosbags, as arrays (points without accelerations: 0)."""
    head = _ns(m.header.stamp)
    times = np.array([head + _ns(p.time_from_start) for p in m.points], dtype=np.int64)
    pos = np.array([p.positions for p in m.points])
    vel = np.array([p.velocities for p in m.points])
    acc = np.array([p.accelerations if len(p.accelerations) else np.zeros(len(p.positions)) for p in m.points])
    return list(m.joint_names), times, pos, vel, acc


def trajectory_chunks(messages: Messages | list[bytes], deserialize: Deserialize) -> list[Setpoints]:
    """Every JointTrajectory message as arrays, in order."""
    messages = Messages.of(messages)
    out: dict[int, Setpoints] = {}
    for group in _by_size(messages):
        alike = read_alike(messages.take(group), JOINT_TRAJECTORY)
        ends = [_chunk(deserialize(messages[group[k]])) for k in (0, -1)]
        if alike is not None:
            heads = alike.times_ns["stamp"][:, :1]
            times = heads + alike.times_ns["points.time_from_start"]
            pos, vel = alike.doubles["points.positions"], alike.doubles["points.velocities"]
            acc = alike.doubles["points.accelerations"]
            if acc.shape[-1] == 0:
                acc = np.zeros_like(pos)
            if all(all(np.array_equal(a, b) for a, b in zip(end[1:], (times[k], pos[k], vel[k], acc[k])))
                   for k, end in zip((0, -1), ends)):
                names = ends[0][0]
                out.update((i, (names, times[k], pos[k], vel[k], acc[k])) for k, i in enumerate(group.tolist()))
                continue
        out.update((i, _chunk(deserialize(messages[i]))) for i in group.tolist())
    return [out[i] for i in range(len(messages))]
