"""header.stamp of a serialized (CDR) message that starts with a std_msgs/Header (or the
time of a rosgraph_msgs/Clock, laid out alike): after the 4-byte encapsulation header come
sec (int32) and nanosec (uint32), little endian. Read and written in place on the 1 kHz
paths (joint_states, chunks, the recorder's /clock)."""
from __future__ import annotations

import struct

from .units import NS

STAMP_OFFSET = 4
STAMP = struct.Struct("<iI")


def read_stamp(data: bytes | bytearray) -> int:
    """The stamp in ns."""
    sec, nanosec = STAMP.unpack_from(data, STAMP_OFFSET)
    return sec * NS + nanosec


def write_stamp(buffer: bytearray, stamp_ns: int) -> None:
    STAMP.pack_into(buffer, STAMP_OFFSET, *divmod(stamp_ns, NS))
