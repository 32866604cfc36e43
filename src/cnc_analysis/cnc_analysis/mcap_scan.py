"""The messages of a recording in one pass over its MCAP file.

rosbags' reader builds a BytesIO, a named tuple and a heap entry per message: 1.0 of the
1.1 s that reading a 300-hole plate's bag took once its messages were no longer
deserialized one by one (cdr_arrays.py). The recorder writes one MCAP file of
uncompressed chunks (BagWriter); such a file is scanned here record by record with
struct into arrays (channel, log time, where each message's bytes lie), so that the
200,000 messages of a 1 kHz topic are never a Python object each. Messages come ordered
as rosbags gives them: by log time, ties in file order. Any other recording (several
files, compressed chunks, SQLite) is read by rosbags' AnyReader into the same arrays.
"""
from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

MAGIC = b"\x89MCAP0\r\n"
SCHEMA, CHANNEL, MESSAGE, CHUNK, DATA_END = 0x03, 0x04, 0x05, 0x06, 0x0F
RECORD = struct.Struct("<BQ")  # opcode, content length
MESSAGE_RECORD = struct.Struct("<BQHIQ")  # opcode, content length, then channel id, sequence, log time
MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
CHUNK_HEAD = struct.Struct("<QQQII")  # start and end time, uncompressed size and crc, compression length
U16, U32, U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")

Message = tuple[str, str, int, bytes | memoryview]  # topic, message type, log time (ns), serialized data


def last_part(topic: str) -> str:
    """A topic's name without its namespace ("/cnc/joint_states" -> "joint_states")."""
    return topic.rsplit("/", 1)[-1]


@dataclass
class Messages:
    """Serialized messages as one byte buffer and where each lies in it: a list of bytes
    that numpy can cut all at once (``stack``)."""

    data: np.ndarray  # uint8
    offsets: np.ndarray  # int64, one per message
    lengths: np.ndarray  # int64

    @classmethod
    def of(cls, messages: "Messages | list[bytes]") -> "Messages":
        """``messages`` as Messages (as they are if they are)."""
        if isinstance(messages, Messages):
            return messages
        lengths = np.array([len(m) for m in messages], dtype=np.int64)
        offsets = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
        return cls(np.frombuffer(b"".join(messages), dtype=np.uint8), offsets, lengths)

    def __len__(self) -> int:
        return len(self.offsets)

    def __getitem__(self, k: int) -> bytes:
        return self.data[self.offsets[k]:self.offsets[k] + self.lengths[k]].tobytes()

    def take(self, indices: np.ndarray) -> "Messages":
        return Messages(self.data, self.offsets[indices], self.lengths[indices])

    def stack(self) -> np.ndarray:
        """The messages, all of one length, as rows of a (messages x length) byte array."""
        width = int(self.lengths[0]) if len(self) else 0
        if width == 0:
            return np.zeros((len(self), 0), dtype=np.uint8)
        return np.lib.stride_tricks.sliding_window_view(self.data, width)[self.offsets]  # one copy, row by row


@dataclass
class Scanned:
    """A recording's messages in log-time order: per message its channel and log time, and
    the bytes (``messages``); ``channels`` maps a channel to (topic, message type)."""

    channels: dict[int, tuple[str, str]]
    channel: np.ndarray  # int64
    log_time: np.ndarray  # uint64, ns
    messages: Messages

    def of_topic(self, name: str) -> np.ndarray:
        """Indices of the messages whose topic's last part is ``name``, in order."""
        of = np.zeros(len(self.channel), bool)
        for c, (topic, _) in self.channels.items():
            if last_part(topic) == name:
                of |= self.channel == c
        return np.flatnonzero(of)


def _string(data: memoryview, at: int) -> tuple[str, int]:
    (length,) = U32.unpack_from(data, at)
    return bytes(data[at + 4:at + 4 + length]).decode(), at + 4 + length


