"""ROS parameters with descriptors: each node lists its parameters once, in one table.

A ``Param`` says what ``ros2 param describe`` shows: the meaning, the unit, the allowed
range and when a change takes effect. rclpy itself refuses a set outside the range
(``SetParametersResult(successful=False, reason=...)``) and any set of a read-only
parameter; a managed node refuses changes to ``at_configure`` parameters unless it is
unconfigured. A value out of range at start-up stops the node with one line naming it.

The tables are read without rclpy too (a node's --help lists them: cnc_msgs_py.tool), so
rclpy is imported where a parameter meets a node.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.node import Node


@dataclass(frozen=True)
class Unset:
    """A parameter declared without a value, of one ``rclpy.Parameter.Type`` (its name), so
    that a table needs no rclpy to be read."""

    type: str

    def __str__(self) -> str:
        return "unset"


@dataclass(frozen=True)
class Param:
    """One parameter: ``default`` (a value, or ``Unset`` of a type)."""

    default: Any
    description: str
    unit: str = ""
    range: tuple[float, float] | None = None  # inclusive; an IntegerRange for an int default
    read_only: bool = False  # fixed for the node's lifetime (no run-time change supported)
    at_configure: bool = False  # a managed node reads it at configure: set it while unconfigured

    def descriptor(self) -> ParameterDescriptor:
        from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

        unit = f" [{self.unit}]" if self.unit else ""
        when = ("fixed at start-up" if self.read_only else
                "read at configure: may be set only while the node is unconfigured" if self.at_configure else
                "may be changed at run time")
        descriptor = ParameterDescriptor(description=self.description + unit, read_only=self.read_only,
                                         additional_constraints=when)
        if self.range is not None:
            lo, hi = self.range
            if isinstance(self.default, int) and not isinstance(self.default, bool):
                descriptor.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
            else:
                descriptor.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
        return descriptor


def declare(node: Node, table: dict[str, Param]) -> None:
    """Declare every parameter of ``table`` on ``node`` with its descriptor.

    Raises:
        ValueError: a value given at start-up (``-p``, a params file) is out of range
            or of the wrong type; the message names the parameter.
    """
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
    from rclpy.parameter import Parameter

    for name, param in table.items():
        default = Parameter.Type[param.default.type] if isinstance(param.default, Unset) else param.default
        try:
            node.declare_parameter(name, default, param.descriptor())
        except (InvalidParameterValueException, InvalidParameterTypeException) as err:
            raise ValueError(f"parameter '{name}': {err}") from err


def value(node: Node, name: str) -> Any:
    """A declared parameter's value; None if it was declared without one and never set."""
    from rclpy.exceptions import ParameterUninitializedException

    try:
        return node.get_parameter(name).value
    except ParameterUninitializedException:
        return None

