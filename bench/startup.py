"""What a user waits for, end to end (issue 43): every console script's --help, cnc-plan of a
one-move job and of a 300-hole plate, cnc-run of that plate (start-up, simulation over
topics, report) and cnc-analyze of its bag. Each is a fresh process timed on the wall clock
as the shell runs it, the best of --repeat runs (the machine is shared: the best is the
least disturbed); the in-process figures of load.py leave out the start-up this measures.

Goals: --help <= 0.3 s, a one-move plan <= 0.6 s, cnc-run of the plate at 12x real time or
more end to end, cnc-analyze of its bag <= 2 s. cnc-run's row adds where its time goes:
the CPU seconds of each process (cnc-run's recorder and report, the bridge, the planner,
and what cnc-run forks). Kept in bench/results/startup.txt.
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
RUN_GOAL_X, ANALYZE_GOAL_S = 12.0, 2.0  # cnc-run of the plate: times real time; cnc-analyze of its bag
TICK = os.sysconf("SC_CLK_TCK")
sys.path.insert(0, str(HERE))


def best_of(command: list[str], repeat: int, env: dict[str, str] | None = None) -> float:
    """The shortest wall time of ``repeat`` runs of ``command`` (each must exit 0)."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        best = min(best, time.perf_counter() - start)
    return best


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of a running process so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def _children(pid: int) -> list[int]:
    children = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(c) for c in children.read_text().split()] if children.exists() else []


def run_watched(command: list[str], env: dict[str, str]) -> tuple[float, dict[str, float]]:
    """Wall time of ``command`` (must exit 0) and the CPU seconds of it and of each process
    it starts (by the module it runs: the bridge and planner nodes), read from /proc every
    0.1 s until each ends: where an end-to-end run's time goes."""
    cpu: dict[int, tuple[str, float]] = {}
    start = time.perf_counter()
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, env=env)
    while proc.poll() is None:
        for pid in [proc.pid, *_children(proc.pid)]:
            try:
                if pid not in cpu:  # named once: an ended process (a zombie) has no command line
                    cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
                    cpu[pid] = (next((a.decode().rsplit(".", 1)[-1] for a in cmdline[1:3] if a.startswith(b"cnc_")),
                                     Path(command[0]).name + ("" if pid == proc.pid else " (forked)")), 0.0)
                cpu[pid] = (cpu[pid][0], _cpu_s(pid))
            except (OSError, IndexError):
                pass  # ended between listing and reading: its last reading stands
        time.sleep(0.1)
    took = time.perf_counter() - start
    if proc.returncode != 0:
        raise subprocess.CalledProcessError(proc.returncode, command)
    by_name: dict[str, float] = {}
    for name, seconds in cpu.values():
        by_name[name] = by_name.get(name, 0.0) + seconds
    return took, by_name


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
            runs = []
            for k in range(args.repeat):
                out = tmp / f"run{k}"
                runs.append((*run_watched([str(BIN / "cnc-run"), str(path), "--out", str(out)], env), out))
            took, cpu, out = min(runs, key=lambda r: r[0])
            machine_s = json.loads((out / "report.json").read_text())["cycle_time_s"]
            rows.append(("cnc-run plate 300 holes", took, machine_s / RUN_GOAL_X))
            notes.append(f"  cnc-run plate 300 holes: {machine_s:.1f} s of machining in {took:.1f} s, "
                         f"{machine_s / took:.1f}x real time end to end (goal {RUN_GOAL_X:g}x)")
            notes.append("  where its time goes, CPU s per process (2 CPUs: at most 2 s of CPU per s of wall): "
                         + ", ".join(f"{name} {seconds:.1f}" for name, seconds in cpu.items()))
            print(f"  cnc-run plate: {took:.2f} s", flush=True)
            rows.append(("cnc-analyze plate 300 holes", best_of(
                [str(BIN / "cnc-analyze"), str(out / "bag"), "--out", str(tmp / "report.json")], args.repeat),
                ANALYZE_GOAL_S))
    load = os.getloadavg()[0]
    lines = [f"start-up and end-to-end wall times, best of {args.repeat}; "
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
