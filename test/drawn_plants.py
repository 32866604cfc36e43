"""Hypothesis strategies for plants inside a machine description's tolerance: the drives a
real machine may have while the plan must still hold (the tolerance property tests)."""
from __future__ import annotations

import dataclasses

from hypothesis import strategies as st

from cnc_msgs_py.machine import Drive, Machine
from cnc_msgs_py.plant import Plant, outside_tolerance


def drive_within(draw, machine: Machine, joint: str, period: float) -> Drive:
    """One drive drawn inside its description's tolerance: gain, feed-forward, velocity loop
    and a transport delay of whole servo periods."""
    d = machine.drives[joint]
    tol = d.tolerance
    factor = {k: draw(st.floats(*getattr(tol, k))) for k in ("kp", "velocity_ff", "velocity_lag")}
    delay = draw(st.integers(round(tol.delay[0] / period), round(tol.delay[1] / period))) * period
    return dataclasses.replace(d, kp=d.kp * factor["kp"], velocity_ff=d.velocity_ff * factor["velocity_ff"],
                               velocity_lag=d.velocity_lag * factor["velocity_lag"], delay=d.delay + delay)


@st.composite
def plants_within(draw, machine: Machine, joints: tuple[str, ...], period: float, alike: bool = False) -> dict:
    """The drives of ``joints`` drawn apart inside their tolerance, or ``alike``: all the
    first one's (for joints described alike); the others as described."""
    first = drive_within(draw, machine, joints[0], period)
    plant = {j: first if alike else drive_within(draw, machine, j, period) for j in joints[1:]}
    plant[joints[0]] = first
    assert outside_tolerance(machine, Plant("drawn", {**machine.drives, **plant})) == []
    return plant
