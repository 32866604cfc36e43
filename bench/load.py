"""Load benchmarks: planning speed, simulation speed over topics, chunk lead, memory.

(a) plan_job wall time and "x real time" (planned duration / wall) for a move job, drill
    jobs of 100 and 1000 holes (10,000 only if the measured scaling says it finishes in
    about two minutes), and a thread job;
(b) jobs run through both nodes over topics (as cnc-run does: bridge in simulation mode,
    planner on sim time, everything recorded): machine time / wall time, peak RSS
    (VmHWM) of the planner and bridge processes polled while they run, chunks lost;
(c) chunk lead on loopback, from the same recordings;
(d) peak Python heap (tracemalloc) of plan_job versus job length;
(e) CPU share of the bridge (simulation:=false) and the planner in real time at 1x, over a
    shipped mill job and a shipped lathe job, beside the figures before issue 27.
Run from the workspace root (ROS sourced, as for the tests):  python bench/load.py
(a few minutes). Writes the table to bench/results/load.txt as well; with --over-topics
only (b) and (c) are run again and replaced in it, with --planning only (a), with
--real-time only (e).
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]

from cnc_msgs_py.heap import keep_freed_memory  # noqa: E402
from cnc_msgs_py.job import job_id_of, load_job_file, parse_job  # noqa: E402
from cnc_msgs_py.machine import load_machine  # noqa: E402
from cnc_planner.planning import plan_job  # noqa: E402
from cnc_planner.segments import plan_segments  # noqa: E402
from cnc_planner.kinds.drill import SEGMENT_HOLES  # noqa: E402
from cnc_servo_bridge.drive import warm_up  # noqa: E402
from publish import RESULTS, write_result  # noqa: E402

JOBS = ROOT / "config" / "jobs"
SEGMENTED_HOLES = 2000  # a long drill job planned as the node plans it: segment by segment
PLAN_RUNS = 3  # each planning row is the fastest of this many runs: the CPUs are shared


def drill_doc(holes: int) -> dict:
    """The drill_row job with ``holes`` holes on a 10 mm grid, 80 to a row, inside the travel."""
    doc = load_job_file(JOBS / "drill_row.yaml")
    doc["job_id"] = f"drill-{holes}"
    doc["drill"]["holes"] = [[-400 + 10 * (i % 80), -250 + 10 * (i // 80)] for i in range(holes)]
    return doc


def move_doc(moves: int) -> dict:
    """A move job of ``moves`` 10 mm feed moves back and forth along X at 1200 mm/min."""
    doc = load_job_file(JOBS / "move_mill3.yaml")
    doc["job_id"] = f"move-{moves}"
    doc["move"] = [{"linear": {"x": 10.0 * (i % 2)}, "feed": 1200} for i in range(1, moves + 1)]
    return doc


def plan(doc: dict, period: float | None = 0.001):
    """plan_job and sampling every setpoint (unless period is None), as cnc-plan does
    (after the drive kernel is loaded, as the planner node loads it at its start)."""
    result, wall, _ = timed_plan(doc, period)
    return result, wall


def timed_plan(doc: dict, period: float | None = 0.001):
    """plan's result, its wall time and its CPU time (this process)."""
    machine = load_machine(doc["machine"])
    job = parse_job(doc)
    warm_up()
    start, cpu = time.perf_counter(), time.process_time()
    result = plan_job(job, machine)
    if period is not None:
        result.sample(np.arange(int(np.ceil(result.duration / period)) + 1) * period)
    return result, time.perf_counter() - start, time.process_time() - cpu


def best_plan(doc: dict, runs: int = PLAN_RUNS):
    """timed_plan of the run with the least wall time out of ``runs``."""
    return min((timed_plan(doc) for _ in range(runs)), key=lambda run: run[1])


def plan_in_segments(doc: dict) -> tuple[float, float, float]:
    """Plan time of all segments, wall time to the first one and to the last one."""
    machine = load_machine(doc["machine"])
    start = time.perf_counter()
    duration, first = 0.0, None
    for segment in plan_segments(parse_job(doc), machine):
        first = time.perf_counter() - start if first is None else first
        duration += segment.duration
    return duration, first, time.perf_counter() - start


