"""Serialized-message templates for the 1 kHz paths (joint_states in the bridge, chunks
in the planner and the bridge): rclpy serializes a message of sentinel values once,
each value's offset is found in those bytes, and later messages are written or read
there in place.

The template's alignment padding is zeroed by a round trip through rosbags' serializer:
rclpy leaves padding as whatever its buffer held, so two processes built different
templates (the bridge then found every chunk unlike its own and deserialized it).
"""
from __future__ import annotations

from functools import cache


@cache
def _typestore():
    """rosbags' message types (0.1 s to build: only once a template is first needed;
    imported here too, so that a node's --help and the planning core load no rosbags)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def zero_padding(data: bytes, typename: str) -> bytearray:
    """The same message (``data`` cut at its end: rclpy's buffer runs on with bytes it
    reserved) with its alignment padding zeroed, as rosbags writes it."""
    store = _typestore()
    return bytearray(store.serialize_cdr(store.deserialize_cdr(data, typename), typename))


def offset_of(data: bytes | bytearray, value: bytes, topic: str) -> int:
    """Where a sentinel value sits in a serialization; it must occur exactly once.

    Raises:
        ValueError: it does not (``topic`` names the message in the error).
    """
    at = data.find(value)
    if at < 0 or data.find(value, at + 1) >= 0:
        raise ValueError(f"{topic}: a value not found once in rclpy's serialization")
    return at
