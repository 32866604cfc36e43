"""LinuxCNC's interpreter as an oracle of our G-code front end.

``rs274 -g FILE`` (LinuxCNC's standalone interpreter, in linuxcnc-uspace) prints the
canonical machining calls it makes of a program: every STRAIGHT_TRAVERSE, STRAIGHT_FEED,
ARC_FEED and spindle-synchronised pass its canned cycles expand into. This module reads
those moves and checks, per operation of our front end's translation (cnc_msgs_py.gcode),
that our reading of each cycle's words is LinuxCNC's:

- drilling (G81/G82/G83/G73): the same holes in the same order, each with its R plane, its
  bottom, its retract level (G98: the initial Z, G99: R) and its peck bottoms below the
  surface (LinuxCNC pecks Q from R, so its first peck of a G83 ends at the surface we
  assume, 2 mm below R: only the bottoms below it are compared);
- threading (G76): the passes' count (spring passes included), their radii (major radius
  less each cumulative depth), pitch, start and end Z, and the infeed angle that LinuxCNC's
  Z shift between the first and the last pass makes with their depth difference;
- roughing (G71): the roughing levels (stock radius less k x I) and the contour: every
  end point and arc midpoint of LinuxCNC's final contour pass lies D (its normal
  finishing offset) from our profile, arcs swept the way our parsed profile sweeps them.

Lengths compared within the resolution rs274 prints (4 decimals: 0.1 um in mm, 2.5 um
in inches). rs274 needs linuxcnc-uspace (apt), so bench-peer runs it and keeps its outputs
in bench/results/rs274_canonical.json (by each program's sha256); test/test_gcode.py checks
the front end against those recorded outputs without LinuxCNC.

    .venv/bin/python bench/peer/oracle.py    # rs274 on config/programs/*.ngc: check, record
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.kinds.thread import tapered_ends

RECORDED = Path(__file__).resolve().parents[1] / "results" / "rs274_canonical.json"
CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z0-9_]+)\((.*)\)")
MM_TOLERANCE = 0.0005  # mm: rounding of rs274's 4 decimals in mm (0.05 um) plus float noise
INCH_TOLERANCE = 0.0013  # mm: half of rs274's last printed digit in inches (0.0001 in)


@dataclass
class Move:
    """One canonical move, in mm: start and end (x, y, z), its kind, whether it is a
    spindle-synchronised pass, and for arcs (XZ plane) the center (z, x) and rotation."""

    kind: str  # rapid | feed | arc
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    synced: bool = False
    pitch: float = 0.0
    center: tuple[float, float] | None = None
    rotation: int = 0


def rs274(text: str) -> str:
    """What ``rs274 -g`` prints for a program (stdout, then stderr), its COMMENT calls left out."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "program.ngc"
        path.write_text(text)
        out = subprocess.run(["rs274", "-g", str(path)], capture_output=True, text=True, timeout=60)
    return "\n".join(line for line in (out.stdout + "\n" + out.stderr).splitlines() if " COMMENT(" not in line)