def planning_rows() -> tuple[list[tuple], list[str]]:
    from soak import plate_doc  # soak imports this module

    keep_freed_memory()  # the allocator as cnc-plan and the planner node set it
    notes = []
    cases = [*((name, load_job_file(JOBS / name)) for name in
               ("move_mill3.yaml", "path_mill3.yaml", "lathe_feed_vibration.yaml")),
             ("move 1000 feeds", move_doc(1000)),
             ("drill 100 holes", drill_doc(100)), ("drill 1000 holes", drill_doc(1000)),
             ("plate 10000 holes", plate_doc(100))]
    rows = []
    for name, doc in cases:
        p, wall, cpu = best_plan(doc)
        rows.append((name, p.duration, wall, cpu, p.duration / wall))
        print(f"  planned {name}: {wall:.2f} s", flush=True)
    segmented, first, wall = min((plan_in_segments(drill_doc(SEGMENTED_HOLES)) for _ in range(PLAN_RUNS)),
                                 key=lambda run: run[2])
    rows.append((f"drill {SEGMENTED_HOLES} holes, segments", segmented, wall, None, segmented / wall))
    notes.append(f"drill {SEGMENTED_HOLES} holes, segments: the first segment ({SEGMENT_HOLES} holes, what a goal "
                 f"waits for before it is accepted) planned in {first:.2f} s; the rest is planned while the job "
                 f"runs, {segmented / wall:.1f}x faster than the machine drills it.")
    for name in ("thread_m12.yaml", "thread_m16.yaml"):
        p, wall, cpu = best_plan(load_job_file(JOBS / name))
        rows.append((name, p.duration, wall, cpu, p.duration / wall))
    notes.append(f"each row: the fastest (wall) of {PLAN_RUNS} runs; cpu s: the process time of that run, x on "
                 f"cpu: plan s / cpu s (the {os.cpu_count()} CPUs are shared: wall above cpu is time the planner "
                 "waited for a CPU); the allocator keeps freed memory, as cnc-plan and the nodes set it "
                 "(cnc_msgs_py.heap).")
    return rows, notes


def planning_section(plan_rows: list[tuple], notes: list[str]) -> list[str]:
    """Section (a) of the results, as lines."""
    lines = ["(a) planning speed: plan_job, one process",
             f"{'job':<26}{'plan s':>10}{'wall s':>10}{'cpu s':>9}{'x real time':>13}{'x on cpu':>10}", "-" * 78]
    lines += [f"{n:<26}{d:>10.2f}{w:>10.3f}{'' if c is None else f'{c:.3f}':>9}{x:>13.1f}"
              f"{'' if c is None else f'{d / c:.1f}':>10}".rstrip() for n, d, w, c, x in plan_rows]
    return lines + [f"  {n}" for n in notes]


def rerun_planning() -> int:
    """Section (a) only, written over the (a) section of the kept results."""
    lines = planning_section(*planning_rows())
    path = RESULTS / "load.txt"
    old = path.read_text().splitlines()
    end = next(i for i, line in enumerate(old) if line.startswith("(b) "))  # the sections after (a), as kept
    text = "\n".join(lines + [""] + old[end:])
    print("\n".join(lines))
    write_result("load.txt", text)
    return 0


