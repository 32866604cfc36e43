"""Command-line tools: cnc-run (a job through both nodes), cnc-plan (offline), cnc-analyze.

Every user-facing failure is one line naming what to fix, with a non-zero exit code.
cnc-run's exit codes: 0 the job succeeded and every verdict of its report holds; 1 the job
did not succeed (rejected by the planner, aborted, canceled); 2 the input is bad (job file,
machine, --out); 3 the run itself failed (nodes, timeout); 4 the job ran to its end but a
verdict of the report failed (a section's ``verdict.passed`` is false): a miss is never
reported as a success. cnc-analyze exits 4 on a failed verdict too. The report's ``drives``
comparison is advice (which axis is not its description), printed but never an exit code.

Each tool parses its arguments before importing what its work needs (the planner, rclpy, the
judge, matplotlib, jinja2): --help and --version answer in a few tens of milliseconds.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from cnc_msgs_py.tool import add_program_options, tool_parser
from cnc_msgs_py.topics import NAMESPACE


def _fail(tool: str, message: str, code: int = 2) -> int:
    print(f"{tool}: {message}", file=sys.stderr)
    return code


def _write_json(path: Path, doc: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2, sort_keys=False) + "\n")


def _rejected_report(job_id: str, reason: str) -> dict:
    return {"job_id": job_id, "state": "rejected", "reason": reason, "cycle_time_s": 0.0,
            "max_following_error": {}, "setpoints": 0, "chunks": 0, "chunks_lost": 0}


def run_main(argv: list[str] | None = None) -> int:
    """cnc-run JOB [--out DIR]: run a job on the emulated machine and report on it."""
    parser = tool_parser("cnc-run", "cnc_planner", description=run_main.__doc__)
    parser.add_argument("job", help="job document (YAML or JSON) or G-code program (.ngc)")
    add_program_options(parser)
    parser.add_argument("--out", type=Path, help="output directory (default runs/<timestamp>)")
    parser.add_argument("--timeout", type=float, default=900.0, help="wall-clock limit (s)")
    parser.add_argument("--namespace", default=NAMESPACE, help=f"the machine's namespace (default {NAMESPACE})")
    parser.add_argument("--plant", type=Path, help="plant file: the bridge emulates drives that differ from the "
                                                   "description (docs/machines.md); the planner never reads it")
    parser.add_argument("--resume-after", type=float, metavar="S",
                        help="a program held at M0/M1 resumes after S s of machine (sim) time; without it the "
                             "job is canceled at its first hold")
    args = parser.parse_args(argv)
    if args.resume_after is not None and not args.resume_after >= 0:
        return _fail("cnc-run", f"--resume-after: must be >= 0 s, got {args.resume_after:g}")
    from cnc_msgs_py.gcode.document import job_from_args
    from cnc_msgs_py.job import job_id_of
    from cnc_msgs_py.machine import MachineError, load_machine
    from cnc_msgs_py.plant import load_plant
    from cnc_msgs_py.schema import JobError

    out = args.out or Path("runs") / time.strftime("%Y%m%d-%H%M%S")
    if (out / "bag").exists():
        return _fail("cnc-run", f"--out: {out / 'bag'} exists already; choose a new directory")
    try:
        doc = job_from_args(args)
        machine = load_machine(doc.get("machine") if isinstance(doc.get("machine"), str) else "")
        plant = str(args.plant.resolve()) if args.plant else ""
        load_plant(plant, machine)  # checked here: a bad plant file is bad input, not a failed run
    except (JobError, MachineError) as err:
        from cnc_planner.report_page import write_report_page

        reason = f"machine: {err}" if isinstance(err, MachineError) else str(err)
        doc = locals().get("doc")
        report = _rejected_report(job_id_of(doc), reason)
        _write_json(out / "report.json", report)
        write_report_page(report, [], out / "report.html", job=doc if isinstance(doc, dict) else None)
        return _fail("cnc-run", f"rejected: {reason}")
    from cnc_planner.baselines import plan_beside
    from cnc_planner.nodes import Nodes, RunError

    # The nodes start first and come up while this process loads rclpy and the report's code;
    # the report's baselines are planned meanwhile, in a child process (forked before rclpy's
    # threads start) that the report collects.
    try:
        nodes = Nodes(machine.name, namespace=args.namespace, bridge_params={"plant": plant} if plant else None)
    except RunError as err:
        return _fail("cnc-run", str(err), 3)
    try:
        beside = plan_beside(doc, machine)
    except JobError:
        beside = None  # the planner rejects it, with the reason
    try:
        from cnc_msgs_py.progress import Progress

        from cnc_planner.plots import write_plots
        from cnc_planner.report import build_report
        from cnc_planner.report_page import write_report_page
        from cnc_planner.runner import run_job
        from cnc_analysis.recording import read_run

        print(f"cnc-run: {args.job} on '{machine.name}' -> {out}", flush=True)
        progress = Progress()
        try:
            status = run_job(json.dumps(doc), job_id_of(doc), machine.name, out / "bag", timeout=args.timeout,
                             progress=progress, namespace=args.namespace, plant=plant, nodes=nodes,
                             resume_after=args.resume_after)
        except RunError as err:
            if beside is not None:
                beside.cancel()
            return _fail("cnc-run", str(err), 3)
        finally:
            progress.close()
    finally:
        nodes.stop()  # stopped by the run already, unless it failed before it began
    run = read_run(out / "bag")
    report = build_report(run)
    _write_json(out / "report.json", report)
    plots = write_plots(run, report, out / "plots")
    page = write_report_page(report, plots, out / "report.html", job=doc)
    print(summary(report))
    print(f"  report {page}")
    if status["state"] != "succeeded":
        return 1
    return VERDICT_FAILED if failed_verdicts(report) else 0


VERDICT_FAILED = 4  # cnc-run's exit code: the job ran, the report judged it a miss


def failed_verdicts(report: dict) -> list[str]:
    """The report's sections whose verdict failed (a section's ``verdict`` with passed false)."""
    return [key for key, section in report.items()
            if isinstance(section, dict) and isinstance(section.get("verdict"), dict)
            and section["verdict"].get("passed") is False]


def summary(report: dict) -> str:
    lines = [f"job {report['job_id']}: {report['state']}" + (f" ({report['reason']})" if report.get("reason") else "")]
    if report["state"] != "rejected":
        fe = ", ".join(f"{k} {v * 1e3:.4f}" for k, v in report["max_following_error"].items())
        lines += [f"  cycle time on feedback  {report['cycle_time_s']:.3f} s",
                  f"  max following error     {fe} (mm / mrad)",
                  f"  setpoints {report['setpoints']} in {report['chunks']} chunks, {report['chunks_lost']} lost"]
    for key, section in report.items():
        if isinstance(section, dict) and isinstance(section.get("verdict"), dict):
            verdict = section["verdict"]
            lines.append(f"  verdict {key}: {'passed' if verdict.get('passed') else 'FAILED'}: {verdict.get('says', '')}")
    drives = report.get("drives")
    if drives:  # advice, not a verdict: which axis is not its description, and what to do
        plant = f" (plant {report['plant']})" if report.get("plant") else ""
        lines.append(f"  drives{plant}: {'as described' if drives['as_described'] else 'DIFFER'}: {drives['says']}")
    return "\n".join(lines)


def cell_main(argv: list[str] | None = None) -> int:
    """cnc-cell JOB [JOB ...] --out DIR: one machine pair per job, all at once, in one DDS
    domain under /cell/m<i>/cnc, each recorded to DIR/m<i>/ (bag, report, plots)."""
    parser = tool_parser("cnc-cell", "cnc_planner", description=cell_main.__doc__)
    parser.add_argument("jobs", nargs="+", help="job documents, one per machine")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--timeout", type=float, default=900.0, help="wall-clock limit per machine (s)")
    parser.add_argument("--resume-after", type=float, metavar="S",
                        help="as cnc-run's: programs held at M0/M1 resume after S s of machine time")
    args = parser.parse_args(argv)
    from cnc_msgs_py.discovery import describe_discovery
    from cnc_planner.runner import local_dds_env

    env = local_dds_env()  # one domain for the whole cell: namespaces keep the machines apart
    runs = []
    for i, job in enumerate(args.jobs, start=1):
        out = args.out / f"m{i}"
        command = [sys.executable, "-m", "cnc_planner.cli", "run", str(job), "--out", str(out),
                   "--namespace", f"/cell/m{i}/cnc", "--timeout", str(args.timeout)]
        if args.resume_after is not None:
            command += ["--resume-after", str(args.resume_after)]
        log = (args.out / f"m{i}.log")
        log.parent.mkdir(parents=True, exist_ok=True)
        runs.append((job, out, subprocess.Popen(command, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT)))
    print(f"cnc-cell: {len(runs)} machines; {describe_discovery(env)}; logs in {args.out}/m<i>.log")
    worst = 0
    for job, out, proc in runs:
        code = proc.wait()
        worst = max(worst, code)
        state = json.loads((out / "report.json").read_text())["state"] if (out / "report.json").exists() else "no report"
        print(f"  {out.name}: {job} -> {state} (exit {code})")
    return worst


def plan_main(argv: list[str] | None = None) -> int:
    """cnc-plan JOB --out DIR: plan offline (no ROS) from the machine's home, where cnc-run's
    simulated drives start, and write setpoints.npz + summary.json."""
    parser = tool_parser("cnc-plan", "cnc_planner", description=plan_main.__doc__)
    parser.add_argument("job", help="job document (YAML or JSON) or G-code program (.ngc)")
    add_program_options(parser)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--period", type=float, default=0.001, help="interpolation period (s)")
    parser.add_argument("--compress", action="store_true",
                        help="write setpoints.npz deflated: an eighth of the size, and for a 300-hole plate "
                             "0.3 s more (default: stored, 0.03 s for its 19 MiB)")
    args = parser.parse_args(argv)
    import numpy as np

    from cnc_msgs_py.gcode.document import job_from_args
    from cnc_msgs_py.heap import keep_freed_memory
    from cnc_msgs_py.job import parse_job
    from cnc_msgs_py.machine import MachineError, load_machine
    from cnc_msgs_py.schema import JobError

    from cnc_planner.kinds.program import HOLD
    from cnc_planner.planning import plan_job

    keep_freed_memory()  # as the planner node does: the plan's arrays reuse freed memory
    try:
        job = parse_job(job_from_args(args))
        machine = load_machine(job.machine)
        plan = plan_job(job, machine, machine.home_joints)  # as cnc-run starts
    except (JobError, MachineError) as err:
        return _fail("cnc-plan", str(err))
    t = np.arange(int(np.ceil(plan.duration / args.period)) + 1) * args.period
    p, v, a = plan.sample(t)
    args.out.mkdir(parents=True, exist_ok=True)
    save = np.savez_compressed if args.compress else np.savez
    save(args.out / "setpoints.npz", t=t, **{j: p[:, i] for i, j in enumerate(plan.joints)},
         **{f"{j}_velocity": v[:, i] for i, j in enumerate(plan.joints)},
         **{f"{j}_acceleration": a[:, i] for i, j in enumerate(plan.joints)})
    _write_json(args.out / "summary.json", {
        "job_id": job.job_id, "machine": machine.name, "duration_s": plan.duration, "setpoints": len(t),
        "joints": list(plan.joints), "events": [{"t": e.time, "name": e.name, **e.data} for e in plan.events],
    })
    print(f"cnc-plan: {job.job_id}: {plan.duration:.3f} s, {len(t)} setpoints -> {args.out}")
    for hold in (e for e in plan.events if e.name == HOLD):
        print(f"  hold at line {hold.data['line']} ({hold.data['code']}) at {hold.time:.3f} s: planned as zero length; "
              f"over topics the program waits there for job_resume")
    return 0


def analyze_main(argv: list[str] | None = None) -> int:
    """cnc-analyze DIR/bag [--out report.json]: recompute the report from a recording alone;
    exits 4 when a verdict of the report fails, as cnc-run does."""
    parser = tool_parser("cnc-analyze", "cnc_planner", description=analyze_main.__doc__)
    parser.add_argument("bag", type=Path)
    parser.add_argument("--out", type=Path, help="write the report here (default: print it)")
    args = parser.parse_args(argv)
    from cnc_analysis.recording import read_run

    from cnc_planner.report import build_report
    try:
        report = build_report(read_run(args.bag))
    except (FileNotFoundError, ValueError) as err:
        return _fail("cnc-analyze", str(err))
    if args.out:
        _write_json(args.out, report)
    else:
        print(json.dumps(report, indent=2))
    failed = failed_verdicts(report)
    if failed:
        print(f"cnc-analyze: verdict failed: {', '.join(failed)}", file=sys.stderr)
        return VERDICT_FAILED
    return 0


if __name__ == "__main__":  # python -m cnc_planner.cli run|plan|analyze|cell ...
    TOOLS = {"run": run_main, "plan": plan_main, "analyze": analyze_main, "cell": cell_main}
    if len(sys.argv) < 2 or sys.argv[1] not in TOOLS:
        sys.exit(f"usage: python -m cnc_planner.cli {{{','.join(TOOLS)}}} [--help] ...")
    sys.exit(TOOLS[sys.argv[1]](sys.argv[2:]))