def _key(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def recording(interpret: Callable[[str], str], into: dict) -> Callable[[str], str]:
    """interpret, keeping each output in ``into`` under its program's sha256."""
    def run(text: str) -> str:
        into[_key(text)] = out = interpret(text)
        return out
    return run


def recorded(path: Path = RECORDED) -> Callable[[str], str]:
    """rs274's outputs as bench-peer recorded them (no LinuxCNC needed), by program."""
    outputs = json.loads(path.read_text())

    def run(text: str) -> str:
        try:
            return outputs[_key(text)]
        except KeyError:
            raise KeyError(f"no rs274 output recorded for this program: rerun make bench-peer "
                           f"(or .venv/bin/python bench/peer/oracle.py) to record {path.name}") from None
    return run


def canonical_moves(output: str) -> tuple[list[Move], str | None]:
    """The moves (mm) of an rs274 -g output and the interpreter's error (None if it ran)."""
    scale, pos, synced, pitch = 1.0, (0.0, 0.0, 0.0), False, 0.0
    moves, error = [], None
    for raw in output.splitlines():
        m = CALL.match(raw)
        if not m:
            if raw.strip() and not raw.startswith("executing") and error is None:
                error = raw.strip()
            continue
        name, args = m.group(1), m.group(2)
        nums = [float(v) for v in re.findall(r"-?\d+\.?\d*(?:e-?\d+)?", args)]
        if name == "USE_LENGTH_UNITS":
            scale = 25.4 if "INCHES" in args else 1.0
        elif name == "START_SPEED_FEED_SYNC":
            synced, pitch = True, nums[0] * scale
        elif name == "STOP_SPEED_FEED_SYNCH":
            synced = False
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            end = (nums[0] * scale, nums[1] * scale, nums[2] * scale)
            moves.append(Move("rapid" if name == "STRAIGHT_TRAVERSE" else "feed", pos, end, synced, pitch))
            pos = end
        elif name == "ARC_FEED":  # XZ plane: first axis Z, second X, the axis Y
            z, x, cz, cx, rot, y = nums[:6]
            end = (x * scale, y * scale, z * scale)
            moves.append(Move("arc", pos, end, center=(cz * scale, cx * scale), rotation=int(rot)))
            pos = end
    return moves, error


# --- drilling ---------------------------------------------------------------------------------
def _holes(moves: list[Move]) -> list[dict]:
    """LinuxCNC's holes in order: each plunge (a feed down in Z alone) grouped by its X/Y."""
    holes: list[dict] = []
    for k, mv in enumerate(moves):
        if mv.kind != "feed" or mv.synced or mv.end[2] >= mv.start[2] - 1e-9:
            continue
        if abs(mv.end[0] - mv.start[0]) > 1e-9 or abs(mv.end[1] - mv.start[1]) > 1e-9:
            continue
        xy = mv.end[:2]
        if not holes or math.dist(holes[-1]["xy"], xy) > 1e-6:
            holes.append({"xy": xy, "r": mv.start[2], "plunges": []})
        holes[-1]["plunges"].append(mv.end[2])
        holes[-1]["retract"] = moves[k + 1].end[2] if k + 1 < len(moves) else None
    return holes


def _check_drill(doc: dict, lc_holes: list[dict], used: int, tol: float) -> tuple[list[str], int, float]:
    d = doc["drill"]
    surface, r = d.get("surface_z", 0.0), d.get("surface_z", 0.0) + d.get("r_gap", 2.0)
    bottom = surface - d["depth"]
    retract = d.get("clearance_z", r)
    peck = (d.get("peck") or {}).get("depth")
    ours_pecks = ([surface - peck * k for k in range(1, int(math.ceil(d["depth"] / peck - 1e-9)))] + [bottom]
                  if peck else [bottom])
    problems, worst = [], 0.0
    mine = lc_holes[used:used + len(d["holes"])]
    if len(mine) != len(d["holes"]):
        return [f"{len(d['holes'])} holes, LinuxCNC drills {len(mine)} here"], used + len(mine), math.inf
    for (x, y), h in zip(d["holes"], mine):
        lc_pecks = [z for z in h["plunges"] if z < surface - tol]
        errs = [math.dist((x, y), h["xy"]), abs(h["r"] - r), abs(h["plunges"][-1] - bottom), abs(h["retract"] - retract)]
        if len(lc_pecks) != len(ours_pecks):
            problems.append(f"hole ({x:g}, {y:g}): {len(ours_pecks)} pecks below the surface, LinuxCNC {len(lc_pecks)}")
        else:
            errs += [abs(a - b) for a, b in zip(lc_pecks, ours_pecks)]
        worst = max(worst, *errs)
    if worst > tol:
        problems.append(f"worst difference {worst * 1e3:.2f} um")
    return problems, used + len(mine), worst


# --- threading --------------------------------------------------------------------------------
def _passes(moves: list[Move]) -> list[Move]:
    return [mv for mv in moves if mv.synced and mv.kind == "feed"]


def _check_thread(doc: dict, passes: list[Move], used: int, tol: float) -> tuple[list[str], int, str, float]:
    """A G76's passes. With tapered ends (end_taper) each pass is more than one synchronised
    feed: an entry taper's two before it (in to the depth plus K at the start Z, then angled
    in to the depth over E), an exit taper's one after it (angled out by K over E to the
    end Z); their end points are compared too."""
    th = parse_job(doc).thread  # SI, its depths as our planner cuts them
    depths = th.depths or [th.depth * math.sqrt(k / th.passes) for k in range(1, th.passes + 1)]
    n = len(depths) + th.spring_passes
    ends = th.end_taper
    entry, exit_ = tapered_ends(ends.ends if ends else None)
    feeds = 1 + 2 * entry + exit_
    mine = passes[used:used + n * feeds]
    if len(mine) != n * feeds:
        return [f"{n} passes of {feeds} feeds (spring included), LinuxCNC cuts {len(mine)} feeds"], \
            used + len(mine), "", math.inf
    groups = [mine[k * feeds:(k + 1) * feeds] for k in range(n)]
    cut = list(depths) + [depths[-1]] * th.spring_passes
    tan_q = math.tan(th.infeed_angle)
    errs = [abs(groups[0][2 * entry].pitch - th.pitch * 1e3)]
    for group, d in zip(groups, cut):  # LinuxCNC's compound infeed: pass k shifted by d_k tan(Q) from
        mv, x, e = group[2 * entry], (th.major_radius - d) * 1e3, ends.length * 1e3 if ends else 0.0
        z0, z1 = (th.start_z - d * tan_q) * 1e3, (th.end_z + (cut[-1] - d) * tan_q) * 1e3  # Z start; its last
        errs += [abs(mv.end[0] - x), abs(mv.start[2] - (z0 - e if entry else z0)),  # pass ends at Z end
                 abs(mv.end[2] - (z1 + e if exit_ else z1))]
        if entry:  # in to the depth plus K at the start, then angled in to the depth over E
            errs += [abs(group[0].end[0] - (x + th.depth * 1e3)), abs(group[0].end[2] - z0),
                     abs(group[1].end[0] - x), abs(group[1].end[2] - (z0 - e))]
        if exit_:  # angled out by K over E to the end
            errs += [abs(group[-1].end[0] - (x + th.depth * 1e3)), abs(group[-1].end[2] - z1)]
    problems = [f"worst difference {max(errs) * 1e3:.2f} um"] if max(errs) > tol else []
    first, last = groups[0][2 * entry], groups[-1][2 * entry]
    shift = first.start[2] - last.start[2]  # along Z, from the last pass to the first
    angle = math.degrees(math.atan2(shift, first.end[0] - last.end[0]))  # over the depth between them
    tapers = f"; tapered {ends.ends} over {ends.length * 1e3:g} mm" if ends else ""
    return problems, used + n * feeds, f"{n} passes: radii, pitch, start/end Z{tapers}; flank {angle:.2f} deg", \
        max(errs)


# --- roughing ---------------------------------------------------------------------------------
def _arc_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, through: np.ndarray) -> float:
    """Distance from p to the arc from a to b around c that passes through `through`."""
    def ang(q):
        return math.atan2(q[1] - c[1], q[0] - c[0])
    r = float(np.hypot(*(a - c)))
    a0, a1, am, ap = ang(a), ang(b), ang(through), ang(p)
    ccw = (am - a0) % (2 * math.pi) < (a1 - a0) % (2 * math.pi)
    sweep = (a1 - a0) % (2 * math.pi) if ccw else (a0 - a1) % (2 * math.pi)
    inside = ((ap - a0) % (2 * math.pi) if ccw else (a0 - ap) % (2 * math.pi)) <= sweep + 1e-12
    if inside:
        return abs(float(np.hypot(*(p - c))) - r)
    return float(min(np.hypot(*(p - a)), np.hypot(*(p - b))))


