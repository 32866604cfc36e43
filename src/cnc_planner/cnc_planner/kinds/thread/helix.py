"""Where the tool is on the helix of one pass, its vibration included: the groove
geometry every pass follows once it has joined its helix.

Geometry (SI, external thread; an internal one mirrors x). Pass k cuts to the cumulative
radial depth d_k. The tool moves in along the infeed line, at infeed_angle from radial:
at depth d its tip is at x = major_radius - d and shifted d*tan(infeed_angle) along the
feed, so it slides down the trailing flank and its leading edge does the cutting. The
helix angle psi of a pass is the spindle angle counted from where that pass's helix
passes start_z; psi is the groove coordinate, the same point of the groove on every pass:

    depth(psi) = d_k - A_k * (1 - w(D_k*psi/2pi + k*phase_shift/2pi))
    x = surface(g) - depth,   z = g - depth*tan(infeed_angle),   g = start_z - pitch*psi/2pi

with surface(g) = major_radius on a straight thread; on a taper thread (`taper`, diameter
per length) the stock is a cone, major_radius at the face and growing by taper/2 per unit
of length into the part (shrinking into a bore), so x follows the cone along the groove
and both axes stay locked to the spindle angle; the depth stays radial below the cone.
Tapered ends (G76's E and L, ends.py) raise x out of the depth over their length of
groove, z still on the lead.

with w the vibration module's waveform (0 at the return point, 1 at the turning point),
A_k = Q * (d_k - d_(k-1)) the radial amplitude and D_k = D + k*D_step. The vibration
therefore moves x and z together along the infeed line and never leaves the flank. With
phase_shift = 180 deg pass k returns where pass k-1 reached its turning point d_(k-1);
with Q > 1 its return lies above it: the tool is in air there and the chip breaks, at
least once per vibration. Spring passes run at full depth without vibration and take
off what the last returns left standing.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from cnc_planner.kinds.thread import _helix_kernel
from cnc_planner.kinds.thread.ends import end_ramp, ramp_peaks
from cnc_planner.kinds.thread.spec import TWO_PI, Pass, ThreadSpec
from cnc_planner.vibration.waveform import waveform

WAVE_POINTS = 4096  # phase samples for the waveform's derivative maxima (the cosine's peaks among them)


def helix(spec: ThreadSpec, cut: Pass, psi: np.ndarray) -> np.ndarray:
    """(3, len(psi), 2): axis x and z, their velocity and acceleration on the helix of a
    pass with its vibration, at helix angles psi (the spindle turning at speed).

    With w the symmetric waveform (waveform() at r = 0.5) of u = per_rev * psi / 2pi + phase:
    depth = d - A * (1 - w), the groove's z under the tool g = start_z + s * pitch * psi / 2pi,
    x = origin_x + surface(g) + radial * depth, z = origin_z + g + s * depth * tan(infeed),
    and their derivatives at the spindle speed. Evaluated by _helix_kernel.c around numpy's
    sine and cosine, in waveform()'s and this formula's order of operations."""
    omega, s, tan = spec.spindle_speed, spec.direction, math.tan(spec.infeed_angle)
    rate = cut.per_rev * omega / TWO_PI
    psi = np.asarray(psi, dtype=float)
    angle = np.empty_like(psi)
    _helix_kernel.phase(psi, cut.per_rev, cut.phase, TWO_PI, angle)
    out = np.empty((3, psi.size, 2))
    _helix_kernel.state(psi, np.sin(angle), np.cos(angle), out, (
        math.pi, TWO_PI, 2 * math.pi**2, cut.depth, cut.amplitude, cut.amplitude * rate, cut.amplitude * rate**2,
        spec.start_z, s * spec.pitch, spec.origin[0], spec.major_radius, spec.surface_slope, spec.radial,
        spec.origin[1], s, tan, spec.radial * spec.taper / 2 * s * spec.lead_speed, spec.lead_speed, s * tan))
    if spec.end_taper is not None:  # x out of the depth by the tapered ends' ramp (ends.py), z on its lead
        rise, slope, curve = end_ramp(spec, spec.pitch * psi / TWO_PI)
        lead = spec.lead_speed
        out[0, :, 0] -= spec.radial * rise
        out[1, :, 0] -= spec.radial * slope * lead
        out[2, :, 0] -= spec.radial * curve * lead**2
    return out


def helix_peaks(spec: ThreadSpec, cut: Pass) -> np.ndarray:
    """(2, 3): the largest |velocity|, |acceleration| and |jerk| of x and z on the helix of
    a pass (the spindle turning at speed): the lead, the taper and the tapered ends' ramp,
    plus the vibration along the infeed line, whose derivatives grow with the vibrations per
    second, squared and cubed."""
    rate = cut.per_rev * spec.spindle_speed / TWO_PI  # vibrations per second
    radial = cut.amplitude * np.array(_wave_maxima()) * rate ** np.arange(1, 4)  # depth: |v|, |a|, |j|
    cone = np.array([spec.taper / 2 * spec.lead_speed, 0.0, 0.0])  # x follows the taper
    return np.stack([radial + cone + ramp_peaks(spec),
                     math.tan(spec.infeed_angle) * radial + np.array([spec.lead_speed, 0.0, 0.0])])


@functools.cache
def _wave_maxima() -> tuple[float, float, float]:
    """max |w'|, |w''|, |w'''| per cycle of the symmetric waveform (sampled: its peaks lie
    on quarter cycles, among the samples)."""
    _, *derivatives = waveform(np.arange(WAVE_POINTS) / WAVE_POINTS)
    return tuple(float(np.max(np.abs(d))) for d in derivatives)