def vm_hwm_kib(pid: int, field: str = "VmHWM") -> int:
    """A memory figure of a process from /proc (VmHWM: peak RSS; VmRSS: RSS now), KiB."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(f"{field}:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def cpu_s(pid: int) -> float:
    """CPU time (user + system) a process has used so far, s, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def simulate(job_file: str, out: Path, doc: dict | None = None) -> dict:
    """One job over topics, as cnc-run: sim speed, node peak RSS, chunks lost, chunk lead."""
    from cnc_planner.runner import Session, local_dds_env
    from cnc_analysis.summary import chunks_lost
    from cnc_analysis.recording import read_run

    doc = doc or load_job_file(JOBS / job_file)
    job_id = job_id_of(doc)
    peak = {"planner": 0, "bridge": 0}
    procs: dict = {}

    def poll(_status: dict | None = None) -> None:
        for name, proc in procs.items():
            peak[name] = max(peak[name], vm_hwm_kib(proc.pid))

    env = local_dds_env(int(os.environ.get("ROS_DOMAIN_ID") or 0) or 42)
    with Session(doc["machine"], out / "bag", env=env, progress=poll) as session:
        procs.update(session.procs)
        sim0, wall0 = session.recorder.sim_ns, time.monotonic()
        cpu0 = {"recorder": time.process_time(), **{name: cpu_s(p.pid) for name, p in procs.items()}}
        session.submit(json.dumps(doc))
        status = session.wait(job_id, 900)
        wall = time.monotonic() - wall0
        sim = (session.recorder.sim_ns - sim0) / 1e9
        cpu = {"recorder": time.process_time(), **{name: cpu_s(p.pid) for name, p in procs.items()}}
        poll()
    run = read_run(out / "bag")
    return {"job": job_file, "state": status["state"], "machine_s": sim, "wall_s": wall,
            "speed": sim / wall, "planner_mib": peak["planner"] / 1024, "bridge_mib": peak["bridge"] / 1024,
            "chunks": len(run.chunks), "lost": chunks_lost(run), "lead": chunk_lead(out / "bag"),
            **feedback_continuity(run.feedback_t),
            "cpu": {name: (cpu[name] - cpu0[name]) / sim for name in cpu}, "load": os.getloadavg()[0]}


REAL_TIME_JOBS = ("move_mill3.yaml", "lathe_feed_vibration.yaml")  # one per shipped machine kind
REAL_TIME_BEFORE = RESULTS / "real_time_before_issue27.txt"  # (e) as measured on main before issue 27


def real_time_share(job_file: str, out: Path, recorded: bool) -> dict:
    """One shipped job in real time at 1x: bridge (simulation:=false) and planner started
    as cnc-run starts them, the job sent as cnc-submit sends it (CncClient) or, ``recorded``,
    as cnc-run and the real-time tests run it (this process recording every topic). Each
    node's CPU time (user + system, /proc) over the wall time from submit to final status."""
    import rclpy
    from cnc_msgs_py.client import CncClient
    from cnc_planner.runner import Session, local_dds_env, node_command

    doc = load_job_file(JOBS / job_file)
    env = local_dds_env(int(os.environ.get("ROS_DOMAIN_ID") or 0) or 42)
    if recorded:
        with Session(doc["machine"], out / "bag", env=env, simulation=False) as session:
            return _share(doc, session.procs, lambda: session.submit(json.dumps(doc)),
                          lambda: session.wait(job_id_of(doc), 120))
    procs = {name: subprocess.Popen(node_command(module, "/cnc", {"machine": doc["machine"], **params}), env=env)
             for name, module, params in (("bridge", "cnc_servo_bridge.bridge_node", {"simulation": False}),
                                          ("planner", "cnc_planner.planner_node", {}))}
    os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE") if k in env})
    rclpy.init()
    node = rclpy.create_node("cnc_bench_submit")
    client = CncClient(node)
    try:
        client.wait_for_planner(30)
        return _share(doc, procs, lambda: client.submit(doc), lambda: client.wait(job_id_of(doc), 120))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        for proc in procs.values():
            proc.send_signal(signal.SIGINT)
            proc.wait(10)


def _share(doc: dict, procs: dict, submit, wait) -> dict:
    """CPU share of each process (and of this one) from ``submit`` until ``wait`` returns."""
    wall0, cpu0, own0 = time.monotonic(), {name: cpu_s(p.pid) for name, p in procs.items()}, time.process_time()
    submit()
    status = wait()
    wall = time.monotonic() - wall0
    share = {name: (cpu_s(p.pid) - cpu0[name]) / wall for name, p in procs.items()}
    share["this"] = (time.process_time() - own0) / wall
    return {"state": status["state"], "wall_s": wall, "share": share, "load": os.getloadavg()[0]}


