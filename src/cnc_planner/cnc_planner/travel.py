"""Axis targets against the machine's travel: a job is checked whole before anything is planned."""
from __future__ import annotations

from types import SimpleNamespace

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.schema import JobError
from cnc_msgs_py.units import to_mm

from cnc_planner.kinematics import Kinematics


def to_axes(kin: Kinematics, point: dict[str, float], field: str) -> dict[str, float]:
    """Kinematics.to_axes, with an unreachable point blamed on the job field it came from."""
    try:
        return kin.to_axes(point)
    except JobError as err:
        if err.field:
            raise
        raise JobError(field, err.reason) from err


def check_travel(machine: Machine, axes: dict[str, float], field: str) -> None:
    """Raise JobError if an axis position lies outside the machine's soft limits."""
    for name, position in axes.items():
        axis = machine.axes[name]
        if not axis.within_travel(position):
            raise JobError(
                field,
                f"puts axis {name} at {to_mm(position):.3f} mm, outside its travel "
                f"[{to_mm(axis.min):g}, {to_mm(axis.max):g}] mm",
            )


def program_axes(machine: Machine, target: SimpleNamespace, field: str) -> list[str]:
    given = [k for k, v in vars(target).items() if v is not None]
    for key in given:
        if key not in machine.linear_axes:
            raise JobError(f"{field}.{key}", f"machine '{machine.name}' has no {key} axis")
    return given
