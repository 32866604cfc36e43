"""Deep holes (depth 5x the diameter): chip breaking by vibration against pecking, on mill3.

20 holes of 3 mm, 15 mm deep, on a 4 x 5 grid at 8 mm pitch; every way is a job document
run over topics (cnc_planner.runner: planner and bridge nodes on simulated time, from the
machine's home, recorded), and the bridge's recorded feedback judged: cycle time (first to
last axis motion) and the longest chip, in spindle revolutions and mm of depth
(analyze_aircut per hole, from the surface to the bottom: the longest stretch the tool cuts
without once being behind the surface cut before). The planning time is taken offline
(plan_job on this process). Ways:

- vibration: D 1.5, Q 1.2 on the Z feed at 0.1 mm/rev, at the highest spindle speed the
  Z axis follows (its jerk limit, 200 m/s^3, caps it; check_vibration names it);
- vibration: auto at the drill's own 3000 rpm: the planner picks a waveform Z follows there
  (one vibration every E revolutions; the row names what it chose);
- G83: pecks of 1 x D with a full retract to R, same speed and feed per rev, and at
  3000 rpm (what the drill would run without the vibration's speed cap);
- G73: chip-break retracts, a full one every 3rd, at 3000 rpm;
- LinuxCNC's G83 on the 3000 rpm pecked job, the same limits: read from
  bench/results/peer.txt (`make bench-peer` runs LinuxCNC, in real time).

Run from the workspace root:  python bench/deep_holes.py  (about 10 minutes: over 10 minutes
of machine time, simulated). Writes the table to bench/results/deep_holes.txt as well.
"""
from __future__ import annotations

import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.job import parse_job  # noqa: E402
from cnc_msgs_py.machine import SPINDLE, load_machine  # noqa: E402
from cnc_planner.planning import plan_job  # noqa: E402
from cnc_planner.runner import run_job  # noqa: E402
from cnc_analysis.recording import read_run  # noqa: E402
from cnc_planner.vibration.waveform import Vibration, _speed_limits  # noqa: E402
from cnc_analysis.aircut import analyze_aircut  # noqa: E402
from cnc_analysis.drilling import analyze_drilling  # noqa: E402
from publish import RESULTS, write_result  # noqa: E402

MACHINE = load_machine("mill3")
DIAMETER_MM, DEPTH_MM, PITCH_MM, R_GAP_MM = 3.0, 15.0, 8.0, 2.0
PECK_RPM = 3000.0  # the pecked job LinuxCNC's G83 runs too (bench/peer)
FEED_PER_REV_MM = 0.1
HOME = dict(zip(MACHINE.joint_names, MACHINE.home_position))  # where a run over topics starts
START = {"x": -0.008, "y": 0.0, "z": 0.05}  # where bench/peer starts LinuxCNC's G83 (8 mm left of HOME)
HOLES = [[PITCH_MM * i, PITCH_MM * j] for j in range(4) for i in range(5)]


def max_vibration_rpm(vib: Vibration) -> float:
    """The highest spindle speed (rpm, rounded down to 10) at which Z follows the vibration."""
    omega = min(_speed_limits(vib, FEED_PER_REV_MM * 1e-3, MACHINE.axes["z"]))[0]
    return math.floor(omega * 60.0 / (2 * math.pi) / 10.0) * 10.0


def job(rpm: float, **drill) -> dict:
    return {"schema": "cnc_job/1", "job_id": "deep-holes", "kind": "drill", "machine": "mill3",
            "tool": {"diameter": DIAMETER_MM}, "spindle_rpm": rpm,
            "drill": {"holes": HOLES, "depth": DEPTH_MM, "r_gap": R_GAP_MM, "feed": FEED_PER_REV_MM * rpm, **drill}}


def pecked_job() -> dict:
    """Our G83-like pecking: 1 x D per peck, full retracts to R, at the drill's own speed."""
    return job(PECK_RPM, peck={"depth": DIAMETER_MM})


def judge(doc: dict) -> tuple[float, float, float, float, list[dict]]:
    """(planning s, cycle time s, longest chip revs, longest chip mm of depth, the vibration
    events' records of the waveform) of the job run over topics, judged on recorded feedback."""
    parsed = parse_job(doc)
    start = time.perf_counter()
    plan_job(parsed, MACHINE, HOME)
    planning = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as out:
        status = run_job(json.dumps(doc), doc["job_id"], MACHINE.name, Path(out) / "bag")
        assert status["state"] == "succeeded", status
        run = read_run(Path(out) / "bag")
    t, fb = run.feedback_t, run.feedback
    x, y, z, spindle = (fb[:, run.column(j)] for j in ("x", "y", "z", SPINDLE))
    cycle, longest, violations = cycle_and_chip(t, x, y, z, spindle)
    assert violations == 0
    chosen = [e["vibration"] for e in run.events if e.get("name") == "vibration_feed"]
    return planning, cycle, longest, longest * FEED_PER_REV_MM, chosen