def _profile_distance(p: np.ndarray, doc_profile: list, parsed: list) -> float:
    """Distance (mm) from p (z, x) to our profile: its lines, and its arcs as our parse sweeps them."""
    dense = np.asarray(parsed) * 1e3
    best, prev = math.inf, None
    for item in doc_profile:
        if isinstance(item, dict):
            a, b, c = np.asarray(prev), np.asarray(item["arc_to"], float), np.asarray(item["center"], float)
            near = dense[np.argmin(np.hypot(*(dense - (a + b) / 2).T))]  # a parsed point on this arc
            best = min(best, _arc_distance(p, a, b, c, near))
            prev = item["arc_to"]
        else:
            if prev is not None:
                a, b = np.asarray(prev, float), np.asarray(item, float)
                u = float(np.clip(np.dot(p - a, b - a) / max(np.dot(b - a, b - a), 1e-30), 0.0, 1.0))
                best = min(best, float(np.hypot(*(p - a - u * (b - a)))))
            prev = item
    return best


def _check_turn(doc: dict, moves: list[Move], tol: float) -> tuple[list[str], str, float]:
    """moves: the program up to its G71 line (then M2): the contour pass is its last run of feeds."""
    t = doc["turn"]
    job = parse_job(doc)
    r_stock = max(r for _, r in t["stock"])
    r_min = min((p[1] if isinstance(p, list) else p["arc_to"][1]) for p in t["profile"])
    allowance = t.get("finish_allowance", 0.0)
    ours = [r_stock - k * t["depth_of_cut"] for k in range(1, 1000) if r_stock - k * t["depth_of_cut"] > r_min + allowance]
    first = len(moves)
    while first > 0 and moves[first - 1].kind in ("feed", "arc"):
        first -= 1
    contour = moves[first:]
    axial = [mv for mv in moves[:first] if mv.kind == "feed" and abs(mv.end[0] - mv.start[0]) < 1e-9
             and mv.end[2] < mv.start[2] - 0.5 and mv.end[0] < r_stock - tol]  # LinuxCNC's pass at the stock: air
    levels = sorted({round(mv.end[0], 4) for mv in axial}, reverse=True)
    problems = []
    if len(levels) != len(ours) or max((abs(a - b) for a, b in zip(levels, ours)), default=0.0) > tol:
        problems.append(f"roughing levels {[round(v, 4) for v in ours]}, LinuxCNC {levels}")
    points = []
    for mv in contour:
        points.append((mv.start[2], mv.start[0]))
        points.append((mv.end[2], mv.end[0]))
        if mv.kind == "arc":
            c = np.asarray(mv.center)
            s, e = np.asarray([mv.start[2], mv.start[0]]), np.asarray([mv.end[2], mv.end[0]])
            a0, a1 = math.atan2(*(s - c)[::-1]), math.atan2(*(e - c)[::-1])
            sweep = ((a1 - a0) % (2 * math.pi)) if mv.rotation > 0 else -((a0 - a1) % (2 * math.pi))
            r = float(np.hypot(*(s - c)))
            points.append((c[0] + r * math.cos(a0 + sweep / 2), c[1] + r * math.sin(a0 + sweep / 2)))
    points = [p for p in points if p[1] < r_stock - tol]  # the exit up the face to the stock is not contour
    dist = [_profile_distance(np.asarray(p), t["profile"], job.turn.profile) for p in points]
    worst = max((abs(d - allowance) for d in dist), default=math.inf)
    if not points:
        problems.append("no contour pass found")
    elif worst > tol:
        problems.append(f"contour {min(dist):.4f}..{max(dist):.4f} mm from our profile, D is {allowance:g}")
    return (problems, f"roughing levels {', '.join(f'{v:g}' for v in levels)} mm; {len(points)} contour points "
            f"at D {allowance:g} mm from our profile", worst)


