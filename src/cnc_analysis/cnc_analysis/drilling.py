"""Overlap timing and safety of a drilling cycle, judged on sampled axis positions.

Fed with the bridge's feedback (where servo lag shows) or with the planner's commands.
Every interval with the tip below the R plane is one visit of a hole: the hole nearest
to X/Y at the visit's deepest sample. A sample below R with X/Y farther than the
tolerance from that hole is a safety violation. All times are in the time base of ``t``;
crossings of R and of the tolerance circle are interpolated between samples.
"""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.units import mm, to_mm

from .verdict import OVERCUT_LIMIT

# m: a hole shallower than programmed by more than this fails (deeper: OVERCUT_LIMIT). The
# planner turns each bottom where the stiffest drive inside the description's tolerance
# would reach the depth, so drives as described (or softer) stop short: 32 um on the shipped
# mill3, 147 um on the soft one, whose 4 ms loop may be 12 ms inside the default tolerance.
# ISO 2768-m allows +-0.2 mm on a 6-30 mm length, a hole's depth as a drawing states it.
DEPTH_SHORT_LIMIT = 0.2e-3


def _runs(mask: np.ndarray, t: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Start indices and end indices (exclusive) of the True runs of a boolean array.

    With sample times ``t``, a run also ends at a gap in them (a recording that lost
    samples): what happened in the gap is unknown, e.g. the tip may have risen above R
    and gone down into the next hole, so two visits must not be merged across it.
    """
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    if t is None or len(t) < 3:
        return starts, ends
    step = np.diff(t)
    after_gap = np.nonzero(step > 1.5 * np.median(step))[0] + 1
    split = after_gap[mask[after_gap] & mask[after_gap - 1]]
    return np.sort(np.concatenate([starts, split])), np.sort(np.concatenate([ends, split]))


def _cross(t: np.ndarray, f: np.ndarray, k: int, level: float) -> float:
    """Time at which f passes ``level`` between samples k-1 and k (t[k] at the ends)."""
    if k <= 0 or k >= len(t) or f[k] == f[k - 1]:
        return float(t[min(max(k, 0), len(t) - 1)])
    share = (level - f[k - 1]) / (f[k] - f[k - 1])
    return float(t[k - 1] + share * (t[k] - t[k - 1]))


def _moving_span(t: np.ndarray, axes: np.ndarray, threshold: float) -> tuple[float, float]:
    """First and last time any axis is farther than ``threshold`` from its start / end rest."""
    left = np.nonzero(np.any(np.abs(axes - axes[0]) > threshold, axis=1))[0]
    unsettled = np.nonzero(np.any(np.abs(axes - axes[-1]) > threshold, axis=1))[0]
    if not len(left):
        return float(t[0]), float(t[0])
    return float(t[left[0]]), float(t[unsettled[-1]])


def _climb_to_r(z: np.ndarray, r_z: float, dither: float) -> int:
    """How many samples at the start the tip spends climbing to R from below it: a cycle
    begun below its R plane rises there first (LinuxCNC's preliminary move, hole-circle.ngc
    starts at Z0 under R0.1): no hole visit, though X/Y moving meanwhile is still X/Y moving
    below R. None if it starts above R or goes down first."""
    if not len(z) or z[0] >= r_z:
        return 0
    above = np.nonzero(z >= r_z)[0]
    end = int(above[0]) if len(above) else len(z)
    return end if z[:end].min() >= z[0] - dither else 0


def analyze_drilling(
    t: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray,
    holes: list[tuple[float, float]], r_z: float, xy_tolerance: float,
    surface_z: float | list[float] | None = None,
) -> dict:
    """Per-hole overlap timing and job-wide safety of a drilling cycle (SI in, JSON out).

    Per hole (in the given order; times None if the hole was never drilled):
      in_position_s   X/Y came within tolerance for good before the tip went below R
      r_down_s/r_up_s the tip passed R going down / going up
      overlap_down_s  how long X/Y still moved after Z began its descent (from its
                      highest point before R), i.e. S1 overlapping S2
      overlap_up_s    how long Z still rose after X/Y left the hole, S3 overlapping S1
      cycle_time_s    from the previous hole's r_up (the job's first motion for the
                      first hole) to this hole's r_up
      depth_mm        deepest point below surface_z (one for all holes or one per
                      hole), when surface_z is given
    Job: ``safety_violations`` (samples below R off their hole, or during a start's climb to
    R off where it began: _climb_to_r) and ``cycle_time_s``
    from the first to the last axis motion (an axis farther than the tolerance from
    its rest at the start / at the end).
    """
    t, x, y, z = (np.asarray(a, dtype=float) for a in (t, x, y, z))
    h = np.asarray(holes, dtype=float).reshape(-1, 2)
    climb = _climb_to_r(z, r_z, xy_tolerance)
    strayed = int(np.sum(np.hypot(x[:climb] - x[0], y[:climb] - y[0]) > xy_tolerance))
    mask = z < r_z
    mask[:climb] = False
    starts, ends = _runs(mask, t)
    below = np.nonzero(mask)[0]
    visit = np.searchsorted(starts, below, side="right") - 1
    # The hole of each visit: nearest to X/Y at the visit's deepest sample.
    order = np.lexsort((z[below], visit))
    deepest = below[order[np.searchsorted(visit[order], np.arange(len(starts)))]]
    hole_of = np.argmin(np.hypot(x[deepest, None] - h[:, 0], y[deepest, None] - h[:, 1]), axis=1)
    off = np.hypot(x[below] - h[hole_of[visit], 0], y[below] - h[hole_of[visit], 1]) > xy_tolerance
    job_start, job_end = _moving_span(t, np.stack([x, y, z], axis=1), xy_tolerance)

    # Per hole: its first visit's entry and its last visit's exit, in drilling order.
    first: dict[int, int] = {}
    last: dict[int, int] = {}
    for v, j in enumerate(hole_of.tolist()):
        first.setdefault(j, v)
        last[j] = v
    drilled = sorted(first, key=lambda j: starts[first[j]])
    bounds = [0] + [int(ends[last[j]]) for j in drilled] + [len(t)]
    surfaces = None if surface_z is None else np.broadcast_to(np.asarray(surface_z, float), (len(h),))
    rows = {j: _hole(j, h[j], surface_z) for j in range(len(h))}
    r_up_prev = job_start
    for rank, j in enumerate(drilled):
        lo, hi = bounds[rank], bounds[rank + 2]
        kd, ku = int(starts[first[j]]) - lo, int(ends[last[j]]) - lo
        tw, xw, yw, zw = t[lo:hi], x[lo:hi], y[lo:hi], z[lo:hi]
        dist = np.hypot(xw - h[j, 0], yw - h[j, 1]) - xy_tolerance
        far_before = np.nonzero(dist[:kd] > 0)[0]
        in_position = _cross(tw, dist, int(far_before[-1]) + 1, 0.0) if len(far_before) else float(tw[0])
        # Z's descent starts at its last highest sample before R, its rise ends at the first
        # highest sample after R; X/Y leaves at its first sample off the hole after the visit.
        top_before = kd - 1 - int(np.argmax(zw[:kd][::-1])) if kd > 0 else 0
        top_after = ku + int(np.argmax(zw[ku:])) if len(zw) > ku else len(zw) - 1
        far_after = np.nonzero(dist[ku:] > 0)[0]
        overlap_up = 0.0
        if len(far_after):
            leave = _cross(tw, dist, ku + int(far_after[0]), 0.0)
            overlap_up = max(0.0, float(tw[top_after]) - leave)
        r_down, r_up = _cross(tw, zw, kd, r_z), _cross(tw, zw, ku, r_z)
        rows[j].update({
            "in_position_s": in_position, "r_down_s": r_down, "r_up_s": r_up,
            "overlap_down_s": max(0.0, in_position - float(tw[top_before])),
            "overlap_up_s": overlap_up, "cycle_time_s": r_up - r_up_prev,
        })
        if surface_z is not None:
            rows[j]["depth_mm"] = to_mm(float(surfaces[j] - zw[kd:ku].min()))
        r_up_prev = r_up
    return {"holes": [rows[j] for j in range(len(h))], "safety_violations": int(np.sum(off)) + strayed,
            "cycle_time_s": job_end - job_start}


def obstacle_clearance(x: np.ndarray, y: np.ndarray, z: np.ndarray, obstacles: list[list[float]],
                       radius: float) -> list[float | None]:
    """Per obstacle [x0, y0, x1, y1, top_z], the lowest height (m) of the tip above its top
    while the tool (a disk of ``radius`` around the tip) overlaps its box; None if never."""
    out: list[float | None] = []
    for x0, y0, x1, y1, top in obstacles:
        dx = np.maximum(np.maximum(x0 - x, x - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - y, y - y1), 0.0)
        over = np.hypot(dx, dy) < radius if radius > 0 else (dx == 0) & (dy == 0)
        out.append(float(np.min(z[over]) - top) if over.any() else None)
    return out


def _hole(index: int, xy: np.ndarray, surface_z: float | list[float] | None) -> dict:
    """A hole's row before analysis: every time None until the hole is found drilled."""
    row = {"index": index, "x_mm": to_mm(float(xy[0])), "y_mm": to_mm(float(xy[1])),
           "in_position_s": None, "r_down_s": None, "r_up_s": None,
           "overlap_down_s": None, "overlap_up_s": None, "cycle_time_s": None}
    if surface_z is not None:
        row["depth_mm"] = None
    return row


