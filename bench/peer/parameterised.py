"""A parameterised program side by side: test/programs/bolt_circle_while.ngc (named
parameters, an O-word while loop, COS/SIN expressions: eight G81 holes on a circle), the
very text on both sides.

LinuxCNC runs the file as it is (bench/peer/programs.ProgramRow.linuxcnc_program: MDI to
where its first rapid goes, then the program). Ours reads the same text with our G-code
front end (cnc_msgs_py.gcode, as a ``program`` job) and runs it through both nodes over
topics, as cnc-run does (bench/peer/ours.run_over_topics), on the fair and the normal
machine. Each recording is judged per operation by the code the other rows use
(programs.judge_recording -> run.judge -> analyze_drilling), and against LinuxCNC's own
interpreter: every feed move of ``rs274 -g``'s canonical moves is a plunge here (one per
hole, checked), and each recording's bottom at each of them (its deepest sample near the
end point's X/Y) is measured against that end point and judged by the drill verdict's
bounds (X/Y within the cycle's tolerance, no deeper than OVERCUT_LIMIT, no shallower than
DEPTH_SHORT_LIMIT). The holes our front end hands the planner are checked against the same
moves by oracle.check_program.

The file is a test program (test/test_gcode_over_topics.py runs it through cnc-run), not
one of config/programs/, so it has its own section of bench/results/peer.txt, which
``run.py --only bolt_circle`` replaces alone.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import Machine
from cnc_analysis.drilling import DEPTH_SHORT_LIMIT
from cnc_analysis.verdict import OVERCUT_LIMIT
from cnc_planner.kinds.drill.block import drill_cycle
from cnc_planner.kinematics import Kinematics

import analysis
import oracle
import programs

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = ROOT / "test" / "programs" / "bolt_circle_while.ngc"
HEADER = "Parameterised program"
NEAR_MM = 1.0  # samples this close to an end point in X/Y belong to its hole (the holes are 23 mm apart)


def rows(only: str | None) -> list[programs.ProgramRow]:
    """The program's row when ``only`` is unset or matches its name."""
    return [programs.program_row(PROGRAM)] if not only or re.search(only, PROGRAM.stem) else []


@dataclass
class Ends:
    """rs274's feed-move end points (mm, program coordinates = axes: no offsets, tool length 0)
    and the cycle's X/Y tolerance (mm), within which a bottom counts as on its end point."""

    points: np.ndarray
    tolerance_mm: float


def feed_ends(row: programs.ProgramRow, interpret: Callable[[str], str], machine: Machine) -> Ends:
    """Every feed move's end point in rs274 -g's reading of the file (each a plunge)."""
    moves, error = oracle.canonical_moves(interpret(row.text))
    if error is not None:
        raise RuntimeError(f"rs274 refuses {row.path.name}: {error}")
    feeds = [mv for mv in moves if mv.kind in ("feed", "arc")]
    if any(mv.kind == "arc" or mv.end[:2] != mv.start[:2] or mv.end[2] >= mv.start[2] for mv in feeds):
        raise ValueError(f"{row.path.name}: a feed move that is not a plunge; its bottom is what is measured")
    points = np.array([mv.end for mv in feeds], dtype=float).reshape(-1, 3)
    drill = next(doc for _, kind, doc in row.operations if kind == "drill")
    job = parse_job({**drill, "machine": machine.name})
    tolerance = drill_cycle(job, machine, Kinematics(machine, job.setup, job.tool)).xy_tolerance
    return Ends(points, tolerance * 1e3)


def reached(axes: dict[str, np.ndarray], ends: Ends) -> dict:
    """Per end point, the recording's (m) bottom there: its deepest sample within NEAR_MM in
    X/Y, its X/Y distance (um) and its height above the end point (um: + short, - deeper).
    An end point is reached when the drill verdict's bounds hold at its bottom."""
    tip = np.stack([axes[a] for a in ("x", "y", "z")], axis=1) * 1e3
    xy, dz, ok = [], [], 0
    for e in ends.points:
        near = np.flatnonzero(np.hypot(*(tip[:, :2] - e[:2]).T) <= NEAR_MM)
        if not len(near):
            continue
        k = near[np.argmin(tip[near, 2])]
        xy.append(float(np.hypot(*(tip[k, :2] - e[:2]))) * 1e3)
        dz.append(float(tip[k, 2] - e[2]) * 1e3)
        ok += xy[-1] <= ends.tolerance_mm * 1e3 and -OVERCUT_LIMIT * 1e6 <= dz[-1] <= DEPTH_SHORT_LIMIT * 1e6
    return {"reached": ok, "ends": len(ends.points), "xy_um": max(xy, default=None),
            "dz_um": (min(dz), max(dz)) if dz else None}


