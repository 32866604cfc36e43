"""The messages of a recording in one pass over its MCAP file.

rosbags' reader builds a BytesIO, a named tuple and a heap entry per message: 1.0 of the
1.1 s that reading a 300-hole plate's bag took once its messages were no longer
deserialized one by one (cdr_arrays.py). The recorder writes one MCAP file of
uncompressed chunks (BagWriter); such a file is scanned here record by record with
struct, and its messages come out as rosbags gives them: ordered by log time, ties in
file order. Any other recording (several files, compressed chunks, SQLite) is read by
rosbags' AnyReader.
"""
from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

MAGIC = b"\x89MCAP0\r\n"
SCHEMA, CHANNEL, MESSAGE, CHUNK, DATA_END = 0x03, 0x04, 0x05, 0x06, 0x0F
RECORD = struct.Struct("<BQ")  # opcode, content length
MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
CHUNK_HEAD = struct.Struct("<QQQII")  # start and end time, uncompressed size and crc, compression length
U16, U32, U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")

Message = tuple[str, str, int, bytes | memoryview]  # topic, message type, log time (ns), serialized data


def _last(topic: str) -> str:
    return topic.rsplit("/", 1)[-1]


def _string(data: memoryview, at: int) -> tuple[str, int]:
    (length,) = U32.unpack_from(data, at)
    return bytes(data[at + 4:at + 4 + length]).decode(), at + 4 + length


def _scan(data: memoryview, start: int, end: int, found: dict, skip: set[str]) -> bool:
    """Read the records from ``start`` to ``end`` into ``found`` (schemas, channels and
    messages); False at anything this scan does not read (a compressed chunk)."""
    schemas, channels, skipped = found["schemas"], found["channels"], found["skipped"]
    times, order, sources = found["t"], found["c"], found["m"]
    at = start
    while at < end:
        op, length = RECORD.unpack_from(data, at)
        body, at = at + RECORD.size, at + RECORD.size + length
        if op == MESSAGE:
            channel, _, log_time, _ = MESSAGE_HEAD.unpack_from(data, body)
            if channel not in skipped:
                times.append(log_time)
                order.append(channel)
                sources.append(data[body + MESSAGE_HEAD.size:at])
        elif op == CHUNK:
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
            if _last(topic) in skip:
                skipped.add(channel)
        elif op == DATA_END:
            return True
    return True


def messages(bag: Path, skip: set[str] = frozenset()) -> Iterator[Message]:
    """Every message of the recording at ``bag`` (a rosbag2 directory) but those of the
    topics named in ``skip`` (the last part of a name: "clock"), in log-time order.

    Raises:
        rosbags' errors, OSError: the recording cannot be read.
    """
    files = sorted(Path(bag).glob("*.mcap"))
    data = memoryview(files[0].read_bytes()) if len(files) == 1 else None
    found: dict = {"schemas": {}, "channels": {}, "skipped": set(), "t": [], "c": [], "m": []}
    if data is not None and data[:8] == MAGIC and _scan(data, 8, len(data), found, skip):
        channels = {c: (topic, found["schemas"].get(schema, "")) for c, (topic, schema) in found["channels"].items()}
        for k in np.argsort(np.array(found["t"], dtype=np.uint64), kind="stable"):
            topic, msgtype = channels[found["c"][k]]
            yield topic, msgtype, int(found["t"][k]), found["m"][k]
        return
    with AnyReader([Path(bag)]) as reader:
        for conn, log_time, raw in reader.messages(connections=[c for c in reader.connections
                                                                 if _last(c.topic) not in skip]):
            yield conn.topic, conn.msgtype, log_time, raw