def real_time_lines(runs: list[dict]) -> list[str]:
    """Table (e), with the figures kept from before issue 27 beside the new ones."""
    before = {}
    if REAL_TIME_BEFORE.exists():
        for line in REAL_TIME_BEFORE.read_text().splitlines():
            if line.startswith("#") or not line.strip():
                continue
            job, how, *numbers = line.split()
            before[job, how] = [float(n) for n in numbers]
    lines = ["(e) CPU share in real time at 1x (bridge simulation:=false, planner): CPU s / wall s of the job",
             f"{'job':<27}{'run as':<12}{'state':>10}{'wall s':>8}{'bridge':>8}{'planner':>9}{'sender':>8}"
             f"{'load avg':>9}  {'before: bridge':>14}{'planner':>8}", "-" * 113]
    for r in runs:
        old = before.get((r["job"], r["how"]))
        lines.append(f"{r['job']:<27}{r['how']:<12}{r['state']:>10}{r['wall_s']:>8.2f}{r['share']['bridge']:>8.3f}"
                     f"{r['share']['planner']:>9.3f}{r['share']['this']:>8.3f}{r['load']:>9.1f}  "
                     + (f"{old[0]:>14.3f}{old[1]:>8.3f}" if old else f"{'-':>14}{'-':>8}"))
    return lines + ["  run as cnc-submit: the job sent by a CncClient, nothing else listening (as the issue measured);",
                    "  cnc-run: this process records every topic as well, as cnc-run and the real-time tests do;",
                    "  sender: this process (client, or recorder). Goals: bridge <= 0.15 of a CPU, planner <= 0.10."]


def real_time_runs() -> list[dict]:
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, job in enumerate(REAL_TIME_JOBS):
            for how in ("cnc-submit", "cnc-run"):
                run = real_time_share(job, Path(tmp) / f"{i}{how}", recorded=how == "cnc-run")
                runs.append({"job": job, "how": how, **run})
                print(f"  {job} {how}: {run}", flush=True)
    return runs


def real_time_only() -> int:
    """--real-time: rerun (e) only and replace it in load.txt."""
    text = (RESULTS / "load.txt").read_text()
    new = "\n".join(real_time_lines(real_time_runs())) + "\n"
    if "(e) CPU share" in text:
        start = text.index("(e) CPU share")
        end = text.index("\n\n", start) + 1
        text = text[:start] + new + text[end:]
    else:
        start = text.index("Notes (")
        text = text[:start] + new + "\n" + text[start:]
    print(text)
    write_result("load.txt", text)
    return 0


def feedback_continuity(feedback_t: np.ndarray, period_s: float = 0.001) -> dict:
    """joint_states samples missing from a recording between its first and last, and the
    longest step between two recorded stamps (ms)."""
    steps = np.diff(feedback_t)
    return {"missing": int(np.sum(np.round(steps / period_s) - 1)), "gap_ms": float(steps.max() * 1e3)}


def chunk_lead(bag: Path) -> np.ndarray:
    """Per chunk: header stamp minus the bridge's time when the recorder received it (s).

    The recorder stamps every message with the latest bridge time it had heard of (/clock
    or joint_states); positive lead = the chunk arrived ahead of its first setpoint."""
    from rosbags.highlevel import AnyReader
    from cnc_analysis.recording import TYPESTORE

    leads = []
    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        conns = [c for c in reader.connections if c.topic.endswith("joint_trajectory")]
        for conn, t_ns, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            leads.append((stamp - t_ns) / 1e9)
    return np.array(leads)


def memory_rows() -> list[tuple]:
    rows = []
    for name, doc in [*((f"move {n} feeds", move_doc(n)) for n in (10, 100, 1000)),
                      *((f"drill {n} holes", drill_doc(n)) for n in (10, 30, 100))]:
        tracemalloc.start()
        p, _ = plan(doc, period=None)  # the plan itself, not an array of every setpoint
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        rows.append((name, p.duration, peak / 2**20))
        print(f"  traced {name}", flush=True)
    tracemalloc.start()
    duration, _, _ = plan_in_segments(drill_doc(1000))  # one segment held at a time
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rows.append(("drill 1000 holes, segments", duration, peak / 2**20))
    return rows


