"""Cutter radius compensation (cnc_msgs_py.gcode.compensation) against LinuxCNC's interpreter
on random contours: rs274 -g and our front end read the same program, and either both refuse
it, or every feed and arc end of LinuxCNC's is one of our feed moves' ends (in order, 1 um)
and every one of ours lies on LinuxCNC's path (1 um). Needs linuxcnc-uspace.

The contours are what a part outline is: 3-7 lines and G2/G3 arcs, each turning at most
140 deg from the last (a contour that turns back on itself within a few degrees is judged
by the sign of a tiny cross product, where LinuxCNC's own rules differ between lines and
arcs), G41.1/G42.1 with D 1, 2 or 4 mm.

    .venv/bin/python bench/peer/compensation_oracle.py [SEED] [N]
"""
from __future__ import annotations

import math
import random
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np

CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_]+)\((.*)\)")
TOLERANCE_MM = 1e-3
# a chord's midpoint lies up to the chord tolerance (1 um) inside its arc, and rs274 prints the
# arc's center and ends rounded to 0.1 um
MIDPOINT_TOLERANCE_MM = 1.5e-3


def cuts(output: str) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None, int]]:
    """rs274's feed moves and arcs (mm programs) as (kind, start, end, center, the index of the
    axis normal to the arc's plane), points x, y, z."""
    plane, pos, out = "XY", np.zeros(3), []
    for raw in output.splitlines():
        m = CALL.match(raw)
        if not m:
            continue
        name, nums = m.group(1), [float(v) for v in re.findall(r"-?\d+\.?\d*", m.group(2))]
        if name == "SELECT_PLANE":
            plane = "XZ" if "XZ" in m.group(2) else "XY"
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            end = np.array(nums[:3])
            if name == "STRAIGHT_FEED":
                out.append(("line", pos, end, None, 2))
            pos = end
        elif name == "ARC_FEED":
            a, b, ca, cb, _, third = nums[:6]
            end, center = (np.array([a, b, third]), np.array([ca, cb, third])) if plane == "XY" else \
                (np.array([b, third, a]), np.array([cb, third, ca]))
            out.append(("arc", pos, end, center, 2 if plane == "XY" else 1))
            pos = end
    return out


def distance_to_path(p: np.ndarray, path: list) -> float:
    """The distance (mm) from a point to LinuxCNC's feed path: to a line, or to an arc's circle
    in its plane with the point's third axis between the arc's ends (a helix)."""
    best = math.inf
    for kind, a, b, c, normal in path:
        if kind == "arc":
            plane = [i for i in range(3) if i != normal]
            lo, hi = sorted((a[normal], b[normal]))
            if lo - TOLERANCE_MM <= p[normal] <= hi + TOLERANCE_MM:
                best = min(best, abs(np.linalg.norm((p - c)[plane]) - np.linalg.norm((b - c)[plane])))
        else:
            u = b - a
            t = 0.0 if not u.any() else float(np.clip((p - a) @ u / (u @ u), 0.0, 1.0))
            best = min(best, float(np.linalg.norm(p - a - t * u)))
    return best


def feed_ends(moves: list[dict]) -> np.ndarray:
    """Our move entries' feed ends (x, y, z; an axis not given 0), a row of NaN for a rapid
    between them (so that no feed is taken to run from a rapid's end)."""
    rows = [[m["linear"].get(a, 0.0) for a in "xyz"] if "linear" in m else [math.nan] * 3
            for m in moves if "linear" in m or "rapid" in m]
    return np.array(rows, dtype=float).reshape(-1, 3)


def moves_of(doc: dict) -> list[dict]:
    """An operation's move entries: a move operation's own, a path operation's points after
    its first as feed moves (G64 P: the path runs through the programmed ends)."""
    if "path" in doc:
        return [{"linear": dict(zip("xyz", point))} for point in doc["path"]["points"][1:]]
    return doc["move"]


