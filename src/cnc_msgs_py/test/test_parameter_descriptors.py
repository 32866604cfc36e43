"""Parameter descriptors built from a node's table (no ROS graph needed)."""
from __future__ import annotations

from cnc_msgs_py.parameters import Param


def test_a_float_parameter_gets_its_unit_range_and_when_it_may_change():
    descriptor = Param(0.3, "setpoints kept ahead", "s", (0.05, 5.0)).descriptor()
    assert descriptor.description == "setpoints kept ahead [s]" and not descriptor.read_only
    assert descriptor.additional_constraints == "may be changed at run time"
    (span,) = descriptor.floating_point_range
    assert (span.from_value, span.to_value) == (0.05, 5.0) and not descriptor.integer_range


def test_an_integer_parameter_gets_an_integer_range_and_read_only_says_so():
    descriptor = Param(100, "setpoints per chunk", "points", (1, 10000), read_only=True).descriptor()
    (span,) = descriptor.integer_range
    assert (span.from_value, span.to_value, span.step) == (1, 10000, 1) and not descriptor.floating_point_range
    assert descriptor.read_only and descriptor.additional_constraints == "fixed at start-up"


def test_a_configure_time_parameter_says_when_it_may_be_set():
    descriptor = Param("mill3", "machine description", at_configure=True).descriptor()
    assert descriptor.description == "machine description" and not descriptor.read_only
    assert descriptor.additional_constraints == "read at configure: may be set only while the node is unconfigured"
