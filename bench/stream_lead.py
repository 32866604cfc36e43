"""The stream's margin while goals are planned beside a running real-time job, under load.

As `make stress` loads the host (two busy processes and the rest of the suite): a 300 s
move on mill3 in real time (canceled at the end), and path goals of --points points
planned beside it one after the other (each canceled once accepted). Judged from the
recording alone: for each goal's planning, the longest wait between two chunks and the
thinnest lead (how far the setpoints received reached beyond the moment the next chunk
arrived; the first second left out, where the stream climbs from its lookahead to the
planning one), and any alarm of the bridge.

Usage: python bench/stream_lead.py [--paths 4] [--points 8000]
Writes bench/results/stream_lead.txt. Not part of make bench: about 5 minutes.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from publish import write_result
from stress_real_time import stress_load

from cnc_analysis.recording import read_run
from cnc_analysis.summary import stream_leads
from cnc_planner.executive import Settings
from cnc_planner.runner import Session, local_dds_env

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))  # the starvation test's goals
from zigzag_paths import zigzag_path  # noqa: E402

CLIMB_S = 1.0  # s after a goal arrives when the stream has reached the planning lookahead
RUNNING = {"schema": "cnc_job/1", "job_id": "running", "kind": "move", "machine": "mill3",
           "move": [{"rapid": {"x": 20.0}}, {"linear": {"x": 0.0}, "feed": 4}]}  # 300 s


def plan_beside(bag: Path, paths: int, points: int) -> list[tuple[float, float]]:
    """Run the job and plan the goals beside it; returns each goal's planning (s, bag time)."""
    windows = []
    with Session("mill3", bag, simulation=False, env=local_dds_env(215)) as session:
        statuses = session.recorder.statuses
        session.submit(json.dumps(RUNNING))
        session.spin_until(lambda: any(s["job_id"] == "running" and s["state"] == "running" for s in statuses),
                           30, "the running job did not start")
        for k in range(paths):
            start = session.recorder.feedback_ns
            session.submit(json.dumps(zigzag_path(f"path-{k}", k, points)))
            session.spin_until(lambda: any(s["job_id"] == f"path-{k}" for s in statuses), 300,
                               f"path-{k} was not answered")
            windows.append((start / 1e9, session.recorder.feedback_ns / 1e9))
            session.cancel(f"path-{k}")
        session.cancel("running")
        final = session.wait("running", 60)
    if final["reason"] != "canceled by request":
        raise RuntimeError(f"the running job ended before the goals were planned: {final['state']} {final['reason']}")
    return windows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=4)
    parser.add_argument("--points", type=int, default=8000)
    args = parser.parse_args()
    with stress_load(dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"), limit=1800.0):
        with tempfile.TemporaryDirectory() as tmp:
            windows = plan_beside(Path(tmp) / "bag", args.paths, args.points)
            run = read_run(Path(tmp) / "bag")
    arrived, lead = stream_leads(run)
    ahead = Settings().planning_lookahead_ns / 1e9
    lines = [f"Paths of {args.points} points planned one after the other beside a 300 s real-time move on "
             f"mill3 (lookahead while planning {ahead:.1f} s), beside two busy processes and the rest of the suite.",
             "", "| goal | planning (s) | chunks | longest wait between chunks (s) | thinnest lead (s) |",
             "|---|---|---|---|---|"]
    for k, (start, end) in enumerate(windows):
        inside = (arrived >= start) & (arrived <= end)
        settled = inside & (arrived >= start + CLIMB_S)
        waits = np.diff(arrived[inside])
        lines.append(f"| path-{k} | {end - start:.1f} | {int(inside.sum())} | "
                     f"{waits.max() if len(waits) else float('nan'):.3f} | "
                     f"{lead[settled].min() if settled.any() else float('nan'):.3f} |")
    lines += ["", f"bridge alarms: {sorted(set(run.alarms)) or 'none'}"]
    print("\n".join(lines))
    write_result("stream_lead.txt", "\n".join(lines))
    return 1 if run.alarms else 0


if __name__ == "__main__":
    sys.exit(main())