def compared(path: Path, recorded_output) -> tuple[str, list, SimpleNamespace, np.ndarray]:
    """A test program's rs274 output (``recorded_output(text)``) and LinuxCNC's cuts in it, its
    job through our front end, and our feed ends: what the oracle tests set side by side."""
    from cnc_msgs_py.gcode.document import job_document
    from cnc_msgs_py.job import parse_job

    output = recorded_output(path.read_text())
    job = parse_job(job_document(path))
    return output, cuts(output), job, feed_ends([m for _, _, d in job.program.operations for m in moves_of(d)])


def agree(path: list, ours: np.ndarray) -> bool:
    """LinuxCNC's ends among ours in order, and ours on LinuxCNC's path: every end within
    TOLERANCE_MM and every midpoint of two feed ends in a row within MIDPOINT_TOLERANCE_MM (a
    chord of an arc lies within the chord tolerance of it, a straight cut across an arc does not)."""
    ends = ours[~np.isnan(ours[:, 0])]
    k = 0
    for _, _, end, _, _ in path:
        while k < len(ends) and np.max(np.abs(ends[k] - end)) > TOLERANCE_MM:
            k += 1
        if k == len(ends):
            return False
    mids = (ours[1:] + ours[:-1]) / 2.0
    return max(distance_to_path(p, path) for p in ends) <= TOLERANCE_MM and \
        max(distance_to_path(p, path) for p in mids[~np.isnan(mids[:, 0])]) <= MIDPOINT_TOLERANCE_MM


def contour(rng: random.Random) -> str:
    lines = ["G21 G90 G17 G94 F100", "G0 X-20 Y-20 Z1", "G1 Z-1",
             f"{rng.choice(['G41.1', 'G42.1'])} D{rng.choice([1, 2, 4])} G1 X0 Y0"]
    x, y, heading = 0.0, 0.0, math.pi / 4
    for _ in range(rng.randint(3, 7)):
        heading += math.radians(rng.uniform(-140, 140))
        length = rng.uniform(3, 20)
        nx, ny = x + length * math.cos(heading), y + length * math.sin(heading)
        if rng.random() < 0.4:
            r = math.hypot(nx - x, ny - y) / 2 * rng.uniform(1.05, 3)
            lines.append(f"{rng.choice(['G2', 'G3'])} X{nx:.3f} Y{ny:.3f} R{r:.3f}")
        else:
            lines.append(f"G1 X{nx:.3f} Y{ny:.3f}")
        x, y = nx, ny
    return "\n".join(lines + ["G40 G1 X40 Y40", "M2"]) + "\n"


def main(seed: int = 1, n: int = 240) -> int:
    from cnc_msgs_py.gcode import Context, GcodeError, translate
    rng = random.Random(seed)
    count = {"agree": 0, "both refuse": 0, "only LinuxCNC refuses": 0, "only we refuse": 0, "paths differ": 0}
    for _ in range(n):
        text = contour(rng)
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "c.ngc").write_text(text)
            res = subprocess.run(["rs274", "-g", str(Path(tmp) / "c.ngc")], capture_output=True, text=True, timeout=60)
        theirs = next((ln for ln in (res.stdout + "\n" + res.stderr).splitlines()
                       if ln.strip() and not ln.lstrip()[:1].isdigit() and not ln.startswith("executing")), None)
        try:
            ops = translate(text, Context("c", "mill3"))
            ours, refused = feed_ends([m for op in ops for m in op.doc["move"]]), None
        except GcodeError as err:
            ours, refused = None, str(err)
        if theirs and refused:
            count["both refuse"] += 1
        elif theirs or refused:
            count["only LinuxCNC refuses" if theirs else "only we refuse"] += 1
            print(f"{theirs or refused}\n{text}")
        else:
            count["agree" if agree(cuts(res.stdout), ours) else "paths differ"] += 1
    print(f"{n} random contours (seed {seed}): " + ", ".join(f"{k} {v}" for k, v in count.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main(*[int(a) for a in sys.argv[1:]]))