def simulations() -> list[dict]:
    """(b) and (c): the three jobs over topics."""
    sims = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, job in enumerate(("drill_row.yaml", "lathe_feed_vibration.yaml")):
            sims.append(simulate(job, Path(tmp) / str(i)))
        sims.append(simulate("plate 300 holes", Path(tmp) / "plate", drill_doc(300)))
    return sims


def topic_lines(sims: list[dict]) -> list[str]:
    """Tables (b) and (c), ending with a blank line."""
    lines = ["(b) simulation over topics (bridge in simulation mode, planner, recorder; as cnc-run)",
             f"{'job':<28}{'state':>10}{'machine s':>10}{'wall s':>8}{'x real':>8}{'planner MiB':>12}"
             f"{'bridge MiB':>11}{'chunks':>7}{'lost':>5}{'missing':>8}{'gap ms':>7}", "-" * 114]
    lines += [f"{s['job']:<28}{s['state']:>10}{s['machine_s']:>10.2f}{s['wall_s']:>8.2f}{s['speed']:>8.2f}"
              f"{s['planner_mib']:>12.1f}{s['bridge_mib']:>11.1f}{s['chunks']:>7}{s['lost']:>5}"
              f"{s['missing']:>8}{s['gap_ms']:>7.1f}" for s in sims]
    lines += ["", "(b) CPU time per second of machine time (the same runs; load-independent, unlike x real)",
              f"{'job':<28}{'planner':>9}{'bridge':>9}{'recorder':>9}{'sum':>7}{'ceiling on 2 CPUs':>19}"
              f"{'load avg':>10}", "-" * 91]
    lines += [f"{s['job']:<28}{s['cpu']['planner']:>9.3f}{s['cpu']['bridge']:>9.3f}{s['cpu']['recorder']:>9.3f}"
              f"{sum(s['cpu'].values()):>7.3f}{min(2 / sum(s['cpu'].values()), 1 / max(s['cpu'].values())):>18.1f}x"
              f"{s['load']:>10.1f}" for s in sims]
    lines += ["", "(c) chunk lead on loopback (chunk's first stamp - bridge time at the recorder's receipt)",
              f"{'job':<28}{'chunks':>7}{'p50 ms':>9}{'p99 ms':>9}{'min ms':>9}", "-" * 62]
    lines += [f"{s['job']:<28}{len(s['lead']):>7}{np.percentile(s['lead'], 50) * 1e3:>9.1f}"
              f"{np.percentile(s['lead'], 1) * 1e3:>9.1f}{s['lead'].min() * 1e3:>9.1f}" for s in sims]
    return lines + [""]


def over_topics_only() -> int:
    """--over-topics: rerun (b) and (c) only and replace them in load.txt (the latest
    figures, above the kept "before" block); (a) and (d) stay as last measured."""
    text = (RESULTS / "load.txt").read_text()
    start, end = text.index("(b) simulation over topics"), text.index("(d) peak memory")
    text = text[:start] + "\n".join(topic_lines(simulations())) + "\n" + text[end:]
    print(text)
    write_result("load.txt", text)
    return 0


def main() -> int:
    lines = []
    print("(a) planning", flush=True)
    plan_rows, notes = planning_rows()
    print("(b, c) simulation over topics", flush=True)
    sims = simulations()
    print("(d) memory", flush=True)
    mem_rows = memory_rows()
    print("(e) real time", flush=True)
    real_time = real_time_runs()

    lines += planning_section(plan_rows, notes)
    lines += ["", *topic_lines(sims)]
    lines += ["", "(d) peak memory of plan_job versus job length (tracemalloc peak, Python heap)",
              f"{'job':<22}{'plan s':>10}{'peak MiB':>10}", "-" * 42]
    lines += [f"{n:<22}{d:>10.2f}{m:>10.1f}" for n, d, m in mem_rows]
    lines += ["", *real_time_lines(real_time)]
    lines += ["", NOTES.format(cpus=os.cpu_count())]
    before = RESULTS / "load_before_issue18.txt"
    if before.exists():  # the figures before the speed work (issue 18), side by side
        lines += ["", "=" * 99, f"Before issue 18 (kept from {before.name}, measured the same way):", "",
                  before.read_text().rstrip()]
    text = "\n".join(lines)
    print(text)
    write_result("load.txt", text)
    return 0