def drilling_failures(result: dict, depths: list[float]) -> list[str]:
    """What fails a drilling cycle judged by analyze_drilling (with surface_z): any sample
    below R with X/Y off its hole, a hole never drilled, a hole deeper than its programmed
    depth (``depths``, m below its surface, in the result's hole order) by more than
    OVERCUT_LIMIT or shallower by more than DEPTH_SHORT_LIMIT. One phrase per kind of miss."""
    failures = []
    if result["safety_violations"]:
        failures.append(f"X/Y moved while the tip was below R in {result['safety_violations']} feedback samples")
    missing = [h for h in result["holes"] if h.get("depth_mm") is None]
    if missing:
        failures.append(f"{len(missing)} of {len(result['holes'])} holes not drilled, the first at {_at(missing[0])}")
    errors = [(mm(h["depth_mm"]) - depth, h, depth) for h, depth in zip(result["holes"], depths)
              if h.get("depth_mm") is not None]
    for name, limit, misses in (("deeper", OVERCUT_LIMIT, [e for e in errors if e[0] > OVERCUT_LIMIT]),
                                ("shallower", DEPTH_SHORT_LIMIT, [e for e in errors if e[0] < -DEPTH_SHORT_LIMIT])):
        if misses:
            _, hole, depth = max(misses, key=lambda e: abs(e[0]))
            failures.append(f"{len(misses)} of {len(errors)} holes {name} than programmed by more than "
                            f"{to_mm(limit):g} mm, the worst {hole['depth_mm']:.4f} mm deep for {to_mm(depth):g} mm at {_at(hole)}")
    return failures


def _at(hole: dict) -> str:
    return f"X {hole['x_mm']:g} Y {hole['y_mm']:g} mm"