def figures(judge, row: programs.ProgramRow, t, axes, spindle, machine: Machine, ends: Ends, **split) -> dict:
    """Whole program and drill operations (programs.judge_recording), and the end points reached."""
    rec = programs.judge_recording(judge, row, t, axes, spindle, machine, **split)
    drills = [op for (_, kind, _), op in zip(row.operations, rec["ops"]) if kind == "drill"]
    errors = [op["error"] for op in drills if "error" in op]
    if errors:
        return {"error": "; ".join(errors)}
    return {"time": rec["time"], "drill_s": sum(op["time"] for op in drills),
            "viol": sum(op["viol"] for op in drills), "depth_um": max(op["depth_um"] for op in drills),
            "holes": sum(op["holes"] for op in drills), **reached(axes, ends)}


def our_side(row: programs.ProgramRow, variants: dict, run_over_topics, judge, ends: Ends) -> dict:
    """fair and jerk: the text through our front end and both nodes over topics."""
    out = {}
    for key, machine in variants[row.machine].items():
        try:
            o = run_over_topics(row.doc(), machine, row.start)
            out[key] = figures(judge, row, o["t"], o["axes"], o["spindle"], machine, ends, starts=o["operations"])
        except Exception as err:  # noqa: BLE001 - shown in the section
            out[key] = {"error": f"{type(err).__name__}: {err}"[:200]}
    return out


def linuxcnc_side(row: programs.ProgramRow, sessions: dict, machine: Machine, judge, ends: Ends) -> dict:
    """'fb' (LinuxCNC's recording through our drive model) and 'raw' (its ideal loop), or 'error'."""
    rec = programs.linuxcnc_recording(row, sessions)
    if isinstance(rec, str):
        return {"error": rec}
    fb = analysis.through_servo(rec.t, rec.axes, machine)
    return {key: figures(judge, row, rec.t, axes, rec.spindle, machine, ends, line=rec.line)
            for key, axes in (("fb", fb), ("raw", rec.axes))}


def section(row: programs.ProgramRow, lc: dict, us: dict, ends: Ends, check: list[str]) -> list[str]:
    """The section's lines: one per way of running the file, the front end against rs274, notes."""
    n = len(next(doc for _, kind, doc in row.operations if kind == "drill")["drill"]["holes"])
    lc_t = lc.get("fb", {}).get("time")
    lines = [f"{HEADER} ({row.name}): test/programs/{row.path.name}, the same text on both sides: named parameters,",
             f"  an O-word while loop and COS/SIN expressions make {n} G81 holes on a circle; LinuxCNC runs the file,",
             "  ours reads it with its G-code front end and runs it through both nodes over topics (as cnc-run)",
             f"  {'way':<34} {'cycle s':>7} {'x LC':>6} {'drill s':>7} {'holes':>5} {'viol':>5} {'depth um':>8} "
             f"{'ends ok':>7} {'XY um':>5} {'Z vs rs274 um':>14}"]
    for name, f in (("LinuxCNC (drive-model feedback)", lc.get("fb")), ("LinuxCNC (ideal loop)", lc.get("raw")),
                    ("ours fair (recorded feedback)", us.get("fair")), ("ours jerk (recorded feedback)", us.get("jerk"))):
        if not f or "error" in f:
            lines.append(f"  {name:<34} {(f or lc).get('error', 'not run')[:150]}")
            continue
        ratio = f"{f['time'] / lc_t:6.3f}" if lc_t else f"{'-':>6}"
        dz = "-" if f["dz_um"] is None else "{:+.1f}..{:+.1f}".format(*f["dz_um"])
        lines.append(f"  {name:<34} {f['time']:7.3f} {ratio} {f['drill_s']:7.3f} {f['holes']:5d} {f['viol']:5d} "
                     f"{f['depth_um']:8.1f} {f['reached']:>3d}/{f['ends']:<3d} {_um(f['xy_um']):>5} {dz:>14}")
    lines += [f"  front end against rs274 -g:{c.split(row.name, 1)[1]}" for c in check]
    lines += [f"  ends ok: of rs274 -g's {len(ends.points)} feed moves (all plunges), those whose bottom on the recording (the",
              f"  deepest sample within {NEAR_MM:g} mm in X/Y) is within the drill verdict: X/Y within "
              f"{ends.tolerance_mm * 1e3:g} um, no deeper than",
              f"  {OVERCUT_LIMIT * 1e6:g} um, no shallower than {DEPTH_SHORT_LIMIT * 1e6:g} um. XY um: the worst bottom's "
              "X/Y distance; Z vs rs274: the",
              "  bottoms' height above the end points (+ short, - deeper), lowest..highest. depth um: the worst hole's",
              "  depth error by analyze_drilling. viol: samples (ms) below R with X/Y more than 10 um off the hole.",
              "  cycle s: first to last axis motion; drill s: the drill operation alone (LinuxCNC's by",
              "  motion.program-line, ours by the planner's operation mark). ours fair: every max_jerk 1e6 m/s^3",
              "  (trapezoids, like LinuxCNC); jerk: the normal mill3, both with the described drives' default",
              "  tolerance: the cycle waits for the slowest tolerated drive and the bottoms stop short so that no",
              "  drive inside it drills deeper (README, Status). LinuxCNC's ideal loop turns back within the servo",
              "  period its plunge ends in (no sample on the end point); behind the servo its G81 drills deeper."]
    return lines


def _um(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"
