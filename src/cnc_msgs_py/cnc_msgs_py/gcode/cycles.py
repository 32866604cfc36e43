"""Canned cycles as our methods' job blocks (mm, as job documents are written).

- G81/G82/G83/G73 holes: one ``drill`` block per run of holes with the same cycle words; the
  R plane R, the bottom Z, G82's dwell P, G83's full-retract pecks and G73's chip-break
  pecks of Q; G98 keeps X/Y travels at the initial Z (``clearance_z``). The surface lies
  2 mm below R (the project's default R gap), or half way between R and Z when the hole is
  shallower than that.
- G76: our thread cycle. The major radius is the drive line plus I, the cumulative depths
  are LinuxCNC's J * k^(1/R) capped at K; when those are our own degression (K * sqrt(k/n))
  within 1 um the block says ``passes: n``, else it lists ``depths``. E and L become
  ``end_taper`` (E its length along the drive line, L 1/2/3 its ends entry/exit/both); E <= 0
  or L0 is the plain thread, as in LinuxCNC.
- G71: our roughing; its profile is the subroutine's path (or the P..Q blocks), its stock the
  program's ``stock`` outline when given (the profile clipped to the stock's right end),
  else G71's own assumption, the cylinder at the cycle's start point.
"""
from __future__ import annotations

import math

from ..kinds.thread import END_TAPER_ENDS

R_GAP_MM = 2.0
DEPTH_MATCH_MM = 1.0e-3  # G76 depths this close to ours become ``passes: n``
MAX_PASSES = 100


def drill_plane(r: float, z: float) -> dict:
    """surface_z, depth and r_gap for a hole from R plane ``r`` down to ``z``."""
    r_gap = min(R_GAP_MM, (r - z) / 2.0)
    surface = r - r_gap
    return {"surface_z": surface, "depth": surface - z, "r_gap": r_gap}


def g76_depths(first: float, full: float, degression: float) -> list[float]:
    """Cumulative depths of G76's cutting passes: first * k^(1/degression) until full.

    Raises:
        ValueError: more than MAX_PASSES passes.
    """
    depths: list[float] = []
    k = 1
    while True:
        d = first * k ** (1.0 / degression)
        if d >= full - 1.0e-12:
            return depths + [full]
        depths.append(d)
        k += 1
        if k > MAX_PASSES:
            raise ValueError(f"reaches K only after more than {MAX_PASSES} passes")


def g76_taper_ends(l_word: int) -> str | None:
    """The thread's end_taper.ends of G76's L as LinuxCNC reads it, by its bits: 1 the entry,
    2 the exit (L1, L2, L3 as documented; L4 and up by the same two bits); None: neither."""
    return (None, *END_TAPER_ENDS)[l_word & 3]  # END_TAPER_ENDS: entry, exit, both


def thread_passes(depths: list[float]) -> dict:
    """``passes: n`` when the depths are our degression within DEPTH_MATCH_MM, else ``depths``."""
    n, full = len(depths), depths[-1]
    if all(abs(d - full * math.sqrt((k + 1) / n)) <= DEPTH_MATCH_MM for k, d in enumerate(depths)):
        return {"passes": n}
    return {"depths": depths}


def clip_to_stock(profile: list, stock: list) -> list:
    """The profile without what lies right of the stock's right end (plain points only)."""
    right = max(p[0] for p in stock if isinstance(p, list))
    out: list = []
    for k, p in enumerate(profile):
        if not isinstance(p, list) or p[0] <= right:
            if out == [] and k > 0 and isinstance(profile[k - 1], list):
                (z0, x0), (z1, x1) = profile[k - 1], p
                if z0 > right > z1 and isinstance(p, list):
                    out.append([right, x0 + (right - z0) / (z1 - z0) * (x1 - x0)])
            out.append(p)
    return out if len(out) >= 2 else profile
