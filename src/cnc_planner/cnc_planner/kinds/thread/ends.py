"""Tapered thread ends (G76's E and L), as LinuxCNC cuts them: at each end asked for, every
pass ramps x out by the thread's depth over ``length`` of the groove (LinuxCNC's angled
feeds "in" from start_z and "out" to end_z: the last pass runs from full depth to the
crest, earlier ones cross it sooner at the same angle), z still one lead per revolution,
so both axes stay locked to the spindle angle and the vibration runs on along the flank.

LinuxCNC's straight ramp leaves the pass's depth with a step in x's velocity, which no
jerk-limited axis follows at the lead speed. Here the corner is rounded: with w the groove
length into the ramp (0 where it begins, ``length`` where it reaches the thread's end),
the ramp is depth/(length - h) * C(w - h), C the unit ramp max(u, 0) convolved with a
raised cosine of half-width h (``blend``): C = u past h, 0 before -h, and in between
(u + h)^2/(4h) - h/(2 pi^2) (1 + cos(pi u/h)), so x's acceleration and jerk stay finite
and continuous. The ramp begins exactly where LinuxCNC's does and ends at the thread's end
one depth out, a little steeper than LinuxCNC's in between (h of the length is rounding).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.thread.spec import ThreadError, ThreadSpec

END_TAPER_SHARE = 0.3  # of x's acceleration and jerk limits for the ramp's corner: the rest
# is the vibration's and the compensated command's


def unit_ramp(u: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """C, C' and C'' at u: the unit ramp with its corner at 0 rounded over [-h, h]."""
    if h == 0.0:
        return np.maximum(u, 0.0), (u > 0.0).astype(float), np.zeros_like(u)
    v = np.clip(u, -h, h)
    c = np.cos(math.pi * v / h)
    inner = (v + h) ** 2 / (4 * h) - h / (2 * math.pi**2) * (1 + c)
    value = np.where(u >= h, u, np.where(u <= -h, 0.0, inner))
    slope = np.where(u >= h, 1.0, (v + h) / (2 * h) + np.sin(math.pi * v / h) / (2 * math.pi))
    curve = np.where(np.abs(u) >= h, 0.0, (1 + c) / (2 * h))
    return value, slope, curve


def end_ramp(spec: ThreadSpec, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far (m) the tapered ends raise the tool out of its pass's depth at p (groove
    length along the feed from start_z), and its first and second derivatives in p."""
    ends = spec.end_taper
    length, h = ends.length, ends.blend
    slope = spec.depth / (length - h)
    total = abs(spec.end_z - spec.start_z)
    out = [np.zeros_like(p) for _ in range(3)]
    for on, w, sign in ((ends.entry, length - p, -1.0), (ends.exit, p - (total - length), 1.0)):
        if on:
            value, d1, d2 = unit_ramp(w - h, h)
            out[0] += slope * value
            out[1] += sign * slope * d1
            out[2] += slope * d2
    return out[0], out[1], out[2]


def ramp_peaks(spec: ThreadSpec) -> np.ndarray:
    """x's largest |velocity|, |acceleration| and |jerk| from the tapered ends, on the
    helix (0 without them): the ramp's slope at the lead speed, and its corner's
    curvature (C'' peaks at 1/h, C''' at pi/(2 h^2))."""
    ends = spec.end_taper
    if ends is None:
        return np.zeros(3)
    slope, lead, h = spec.depth / (ends.length - ends.blend), spec.lead_speed, ends.blend
    if h == 0.0:
        return np.array([slope * lead, math.inf, math.inf])
    return slope * np.array([lead, lead**2 / h, math.pi / 2 * lead**3 / h**2])


def fit_end_taper(spec: ThreadSpec, machine: Machine) -> ThreadSpec:
    """The spec with its ramps' corners rounded as little as keeps x within END_TAPER_SHARE
    of its acceleration and jerk limits at the lead speed (unchanged without tapered ends).

    With the slope bounded by 2 depth/length (the corner takes at most half the length):
    acceleration slope lead^2/h and jerk slope pi/2 lead^3/h^2 give h; the length must hold
    two of it, which needs length >= 2 lead sqrt(depth/(share a)) and
    (4 pi depth lead^3/(share j))^(1/3).

    Raises:
        ThreadError: thread.end_taper.length too short for that.
    """
    ends = spec.end_taper
    if ends is None:
        return spec
    x = machine.axis("x")
    a, j = END_TAPER_SHARE * x.max_acceleration, END_TAPER_SHARE * x.max_jerk
    lead, depth, length = spec.lead_speed, spec.depth, ends.length
    least = max(2 * lead * math.sqrt(depth / a), (4 * math.pi * depth * lead**3 / j) ** (1 / 3))
    if length < least:
        raise ThreadError(
            "thread.end_taper.length", f"{to_mm(length):.4g} mm is too short for x to ramp out by the depth "
            f"{to_mm(depth):.4g} mm at the lead speed {to_mm(lead):.4g} mm/s within {END_TAPER_SHARE:.0%} of its "
            f"acceleration and jerk: needs >= {to_mm(least):.4g} mm"
        )
    slope = 2 * depth / length
    h = max(slope * lead**2 / a, math.sqrt(math.pi / 2 * slope * lead**3 / j))
    return replace(spec, end_taper=replace(ends, blend=min(h, length / 2)))
