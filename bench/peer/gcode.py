"""G-code for LinuxCNC 2.9 from the same job documents our planner gets (mm, mm/min, rpm).

- deep holes: G83 with G99 (full retract to R after every peck of Q);
- drilling: G81 with G99 (retract to R) or G98 (retract to the initial Z, the clearance
  level the program starts at), holes in the job's order;
- threading: G76 in radius mode (G8, so I/J/K are radii like our x), first depth J and
  degression R=2 chosen so G76 cuts the same cumulative depths as our planner,
  depth*sqrt(k/passes), then the spring passes (H);
- roughing: G71 (2.9 has G70/G71/G72; plain G71 also cuts pockets) on the profile given
  as an O-word subroutine, from the stock's largest radius so its pass levels are ours
  (r_max - k*d); D is the finishing allowance (LinuxCNC offsets the profile normal to it,
  ours is radial), R our clearance, feed per minute = feed per rev x rpm (G94).

Every program starts where the driver put the tool with MDI (the row's start) and ends
with M2; M3 comes first: the simulated spindle is at speed at once, and our planner's
spindle is run up before the measured motion starts too.
"""
from __future__ import annotations

import math


def _f(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".") if abs(v) >= 1e-9 else "0"


def drill_program(name: str, job: dict, retract: str) -> str:
    """G81 drilling of job['drill'] with G98 or G99."""
    return _canned_cycle(name, job, f"{retract} G81", "")


def peck_program(name: str, job: dict) -> str:
    """G83 (G99: full retract to R after every peck of Q) of job['drill'] with its peck depth."""
    return _canned_cycle(name, job, "G99 G83", f" Q{_f(job['drill']['peck']['depth'])}")


def _canned_cycle(name: str, job: dict, cycle: str, words: str) -> str:
    """One canned drilling cycle (``cycle``, extra ``words``) over job['drill']'s holes."""
    d = job["drill"]
    surface = d.get("surface_z", 0.0)
    bottom, r = surface - d["depth"], surface + d.get("r_gap", 2.0)
    holes = d["holes"]
    lines = [f"({name}: {cycle}{words})", "G21 G90 G17 G94 G40 G49 G64",
             f"M3 S{_f(job['spindle_rpm'])}",
             f"{cycle} X{_f(holes[0][0])} Y{_f(holes[0][1])} Z{_f(bottom)} R{_f(r)}{words} F{_f(d['feed'])}"]
    lines += [f"X{_f(x)} Y{_f(y)}" for x, y in holes[1:]]
    lines += ["G80", "M5", "M2", ""]
    return "\n".join(lines)


def g76_first_depth(depth: float, passes: int) -> float:
    """J for degression R=2: G76 cuts J*sqrt(k) while that is below K, then K. Rounded up
    to 0.1 um so that pass `passes` is the first to reach K (as ours: depth*sqrt(k/n))."""
    return math.ceil(depth / math.sqrt(passes) * 1e4) / 1e4


def thread_program(name: str, job: dict, clearance: float, back_to_start: bool) -> str:
    """G76 of job['thread'] (external, single start); the drive line is `clearance` above
    the major radius. back_to_start: rapid to start_z at the end, as our cycle does."""
    t = job["thread"]
    passes = len(t["depths"]) if t.get("depths") else t.get("passes", 6)
    j = g76_first_depth(t["depth"], passes)
    lines = [f"({name}: G76, {passes} passes + {t.get('spring_passes', 1)} spring)",
             "G21 G18 G8 G90 G94 G40 G49 G64", f"M3 S{_f(job['spindle_rpm'])}",
             f"G76 P{_f(t['pitch'])} Z{_f(t['end_z'])} I{_f(-clearance)} J{_f(j)} R2 K{_f(t['depth'])} "
             f"Q{_f(t.get('infeed_angle', 29.5))} H{t.get('spring_passes', 1)} E0 L0"]
    if back_to_start:
        lines.append(f"G0 Z{_f(t['start_z'])}")
    lines += ["M5", "M2", ""]
    return "\n".join(lines)


def turn_program(name: str, job: dict, sub: int = 100) -> str:
    """G71 roughing of job['turn'] from its origin and back to it."""
    t = job["turn"]
    oz, ox = t["origin"]
    r_max = max(r for _, r in t["stock"])
    z_start = oz
    feed = t["feed"] * job["spindle_rpm"]
    # the profile from the start level down to its first point, then along it; G71 cannot
    # intersect two parallel pieces (its offset step fails), so collinear points are dropped
    path = _drop_collinear([(z_start, r_max), (z_start, t["profile"][0][1])] + [tuple(p) for p in t["profile"]])
    lines = [f"({name}: G71 Q{sub}, feed {_f(t['feed'])} mm/rev at {_f(job['spindle_rpm'])} rpm)",
             "G21 G18 G8 G90 G94 G40 G49 G64", f"M3 S{_f(job['spindle_rpm'])}", f"F{_f(feed)}",
             f"o{sub} sub"]
    lines += [f"G1 X{_f(x)} Z{_f(z)}" for z, x in path[1:]]
    lines += [f"o{sub} endsub",
              f"G71 Q{sub} X{_f(r_max)} Z{_f(z_start)} D{_f(t.get('finish_allowance', 0.0))} "
              f"I{_f(t['depth_of_cut'])} R{_f(t.get('clearance', 0.5))}",
              f"G0 X{_f(ox)} Z{_f(oz)}", "M5", "M2", ""]
    return "\n".join(lines)


def _drop_collinear(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The outline without repeated points and without points inside a straight piece."""
    out: list[tuple[float, float]] = []
    for p in points:
        if out and abs(p[0] - out[-1][0]) < 1e-9 and abs(p[1] - out[-1][1]) < 1e-9:
            continue
        if len(out) >= 2:
            (z0, x0), (z1, x1) = out[-2], out[-1]
            if abs((z1 - z0) * (p[1] - x1) - (x1 - x0) * (p[0] - z1)) < 1e-9:
                out[-1] = p
                continue
        out.append(p)
    return out