# --- per program --------------------------------------------------------------------------------
def upto(text: str, line: int) -> str:
    """The program up to its line ``line`` (a G71's), then M2: what rs274 makes of a roughing
    cycle alone, its contour pass the last run of feeds."""
    return "\n".join(text.splitlines()[:line]) + "\nM2\n"


def check_program(name: str, text: str, operations: list[tuple[int, str, dict]],
                  interpret: Callable[[str], str] = rs274) -> list[str]:
    """One line per cycle operation: what LinuxCNC's interpreter (``interpret``: a program's
    text to rs274 -g's output) made of it against ours."""
    moves, error = canonical_moves(interpret(text))
    tol = INCH_TOLERANCE if re.search(r"\bG20\b", text) else MM_TOLERANCE
    if error is not None:
        return [f"  {name}: rs274 refuses it: {error[:110]}"]
    lines = []
    holes, passes = _holes(moves), _passes(moves)
    used_holes = used_passes = 0
    for line, kind, doc in operations:
        if kind == "drill":
            problems, used_holes, worst = _check_drill(doc, holes, used_holes, tol)
            d = doc["drill"]
            what = (f"{len(d['holes'])} holes to Z{d.get('surface_z', 0.0) - d['depth']:g}, R, retract"
                    + (", pecks" if d.get("peck") else ""))
        elif kind == "thread":
            problems, used_passes, what, worst = _check_thread(doc, passes, used_passes, tol)
        elif kind == "turn":
            problems, what, worst = _check_turn(doc, canonical_moves(interpret(upto(text, line)))[0], tol)
        else:
            continue
        verdict = f"same within {worst * 1e3:.2f} um" if not problems else "DIFFERS: " + "; ".join(problems)
        lines.append(f"  {name} line {line} {kind}: {verdict} ({what})")
    return lines


def main() -> int:
    """Check every program of config/programs/ against rs274 and record its outputs."""
    import programs  # bench/peer/programs.py, beside this script
    outputs: dict[str, str] = {}
    interpret = recording(rs274, outputs)
    for row in programs.program_rows():
        print("\n".join(check_program(row.name, row.text, row.operations, interpret)))
    RECORDED.write_text(json.dumps(outputs, indent=0, sort_keys=True) + "\n")
    print(f"recorded {len(outputs)} rs274 outputs in {RECORDED}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
