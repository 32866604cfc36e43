"""Memory of the two nodes: where it goes at start-up, and its peak over whole jobs.

(a) start-up: resident memory (VmRSS) of a fresh interpreter after each import a node
    makes, and the Python heap (tracemalloc) those imports hold; one process per node;
(b) jobs through both nodes over topics, as cnc-run runs them (bridge in simulation mode,
    planner on sim time, everything recorded): peak RSS (VmHWM) of the planner and bridge
    processes, and their RSS at 10 %, 50 % and 100 % of the job, to show whether it grows
    with the job. Jobs: drill_row.yaml, lathe_feed_vibration.yaml, a 300-hole plate (the
    plate of bench/load.py (b)); ``--long N`` adds a plate of N holes (5 mm pitch, the
    soak plate's shape; 10000 is the soak's plate) and ``--raster LINES`` the soak's
    raster of that many lines (880: the 1-hour raster).
Run from the workspace root:  python bench/memory.py [--long 10000] [--raster 880]   (a few
minutes; with both soak jobs about 40 more). Writes the table to bench/results/memory.txt
(memory_plate<N>_raster<LINES>.txt with the soak jobs).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.job import load_job_file  # noqa: E402
from load import drill_doc  # noqa: E402
from publish import write_result  # noqa: E402
from soak import plate_doc, raster_doc, run  # noqa: E402

JOBS = ROOT / "config" / "jobs"

# What each node's process imports, in order; the last step of the bridge runs the kernel.
STAGES = {
    "bridge": [("python + numpy", "import numpy"), ("+ rclpy", "import rclpy"),
               ("+ drive model, kernel run once", "from cnc_servo_bridge.drive import warm_up; warm_up()"),
               ("+ bridge node module", "import cnc_servo_bridge.bridge_node")],
    "planner": [("python + numpy", "import numpy"), ("+ rclpy", "import rclpy"),
                ("+ planner node module", "import cnc_planner.planner_node")],
}

PROBE = """
import sys, tracemalloc
def rss():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
for code in sys.argv[1:]:
    exec(code)
    heap = tracemalloc.get_traced_memory()[0] / 2**20 if tracemalloc.is_tracing() else 0.0
    print(rss(), heap)
"""


def start_up(node: str) -> list[tuple[str, float, float]]:
    """(stage, RSS MiB, Python heap MiB) after each import of the node's process.

    RSS from a plain interpreter; the heap from a second one traced from its start
    (tracing inflates RSS, so the two are measured apart)."""
    codes = [code for _, code in STAGES[node]]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path[:3])}

    def probe(*flags: str) -> list[list[float]]:
        out = subprocess.run([sys.executable, *flags, "-c", PROBE, *codes], capture_output=True, text=True,
                             check=True, env=env).stdout
        return [[float(x) for x in line.split()] for line in out.splitlines()]

    plain, traced = probe(), probe("-X", "tracemalloc")
    return [(name, r[0], t[1]) for (name, _), r, t in zip(STAGES[node], plain, traced)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--long", type=int, default=0, metavar="N", help="also a plate of N holes (soak proxy)")
    parser.add_argument("--raster", type=int, default=0, metavar="LINES", help="also the soak's raster of LINES lines")
    args = parser.parse_args()
    lines = ["(a) start-up: one fresh interpreter per node, after each import it makes",
             f"{'node':<9}{'stage':<34}{'RSS MiB':>9}{'Python heap MiB':>17}", "-" * 69]
    for node in STAGES:
        lines += [f"{node:<9}{stage:<34}{rss:>9.1f}{heap:>17.1f}" for stage, rss, heap in start_up(node)]
    jobs = [("drill_row.yaml", load_job_file(JOBS / "drill_row.yaml")),
            ("lathe_feed_vibration.yaml", load_job_file(JOBS / "lathe_feed_vibration.yaml")),
            ("plate 300 holes", drill_doc(300))]
    if args.long:
        side = round(args.long ** 0.5)
        jobs.append((f"plate {side * side} holes, 5 mm", plate_doc(side)))
    if args.raster:
        jobs.append((f"raster {args.raster} lines", raster_doc(args.raster)))
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, doc) in enumerate(jobs):
            print(f"running {name}", flush=True)
            results.append((name, run(doc, Path(tmp) / str(i))))
    mib = lambda kib: kib / 1024  # noqa: E731
    lines += ["", "(b) peak RSS of each node over a whole job (over topics, as cnc-run)",
              f"{'job':<30}{'state':>10}{'planner peak MiB':>17}{'bridge peak MiB':>16}"
              f"{'planner RSS @10/50/100 %':>26}{'bridge RSS @10/50/100 %':>25}", "-" * 124]
    for name, r in results:
        at = {node: "/".join(f"{mib(r['rss_at'].get(m, {}).get(node, 0)):.0f}" for m in (10, 50, 100))
              for node in ("planner", "bridge")}
        lines.append(f"{name:<30}{r['status']['state']:>10}{mib(r['peak']['planner']):>17.1f}"
                     f"{mib(r['peak']['bridge']):>16.1f}{at['planner']:>26}{at['bridge']:>25}")
    lines += ["", NOTES.format(cpus=os.cpu_count())]
    text = "\n".join(lines)
    print(text)
    name = "memory" + (f"_plate{args.long}" if args.long else "") + (f"_raster{args.raster}" if args.raster else "")
    write_result(f"{name}.txt", text)
    return 0


NOTES = """\
Notes ({cpus} CPUs, shared with other work).
(a) RSS: VmRSS of the process from /proc after the import; Python heap: what tracemalloc
  counts as held after it (Python objects and numpy buffers; shared libraries and C/C++
  allocations are in RSS only). The drive model's kernel is a C function compiled by
  cnc_servo_bridge's setup.py at install time (cnc_servo_bridge/_drive_kernel.c).
(b) peak: VmHWM of the node process, polled at every job_status (every 0.5 s of machine
  time) and at the end; RSS @n %: VmRSS when job_status first reported n % progress. Long
  drill jobs are planned in segments while they run (cnc_planner/segments.py), so the
  planner's memory should not grow with the job."""


if __name__ == "__main__":
    sys.exit(main())
