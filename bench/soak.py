"""Soak: a 10,000-hole drill job and a 1-hour move program streamed through both nodes.

Each job runs as cnc-run runs it (bridge in simulation mode as the clock, planner on sim
time, every topic recorded to MCAP), then the recording is checked:
- every joint_trajectory chunk starts one period after the previous one ends: none
  lost, repeated or overlapping;
- every 1 kHz joint_states sample is in the bag: none missing, longest gap one period;
- job_status carried progress all along (monotonic, counts of holes / moves passed);
- the job succeeded, and on the drill job every hole is safe on the feedback
  (drill_analysis: the tip below R only with X/Y on the hole);
- peak RSS (VmHWM) of the planner and bridge processes, and their RSS at 10 %, 50 % and
  100 % of the job, to show it does not grow with the job.
Run from the workspace root:  python bench/soak.py   (about 7 minutes on 2 idle CPUs;
`--quick` runs both jobs cut to a tenth, `--only plate|raster` one of them, `--real-time`
a 10-minute raster with the bridge on the wall clock at 1x, where nothing holds the clock
back for the recorder). Writes bench/results/soak.txt (soak_<options>.txt for the variants).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.job import load_job_file, parse_job  # noqa: E402
from cnc_msgs_py.machine import load_machine  # noqa: E402
from load import feedback_continuity, vm_hwm_kib  # noqa: E402
from publish import RESULTS, write_result  # noqa: E402

JOBS = ROOT / "config" / "jobs"
PERIOD_NS = 1_000_000
REAL_TIME_LINES = 148  # the raster's strokes for about 10 minutes of machine time


def plate_doc(side: int) -> dict:
    """A perforated plate: side x side holes, 5 mm pitch, 1.5 mm deep, drilled row by row."""
    doc = load_job_file(JOBS / "drill_row.yaml")
    doc["job_id"] = f"plate-{side * side}"
    doc["drill"].update(holes=[[-250 + 5 * (i % side), -250 + 5 * (i // side)] for i in range(side * side)],
                        depth=1.5, r_gap=1.0, feed=1500)
    return doc


def raster_doc(lines: int) -> dict:
    """A finishing raster over a face: 40 mm strokes at 600 mm/min, 0.25 mm step-over."""
    moves: list[dict] = [{"rapid": {"x": -20, "y": -100, "z": 1}}, {"linear": {"z": -0.2}, "feed": 300}]
    for i in range(lines):
        moves.append({"linear": {"x": 20 if i % 2 == 0 else -20}, "feed": 600})
        moves.append({"linear": {"y": -100 + 0.25 * (i + 1)}, "feed": 600})
    moves.append({"rapid": {"z": 5}})
    return {"schema": "cnc_job/1", "job_id": f"raster-{lines}", "kind": "move", "machine": "mill3",
            "spindle_rpm": 8000, "move": moves}


def run(doc: dict, out: Path, simulation: bool = True) -> dict:
    """The job through both nodes, recorded; node memory polled along the way."""
    from cnc_planner.runner import Session, local_dds_env

    procs: dict = {}
    peak = {"planner": 0, "bridge": 0}
    rss_at: dict[int, dict[str, int]] = {}
    last = {"progress": 0.0}

    def poll(status: dict | None = None) -> None:
        for name, proc in procs.items():
            peak[name] = max(peak[name], vm_hwm_kib(proc.pid))
        progress = (status or {}).get("progress", 0.0) or 0.0
        for mark in (10, 50, 100):
            if mark not in rss_at and progress * 100 >= mark - 0.5:
                rss_at[mark] = {n: vm_hwm_kib(p.pid, "VmRSS") for n, p in procs.items()}
        if progress >= last["progress"] + 0.05:
            last["progress"] = progress
            print(f"  {doc['job_id']}: {progress * 100:.0f} %  ({status.get('detail')})", flush=True)

    env = local_dds_env(int(os.environ.get("ROS_DOMAIN_ID") or 0) or 43)
    with Session(doc["machine"], out, simulation=simulation, env=env, progress=poll) as session:
        procs.update(session.procs)
        sim0, wall0 = session.recorder.sim_ns, time.monotonic()
        session.submit(json.dumps(doc))
        status = session.wait(doc["job_id"], 6 * 3600)
        wall = time.monotonic() - wall0
        sim = (session.recorder.sim_ns - sim0) / 1e9
        poll(status)
        session.settle(status)
    return {"status": status, "machine_s": sim, "wall_s": wall, "peak": peak, "rss_at": rss_at}


def check_recording(bag: Path) -> dict:
    """Chunk and feedback continuity and the progress reports, streamed from the bag."""
    from rosbags.highlevel import AnyReader
    from cnc_msgs_py.header_bytes import read_stamp
    from cnc_analysis.recording import TYPESTORE

    chunks = gaps = overlaps = points = 0
    previous_end = None
    feedback_t: list[int] = []
    progress: list[float] = []
    detail: dict = {}
    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        conns = [c for c in reader.connections if c.topic.endswith(("joint_trajectory", "job_status", "joint_states"))]
        for conn, _, raw in reader.messages(connections=conns):
            if conn.topic.endswith("joint_states"):  # millions: the stamp read from the CDR, not deserialised
                feedback_t.append(read_stamp(raw))
                continue
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic.endswith("job_status"):
                status = json.loads(msg.data)
                if status["state"] == "running":
                    progress.append(status["progress"])
                    detail = status.get("detail") or detail
                continue
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            end = stamp + (len(msg.points) - 1) * PERIOD_NS
            if previous_end is not None:
                step = stamp - previous_end
                gaps += step > PERIOD_NS
                overlaps += step < PERIOD_NS
            previous_end = end
            chunks += 1
            points += len(msg.points)
    stamps = np.sort(np.array(feedback_t, dtype=np.int64))
    continuity = (feedback_continuity((stamps - stamps[0]) * 1e-9, PERIOD_NS * 1e-9) if len(stamps) > 1
                  else {"missing": 0, "gap_ms": 0.0})
    return {"chunks": chunks, "points": points, "gaps": gaps, "overlaps": overlaps,
            "feedback_samples": len(feedback_t), "feedback_missing": continuity["missing"],
            "longest_gap_ms": continuity["gap_ms"],
            "statuses": len(progress), "monotonic": bool(np.all(np.diff(progress) >= 0)),
            "last_progress": progress[-1] if progress else 0.0, "detail": detail}


def drill_safety(bag: Path, doc: dict) -> dict:
    """Every hole judged on the recorded feedback."""
    from cnc_planner.kinds.drill.block import drill_cycle
    from cnc_planner.kinematics import Kinematics
    from cnc_analysis.drilling import analyze_drilling
    from cnc_analysis.recording import read_run

    machine = load_machine(doc["machine"])
    job = parse_job(doc)
    cycle = drill_cycle(job, machine, Kinematics(machine, job.setup, job.tool))
    run = read_run(bag)
    x, y, z = (run.feedback[:, run.column(j)] for j in ("x", "y", "z"))
    result = analyze_drilling(run.feedback_t, x, y, z, cycle.holes, cycle.r_z, cycle.xy_tolerance, cycle.surface_z)
    return {"holes": len(result["holes"]), "violations": result["safety_violations"],
            "feedback_samples": len(run.feedback_t)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="both jobs cut to a tenth (a smoke run)")
    parser.add_argument("--only", choices=("plate", "raster"), help="run one of the two jobs")
    parser.add_argument("--real-time", action="store_true", help="a 10-minute raster at 1x on the wall clock")
    parser.add_argument("--keep", type=Path, help="keep the recordings in this folder (one bag per job)")
    args = parser.parse_args()
    jobs = [plate_doc(32 if args.quick else 100), raster_doc(88 if args.quick else 880)]
    jobs = [doc for doc in jobs if args.only is None or doc["job_id"].startswith(args.only)]
    if args.real_time:
        jobs = [raster_doc(REAL_TIME_LINES)]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for doc in jobs:
            bag = (args.keep or Path(tmp)) / doc["job_id"]
            print(f"running {doc['job_id']}", flush=True)
            result = run(doc, bag, simulation=not args.real_time)
            print(f"  checking the recording of {doc['job_id']}", flush=True)
            result["check"] = check_recording(bag)
            if args.real_time:  # no /clock: the machine time is the span of the recorded feedback
                result["machine_s"] = result["check"]["feedback_samples"] * PERIOD_NS / 1e9
            if doc["kind"] == "drill":
                result["safety"] = drill_safety(bag, doc)
            rows.append((doc, result))
    text = table(rows, "real time, 1x on the wall clock" if args.real_time else "quick: a tenth of each job"
                 if args.quick else "full, simulation")
    before = RESULTS / "soak_before_issue18.txt"
    if not (args.quick or args.only or args.real_time):  # the figures before the speed work (issue 18)
        text += "\n\n" + "=" * 108 + f"\nBefore issue 18 (kept from {before.name}):\n\n" + before.read_text().rstrip()
    print(text)
    name = ("soak" + ("_quick" if args.quick else "") + (f"_{args.only}" if args.only else "")
            + ("_real_time" if args.real_time else ""))
    write_result(f"{name}.txt", text)
    return 0


def table(rows: list[tuple[dict, dict]], mode: str) -> str:
    mib = lambda kib: kib / 1024  # noqa: E731
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    lines = [f"Soak ({mode}; {os.cpu_count()} CPUs, load average {os.getloadavg()[1]:.1f} at the end; "
             f"commit {commit.stdout.strip() or 'unknown'})", "",
             f"{'job':<14}{'state':>10}{'machine s':>10}{'wall s':>8}{'x real':>7}{'chunks':>8}{'gaps':>5}"
             f"{'overl.':>7}{'statuses':>9}{'mono':>5}{'samples':>10}{'missing':>8}{'gap ms':>7}", "-" * 108]
    for doc, r in rows:
        c = r["check"]
        lines.append(f"{doc['job_id']:<14}{r['status']['state']:>10}{r['machine_s']:>10.1f}{r['wall_s']:>8.0f}"
                     f"{r['machine_s'] / r['wall_s']:>7.2f}{c['chunks']:>8}{c['gaps']:>5}{c['overlaps']:>7}"
                     f"{c['statuses']:>9}{'yes' if c['monotonic'] else 'NO':>5}{c['feedback_samples']:>10}"
                     f"{c['feedback_missing']:>8}{c['longest_gap_ms']:>7.1f}")
    lines += ["", f"{'job':<14}{'node':>8}{'peak MiB':>10}{'RSS@10%':>9}{'RSS@50%':>9}{'RSS@100%':>9}", "-" * 59]
    for doc, r in rows:
        for node in ("planner", "bridge"):
            at = [mib(r["rss_at"].get(m, {}).get(node, 0)) for m in (10, 50, 100)]
            lines.append(f"{doc['job_id']:<14}{node:>8}{mib(r['peak'][node]):>10.1f}"
                         + "".join(f"{v:>9.1f}" for v in at))
    lines.append("")
    for doc, r in rows:
        c = r["check"]
        lines.append(f"{doc['job_id']}: last progress {c['last_progress']:.3f}, counts {c['detail']}")
        if "safety" in r:
            s = r["safety"]
            lines.append(f"{doc['job_id']}: {s['holes']} holes judged on {s['feedback_samples']} recorded feedback "
                         f"samples: {s['violations']} samples below R with X/Y off the hole")
    lines += ["", NOTES]
    return "\n".join(lines)


NOTES = """\
gaps / overl.: chunks whose first stamp is more (lost points) or less (repeated or
  overlapping points) than one period after the previous chunk's last point, in the
  order the recorder received them.
samples / missing / gap ms: joint_states samples in the bag, how many of the 1 kHz
  samples between the first and the last are not, and the longest step between two
  recorded stamps (1.0 ms: none missing).
statuses: running job_status messages recorded (every 0.5 s of machine time);
  mono: their progress never went back.
RSS@n%: resident memory of the node process when job_status first reported n %
  progress; peak: VmHWM. Long jobs are planned in segments ahead of the stream
  (cnc_planner/segments.py, lookahead.py), so the planner holds a few segments, not
  the job.
x real: machine time / wall time of the whole loop (bridge stepping in lockstep with
  the setpoints, planner, DDS and the Python recorder writing every topic; the
  recorder holds the bridge's clock back when it falls behind, RECORDER_WINDOW_NS)."""


if __name__ == "__main__":
    sys.exit(main())
