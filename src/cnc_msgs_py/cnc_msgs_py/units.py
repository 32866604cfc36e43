"""The one place where machinist units (job documents) become SI units (topics, core).

Job documents speak mm, mm/min, mm/rev, rpm and degrees; every ROS message and every
planning/analysis module speaks m, m/s, rad and rad/s (REP 103). Convert only here.
"""
from __future__ import annotations

import math

M_PER_MM = 1.0e-3
NS = 1_000_000_000  # nanoseconds per second: times on topics and in recordings are integer ns


def mm(value: float) -> float:
    """Millimetres to metres."""
    return value * M_PER_MM


def to_mm(value_m: float) -> float:
    """Metres to millimetres (for reports read by machinists)."""
    return value_m / M_PER_MM


def mm_per_min(value: float) -> float:
    """Feed in mm/min to m/s."""
    return value * M_PER_MM / 60.0


def to_mm_per_min(value_m_s: float) -> float:
    """Feed in m/s to mm/min."""
    return value_m_s * 60.0 / M_PER_MM


def m_per_min(value: float) -> float:
    """A cutting (surface) speed in m/min to m/s."""
    return value / 60.0


def to_m_per_min(value_m_s: float) -> float:
    """A cutting (surface) speed in m/s to m/min."""
    return value_m_s * 60.0


def rpm(value: float) -> float:
    """Spindle speed in rev/min to rad/s."""
    return value * 2.0 * math.pi / 60.0


def to_rpm(value_rad_s: float) -> float:
    """Spindle speed in rad/s to rev/min."""
    return value_rad_s * 60.0 / (2.0 * math.pi)


def deg(value: float) -> float:
    """Degrees to radians."""
    return math.radians(value)


def to_deg(value_rad: float) -> float:
    """Radians to degrees."""
    return math.degrees(value_rad)


# Unit names as declared in the job schema, mapped to their converter.
CONVERTERS = {
    "mm": mm,
    "mm/min": mm_per_min,
    "mm/rev": mm,
    "m/min": m_per_min,  # surface (cutting) speed, as G96's S  # a length per revolution: the revolution stays, the length goes SI
    "rpm": rpm,
    "deg": deg,
    "1": float,
}