def cycle_and_chip(t: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray,
                   spindle: np.ndarray) -> tuple[float, float, int]:
    """(cycle time s, longest chip in spindle revolutions, safety violations: samples below
    R with X/Y off the hole) of the job's holes, from sampled
    feedback (m, rad): whoever planned it (ours, or LinuxCNC's G83 in bench/peer) is judged
    by the same code."""
    holes = [(h[0] * 1e-3, h[1] * 1e-3) for h in HOLES]
    result = analyze_drilling(t, x, y, z, holes, R_GAP_MM * 1e-3, 1e-5, 0.0)
    longest = 0.0
    for hole in result["holes"]:
        inside = (t >= hole["r_down_s"]) & (t <= hole["r_up_s"])
        cut = inside & (np.arange(len(t)) >= np.argmax(inside & (z < 0.0)))
        longest = max(longest, analyze_aircut(spindle[cut], -z[cut]).max_chip_revs)
    return result["cycle_time_s"], longest, result["safety_violations"]


def linuxcnc_g83() -> list[str]:
    """LinuxCNC's G83 on the pecked job at the same limits, as `make bench-peer` last
    measured it (bench/results/peer.txt: LinuxCNC runs in real time, so it is not rerun here)."""
    peer = RESULTS / "peer.txt"
    rows = [line.split() for line in (peer.read_text().splitlines() if peer.exists() else [])
            if line.startswith("  LinuxCNC G83 (drive-model feedback)")]
    if not rows:
        return ["LinuxCNC G83: not measured yet (make bench-peer)"]
    cycle, revs, violations = float(rows[0][-3]), float(rows[0][-2]), int(rows[0][-1])
    return [f"{f'LinuxCNC G83 3 mm, {PECK_RPM:.0f} rpm (peer.txt)':44s} {'-':>7s} {cycle:8.2f} {revs:10.2f} "
            f"{revs * FEED_PER_REV_MM:8.2f}",
            "  (from bench/results/peer.txt, make bench-peer: LinuxCNC 2.9's G83 recorded, through the same drive"
            f" model;", f"  no jerk limit; {violations} ms with the tip below R while X/Y was off the hole)"]


def main() -> None:
    vib = {"D": 1.5, "Q": 1.2}
    slow = max_vibration_rpm(Vibration(D=1.5, Q=1.2))
    ways = [
        (f"vibration D1.5 Q1.2, {slow:.0f} rpm", job(slow), vib),
        (f"vibration auto, {PECK_RPM:.0f} rpm", job(PECK_RPM), "auto"),
        (f"G83 peck 3 mm (1 x D), {slow:.0f} rpm", job(slow, peck={"depth": DIAMETER_MM}), None),
        (f"G83 peck 3 mm (1 x D), {PECK_RPM:.0f} rpm", pecked_job(), None),
        (f"G73 break 3 mm, full every 3rd, {PECK_RPM:.0f} rpm",
         job(PECK_RPM, peck={"depth": DIAMETER_MM, "retract": "break", "full_every": 3}), None),
    ]
    lines = [f"Deep holes on mill3: {len(HOLES)} holes of {DIAMETER_MM:g} mm, {DEPTH_MM:g} mm deep "
             f"({DEPTH_MM / DIAMETER_MM:g} x D), {PITCH_MM:g} mm pitch, {FEED_PER_REV_MM:g} mm/rev; "
             "run over topics, judged on the recorded feedback",
             f"{'way':44s} {'plan s':>7s} {'cycle s':>8s} {'chip revs':>10s} {'chip mm':>8s}"]
    notes = []
    for name, doc, vibration in ways:
        if vibration is not None:
            doc["vibration"] = vibration
        planning, cycle, revs, mm, chosen = judge(doc)
        lines.append(f"{name:44s} {planning:7.1f} {cycle:8.2f} {revs:10.2f} {mm:8.2f}")
        print(lines[-1], flush=True)
        if vibration == "auto":
            c = chosen[0]
            notes.append(f"  (auto chose E {c['E']:g} R {c['R']:g} Q {c['Q']:g} for every hole: one vibration every "
                         f"{c['window_revs']:g} revolutions; predicted chip {c['predicted_chip_revs']:.2f} revs)")
            lines.append(notes[-1])
    lines += linuxcnc_g83()
    lines.append("chip: the longest stretch cut without an air-cut (analyze_aircut), per hole from the surface")
    text = "\n".join(lines)
    print(text)
    write_result("deep_holes.txt", text)


if __name__ == "__main__":
    main()