def _scan(data: memoryview, start: int, end: int, found: dict, skip: set[str]) -> bool:
    """Read the records from ``start`` to ``end`` into ``found`` (schemas, channels, and per
    message its channel, log time, and the offset and length of its bytes); False at
    anything this scan does not read (a compressed chunk)."""
    schemas, channels, skipped, heads = found["schemas"], found["channels"], found["skipped"], found["heads"]
    record, extend = MESSAGE_RECORD.unpack_from, heads.extend
    head, past_head = RECORD.size, RECORD.size + MESSAGE_HEAD.size
    at = start
    while at < end:
        op, length, channel, _, log_time = record(data, at)  # a message's fields; others' bytes unread
        if op == MESSAGE:
            if channel not in skipped:
                extend((channel, log_time, at + past_head, length - MESSAGE_HEAD.size))
            at += head + length
            continue
        body, at = at + head, at + head + length
        if op == CHUNK:
            *_, compression = CHUNK_HEAD.unpack_from(data, body)
            if compression:
                return False
            records = body + CHUNK_HEAD.size
            (size,) = U64.unpack_from(data, records)
            if not _scan(data, records + 8, records + 8 + size, found, skip):
                return False
        elif op == SCHEMA:
            (schema,) = U16.unpack_from(data, body)
            schemas[schema], _ = _string(data, body + 2)
        elif op == CHANNEL:
            channel, schema = struct.unpack_from("<HH", data, body)
            topic, _ = _string(data, body + 4)
            channels[channel] = (topic, schema)
            if last_part(topic) in skip:
                skipped.add(channel)
        elif op == DATA_END:
            return True
    return True


def scan(bag: Path, skip: set[str] = frozenset()) -> Scanned:
    """The messages of the recording at ``bag`` (a rosbag2 directory) but those of the
    topics named in ``skip`` (the last part of a name: "clock"), in log-time order.

    Raises:
        rosbags' errors, OSError: the recording cannot be read.
    """
    files = sorted(Path(bag).glob("*.mcap"))
    raw = files[0].read_bytes() if len(files) == 1 else b""
    found: dict = {"schemas": {}, "channels": {}, "skipped": set(), "heads": []}
    if raw[:8] == MAGIC and _scan(memoryview(raw), 8, len(raw), found, skip):
        channels = {c: (topic, found["schemas"].get(schema, "")) for c, (topic, schema) in found["channels"].items()
                    if c not in found["skipped"]}
        heads = np.array(found["heads"], dtype=np.uint64).reshape(-1, 4)
        order = np.argsort(heads[:, 1], kind="stable")
        heads = heads[order]
        messages = Messages(np.frombuffer(raw, dtype=np.uint8), heads[:, 2].astype(np.int64),
                            heads[:, 3].astype(np.int64))
        return Scanned(channels, heads[:, 0].astype(np.int64), heads[:, 1], messages)
    with AnyReader([Path(bag)]) as reader:
        wanted = [c for c in reader.connections if last_part(c.topic) not in skip]
        ids = {c.id: c for c in wanted}
        read = [(conn.id, log_time, raw) for conn, log_time, raw in reader.messages(connections=wanted)]
    return Scanned({i: (c.topic, c.msgtype) for i, c in ids.items()},
                   np.array([r[0] for r in read], dtype=np.int64), np.array([r[1] for r in read], dtype=np.uint64),
                   Messages.of([r[2] for r in read]))


def messages(bag: Path, skip: set[str] = frozenset()) -> Iterator[Message]:
    """Every message of the recording at ``bag`` as (topic, message type, log time, bytes),
    in log-time order (see ``scan``).

    Raises:
        rosbags' errors, OSError: the recording cannot be read.
    """
    found = scan(bag, skip)
    for k, (channel, log_time) in enumerate(zip(found.channel.tolist(), found.log_time.tolist())):
        topic, msgtype = found.channels[channel]
        yield topic, msgtype, log_time, found.messages[k]
