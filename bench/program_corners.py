"""The new G-code methods of issue 42 on the corners of the drives' tolerance: each oracle
program planned once on the described machine, then judged (build_report, each operation by
its own judge) on the drive model's predicted feedback of every tolerance corner
(cnc_msgs_py.plant.tolerance_corners, the k-th corner of every named joint together, as
src/cnc_planner/test/test_turn_tolerance.py pairs them). A verdict that fails here is a
plant inside the stated tolerance that the plan does not hold: the planner's margins, not
the judge, must grow.

Usage: bench/program_corners.py     (prints the table; bench/results/program_corners.txt keeps it)
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.gcode.document import job_document  # noqa: E402
from cnc_msgs_py.job import parse_job  # noqa: E402
from cnc_msgs_py.machine import Machine, load_machine  # noqa: E402
from cnc_msgs_py.plant import Plant, tolerance_corners  # noqa: E402
from cnc_planner.planning import plan_job  # noqa: E402
from cnc_planner.report import build_report, predicted_run  # noqa: E402

# (program, what it shows, the joints whose tolerance is walked, the report section judged)
CASES = [
    ("path_tolerance_g64.ngc", "G64 P0.02 path", ("x", "y", "z"), "kinematics"),
    ("lathe_g72.ngc", "G72 facing", ("x", "z"), "turn"),
    ("lathe_g76_taper.ngc", "G76 tapered ends", ("x", "z", "spindle"), "thread"),
    ("lathe_g33.ngc", "G33 passes", ("x", "z", "spindle"), "spindle_sync"),
    ("mill_g33_1.ngc", "G33.1 rigid tap", ("z", "spindle"), "spindle_sync"),
    ("drill_after_rapids.ngc", "G81 after rapids", ("x", "y", "z"), "drill"),
]


def corners(machine: Machine, joints: tuple[str, ...]) -> list[Plant]:
    """The described drives with the k-th tolerance corner of every joint in ``joints``."""
    each = [tolerance_corners(machine.drives[j]) for j in joints]
    return [Plant(f"corner {k}", {**machine.drives, **{j: c[k % len(c)] for j, c in zip(joints, each)}})
            for k in range(max(len(c) for c in each))]


def judged(name: str, joints: tuple[str, ...], key: str) -> tuple[int, list[str]]:
    """How many operation verdicts were judged over the corners, and the failed ones' words."""
    path = ROOT / "test" / "gcode_oracle" / name
    doc = job_document(path)
    machine = load_machine(doc["machine"])
    plan = plan_job(parse_job(doc), machine, machine.home_joints)  # from where cnc-run starts
    verdicts = []
    for plant in corners(machine, joints):
        report = build_report(predicted_run(doc, plan, machine, plant=plant), machine)
        verdicts += [(plant.name, op[key]["verdict"]) for op in report["program"]["operations"] if key in op]
    return len(verdicts), [f"{corner}: {v['says']}" for corner, v in verdicts if not v["passed"]]


def main() -> int:
    print(f"{'program':26s} {'method':18s} {'judged':>6s} {'failed':>6s}  the first failure")
    for name, what, joints, key in CASES:
        count, failed = judged(name, joints, key)
        print(f"{name:26s} {what:18s} {count:6d} {len(failed):6d}  {failed[0][:110] if failed else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
