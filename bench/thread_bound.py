"""Threads against the independent Z-only lower bound, over topics.

Each job is run with cnc-run (planner and bridge nodes, sim time, recorded to a bag) and
judged from the bag alone by the project-independent readers in test/: thread_reader
(chips and helix on feedback) and z_only_bound (the Z-only bound from the job document and
the machine's Z limits, and the cycle from the first to the last x/z motion on feedback).

Columns: cycle s over topics; bound s; ratio; the bound's parts (approach from home onto
the helix at the face, one stroke face to end_z at lead speed, one shortest Z return
end_z -> face at lead speed, final stop back at start_z); longest chip (revolutions, cutting
passes) and helix residual (um) on feedback.

Usage: python bench/thread_bound.py   (writes bench/results/thread_bound.txt too)
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "test"))

from publish import write_result  # noqa: E402
from z_only_bound import cycle_time, z_only_bound  # noqa: E402
from thread_reader import judge, read_bag  # noqa: E402

JOBS = ("thread_m12.yaml", "thread_m16.yaml")
CNC_RUN = Path(sys.executable).parent / "cnc-run"


def row(name: str, out: Path) -> str:
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "ROS_DOMAIN_ID": os.environ.get("ROS_DOMAIN_ID", str(60 + os.getpid() % 30))}
    result = subprocess.run([str(CNC_RUN), str(ROOT / "config" / "jobs" / name), "--out", str(out)],
                            capture_output=True, text=True, env=env, timeout=900)
    if result.returncode != 0:
        raise RuntimeError(result.stderr[-2000:])
    job, t, x, z, spindle = read_bag(out / "bag")
    cycle = cycle_time(t, x, z)
    bound = z_only_bound(job)
    thread = judge(job, t, x, z, spindle)
    th = job["thread"]
    label = f"{Path(name).stem} {th['pitch']:g}mm {job['spindle_rpm']}rpm"
    return (f"{label:<26} {bound['passes']:>6} {cycle:>8.3f} {bound['bound_s']:>8.3f} {cycle / bound['bound_s']:>6.3f} "
            f"{bound['approach_s']:>7.3f} {bound['stroke_s']:>7.3f} {bound['return_s']:>7.3f} {bound['final_s']:>7.3f} "
            f"{thread['max_chip_revs']:>6.2f} {thread['helix_residual_mm'] * 1e3:>7.2f}")


def main() -> None:
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [row(name, Path(tmp) / name) for name in JOBS]
    lines = [
        "Threads over topics against the independent Z-only bound (test/z_only_bound.py): cnc-run on the",
        "shipped lathe, judged from the bag. cycle: first to last x/z motion on feedback; bound: approach",
        "from home onto the helix at the face + passes x stroke (face to end_z at lead speed) + (passes-1)",
        "x shortest Z return (end_z -> face, at lead speed both ends) + final (end_z -> rest at start_z),",
        "each time-optimal for Z alone at the full limits. chip: longest, revolutions, cutting passes;",
        "helix: residual on feedback, um (test/thread_reader.py).",
        f"{'job':<26} {'passes':>6} {'cycle s':>8} {'bound s':>8} {'ratio':>6} {'approach':>7} {'stroke':>7} "
        f"{'return':>7} {'final':>7} {'chip':>6} {'helix':>7}",
        *rows,
        "",
        f"({time.perf_counter() - start:.0f} s)",
    ]
    text = "\n".join(lines)
    print(text)
    write_result("thread_bound.txt", text)


if __name__ == "__main__":
    main()