NOTES = """\
Notes ({cpus} CPUs, shared with other work; wall times vary with the load).
x real time: planned machine time / wall time to plan and sample every 1 ms setpoint (as
  cnc-plan does, without interpreter start; the drive kernel loaded first, as the planner
  node loads it at start), or, in (b), to run.
(b) machine s: the bridge's sim time from submitting the job to its final status,
  including the planner's start delay; wall s the same span on the wall clock. The bridge
  steps in lockstep with the setpoint stream, so this is the whole loop's speed (planner,
  bridge, DDS and the Python recorder writing every topic), not the drive model's alone.
  Peak RSS: VmHWM of the node processes from /proc, polled while they ran. chunks lost:
  analysis.chunks_lost on the recording; missing: joint_states samples not in the
  recording between its first and last, gap ms the longest step between two recorded
  samples (1.0: none missing). Each process steps, plans or records on one
  thread, so x real is at most min(2 CPUs / the sum, 1 / the largest) of the CPU seconds
  per machine second: the "ceiling" column, what an otherwise idle 2-CPU machine would
  allow before latency; x real is lower when other work shares the CPUs (load avg: the
  1-minute load average at the end of the run). The recorder's figure is the bench
  process's (it records).
(c) The planner's publish time is not observable without instrumenting it, so the lead is
  measured instead: the recorder stamps each message with the latest bridge time it has
  heard (/clock or joint_states), and lead = the chunk's header stamp - that time. The
  planner streams up to lookahead (0.3 s) ahead of the feedback it last heard, in 0.1 s
  chunks, so the lead sits about 0.2-0.31 s when the stream keeps up; the p99 column is the
  1st percentile (the smallest leads, the risk side); a lead near or below 0 would be an
  underrun (the bridge waits for it in simulation, and would alarm in real time).
(d) tracemalloc counts Python allocations only (numpy buffers included, ruckig's C++ not).
  plan_job plans and holds the whole job, so its memory grows with job length: move jobs
  ~3.5 KiB per feed move, drill jobs ~0.16 MiB per hole (the safety search's drive-model
  arrays over the whole cycle). The planner node does not plan long jobs whole: drill jobs
  over 50 holes and move programs over 500 moves are planned in segments while they run
  (cnc_planner/segments.py, lookahead.py), so it holds a few segments at a time: the
  "segments" row. A 10,000-hole plate and a 1-hour program streamed over topics are in
  bench/results/soak.txt (make soak, about an hour).
Limits found (measured, not worked around):
- Between jobs the bridge (simulation) idles at wall-clock pace until the next job's first
  setpoint (the planner's start delay); 100 short jobs back to back took ~1.1 s wall each in
  session 1's measurement, a stall whose cause is not diagnosed (test_load uses a 0.5 s
  underrun_timeout).
- job_goal is reliable KEEP_LAST depth 10: clients keep at most 10 goals unacknowledged
  (test_load keeps 5 in flight). Goals are now taken off the topic at once and planned on
  an intake thread, but bursts beyond 10 have not been measured again."""


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--planning", action="store_true", help="rerun (a), planning speed, only")
    only.add_argument("--over-topics", action="store_true", help="rerun (b) and (c), over topics, only")
    only.add_argument("--real-time", action="store_true", help="rerun (e), CPU share in real time, only")
    options = parser.parse_args()
    sys.exit(rerun_planning() if options.planning else over_topics_only() if options.over_topics
             else real_time_only() if options.real_time else main())
