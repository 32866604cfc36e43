"""What a user waits for, end to end (issue 43): every console script's --help, cnc-plan of a
one-move job and of a 300-hole plate, cnc-run of that plate (start-up, simulation over
topics, report) and cnc-analyze of its bag. Each is a fresh process timed on the wall clock
as the shell runs it, the best of --repeat runs (the machine is shared: the best is the
least disturbed); the in-process figures of load.py leave out the start-up this measures.

Goals: --help <= 0.3 s, a one-move plan <= 0.6 s. Kept in bench/results/startup.txt.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from importlib.metadata import entry_points
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
BIN = Path(sys.executable).parent
PACKAGES = ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")
HELP_GOAL_S, ONE_MOVE_GOAL_S = 0.3, 0.6
sys.path.insert(0, str(HERE))


def best_of(command: list[str], repeat: int, env: dict[str, str] | None = None) -> float:
    """The shortest wall time of ``repeat`` runs of ``command`` (each must exit 0)."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        best = min(best, time.perf_counter() - start)
    return best


def one_move_doc() -> dict:
    return {"schema": "cnc_job/1", "job_id": "one-move", "kind": "move", "machine": "mill3",
            "tool": {"length": 0.0, "diameter": 6.0}, "setup": {"origin": [0, 0, 0], "rotation_deg": [0, 0, 0]},
            "spindle_rpm": 0, "move": [{"linear": {"x": 10.0}, "feed": 1200}]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per row; the best is kept")
    parser.add_argument("--no-plate", action="store_true", help="skip the plate's cnc-run and cnc-analyze rows")
    parser.add_argument("--out", type=Path, default=RESULTS / "startup.txt")
    args = parser.parse_args()
    from load import drill_doc  # the 300-hole plate of load.py and memory.py

    scripts = sorted(ep.name for ep in entry_points(group="console_scripts")
                     if ep.dist is not None and ep.dist.name in PACKAGES)
    rows = [(f"{name} --help", best_of([str(BIN / name), "--help"], args.repeat), HELP_GOAL_S) for name in scripts]
    print("\n".join(f"  {r[0]}: {r[1]:.3f} s" for r in rows), flush=True)
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "ROS_DOMAIN_ID": os.environ.get("ROS_DOMAIN_ID") or "44"}
    notes = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        jobs = {"one-move job": one_move_doc(), "plate 300 holes": drill_doc(300)}
        for name, doc in jobs.items():
            path = tmp / f"{doc['job_id']}.json"
            path.write_text(json.dumps(doc))
            for option in ([], ["--compress"]):
                label = f"cnc-plan {name}" + (" --compress" if option else "")
                took = best_of([str(BIN / "cnc-plan"), str(path), "--out", str(tmp / "plan"), *option], args.repeat)
                rows.append((label, took, ONE_MOVE_GOAL_S if name == "one-move job" and not option else None))
                size = (tmp / "plan" / "setpoints.npz").stat().st_size
                notes.append(f"  {label}: setpoints.npz {size / 2**20:.2f} MiB")
                print(f"  {label}: {took:.3f} s", flush=True)
        if not args.no_plate:
            path = tmp / "plate.json"
            path.write_text(json.dumps(jobs["plate 300 holes"]))
            out = tmp / "run"
            start = time.perf_counter()
            subprocess.run([str(BIN / "cnc-run"), str(path), "--out", str(out)], check=True,
                           stdout=subprocess.DEVNULL, env=env)
            took = time.perf_counter() - start
            machine_s = json.loads((out / "report.json").read_text())["cycle_time_s"]
            rows.append(("cnc-run plate 300 holes (once)", took, None))
            notes.append(f"  cnc-run plate 300 holes: {machine_s:.1f} s of machining in {took:.1f} s, "
                         f"{machine_s / took:.1f}x real time end to end")
            print(f"  cnc-run plate: {took:.2f} s", flush=True)
            rows.append(("cnc-analyze plate 300 holes", best_of(
                [str(BIN / "cnc-analyze"), str(out / "bag"), "--out", str(tmp / "report.json")], args.repeat), None))
    load = os.getloadavg()[0]
    lines = [f"start-up and end-to-end wall times, best of {args.repeat} (one run for cnc-run); "
             f"{os.cpu_count()} CPUs, load average {load:.1f}",
             f"{'what':<44}{'wall s':>8}{'goal s':>8}", "-" * 60]
    lines += [f"{what:<44}{took:>8.3f}{'' if goal is None else f'{goal:>8.1f}'}"
              + ("" if goal is None or took <= goal else "  over") for what, took, goal in rows]
    text = "\n".join(lines + [""] + notes) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
