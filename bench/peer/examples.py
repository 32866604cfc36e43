"""LinuxCNC 2.9's example programs (Debian's linuxcnc-uspace, /usr/share/linuxcnc/ncfiles)
through our G-code front end and planner, beside LinuxCNC's own interpreter (rs274 -g).

The machining examples each run on a shipped machine with its own tool table (mill3, or
lathe for the lathe programs) and plan, or are refused: for a machine reason (travel, an
axis the machine lacks, a work offset (G55..) it keeps none of, a probe it lacks) or for a
language reason (a word this front end refuses, with its reason). Probing, remap and I/O
demos and the language demos that move no axis are left out, each with why. A program that
never starts the spindle runs with it started ahead, as an operator would (``--spindle``).
Each that plans is judged as cnc-run's report would judge it, on the drive model's predicted
feedback from the machine's home (``judged``). The files are
LinuxCNC's (GPL): they are read where they are installed, never copied; bench/results/linuxcnc_examples.json keeps each one's sha256,
outcome and rs274's verdict, and test/test_gcode_examples.py checks the outcomes.

Our own must-show programs (test/programs/*.ngc) and the front end's oracle programs
(test/gcode_oracle/*.ngc) go through rs274 -g with the machine's tool table (``-t``); its
outputs are kept in bench/results/rs274_examples.json by each program's sha256, for the
tests to compare LinuxCNC's feed moves with our plan without LinuxCNC.

    apt-get install linuxcnc-uspace
    .venv/bin/python bench/peer/examples.py      # writes bench/results/linuxcnc_examples.json
"""
from __future__ import annotations

import hashlib
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

NCFILES = Path("/usr/share/linuxcnc/ncfiles")
RESULTS = Path(__file__).resolve().parents[1] / "results" / "linuxcnc_examples.json"
RS274_RECORDED = Path(__file__).resolve().parents[1] / "results" / "rs274_examples.json"
MUST_SHOW = Path(__file__).resolve().parents[2] / "test" / "programs"
ORACLE_PROGRAMS = Path(__file__).resolve().parents[2] / "test" / "gcode_oracle"  # coordinate systems, G70/G72, ...
LATHE = ("lathe", "g76.ngc", "threading.ngc")  # programs for a lathe (X/Z, G7/G18, threads)
LEFT_OUT = {
    "gridprobe.ngc": "probing (G38.2)", "probe-hole.ngc": "probing (G38.x)", "smartprobe.ngc": "probing (G38.5)",
    "tool-length-probe.ngc": "probing (G38.2)", "touchoff.ngc": "a probing/touch-off macro (no motion of its own)",
    "m6remap.ngc": "remap demo", "m6demo.ngc": "remap demo", "m61demo.ngc": "remap demo", "m250.ngc": "remap demo",
    "testm6fail.ngc": "remap demo", "g881.ngc": "remap subroutine", "g881min.ngc": "remap subroutine",
    "g882.ngc": "remap subroutine", "m75.ngc": "remap demo", "m76.ngc": "remap demo",
    "plasmatest.ngc": "plasma I/O demo (torch on/off, THC)",
    "factorial.ngc": "language demo, moves no axis", "retval.ngc": "language demo, moves no axis",
    "roparams.ngc": "language demo, moves no axis", "g20sub.ngc": "a subroutine file, moves no axis of its own",
    "nestedcall.ngc": "language demo (its own 'callsub' typo is refused by rs274 too)",
    "increment.ngc": "a subroutine file, moves no axis of its own",
    "m70m72-demo.ngc": "language demo (M70/M72), moves no axis: read to its end",
    "m73-demo.ngc": "language demo (M73), moves no axis: read to its end",
}
# a machine reason: travel, an axis it lacks, the spindle, a tool of its table that does not fit the
# program (a cutter too big for a compensated entry), a work offset it keeps none of, a probe
MACHINE_REASONS = ("outside its travel", "has no", "exceeds the spindle", "cannot run", "than the tool radius",
                   "keeps no")
# the program asks for what our methods must not do: drill or turn with the spindle stopped. A
# program that never starts the spindle (written for LinuxCNC's simulator) is run as an operator
# runs it, the spindle started in MDI before cycle start (``--spindle``): ``spindle_ahead_rpm``
# and the refusal without it (``without_spindle``) are recorded. A position read before the
# program gives one is where the machine stands, as in LinuxCNC: no refusal.
PROGRAM_REASONS = ("the spindle is off",)
SPINDLE_AHEAD_RPM = 1000.0  # cnc-run --spindle 1000: an operator's MDI S1000 M3


def machine_of(name: str) -> str:
    return "lathe" if name.startswith(LATHE) or name in LATHE else "mill3"


def ours(path: Path, machine: str, spindle_rpm: float | None = None) -> tuple[str, str]:
    """('plans', seconds from the machine's home, as cnc-plan) or ('machine' | 'program' |
    'language', the refusal) for one file; ``spindle_rpm``: the spindle turning as the program
    begins (cnc-run --spindle)."""
    from cnc_msgs_py.gcode.document import job_document
    from cnc_msgs_py.job import parse_job
    from cnc_msgs_py.machine import load_machine
    from cnc_msgs_py.schema import JobError

    from cnc_planner.planning import plan_job
    try:
        job = parse_job(job_document(path, machine, spindle_rpm=spindle_rpm))
        described = load_machine(machine)
        return "plans", f"{plan_job(job, described, described.home_joints).duration:.1f} s"
    except JobError as err:
        text = str(err)
        if any(k in text for k in MACHINE_REASONS):
            return "machine", text
        return ("program" if any(k in text for k in PROGRAM_REASONS) else "language"), text


def judged(path: Path, machine: str, spindle_rpm: float | None = None) -> str:
    """'passes', or what failed, of the report's program verdict on the drive model's predicted
    feedback to the plan made from the machine's home, where cnc-run's simulated machine
    starts (a lathe program's tool would otherwise begin at X0 Z0, inside its part)."""
    from cnc_msgs_py.gcode.document import job_document
    from cnc_msgs_py.job import parse_job
    from cnc_msgs_py.machine import load_machine

    from cnc_planner.planning import plan_job
    from cnc_planner.report import build_report, predicted_run
    described = load_machine(machine)
    doc = job_document(path, machine, spindle_rpm=spindle_rpm)
    plan = plan_job(parse_job(doc), described, described.home_joints)
    verdict = build_report(predicted_run(doc, plan, described), described)["program"]["verdict"]
    return "passes" if verdict["passed"] else verdict["says"]


def rs274_verdict(path: Path, machine: str) -> str:
    """'reads' when rs274 -g interprets the whole file, else its first error line."""
    errors = [ln for ln in rs274(path, machine).splitlines()
              if ln.strip() and not ln.lstrip()[:1].isdigit() and not ln.startswith("executing")]
    return errors[0].strip() if errors else "reads"


def survey(folder: Path = NCFILES) -> dict:
    rows = {}
    for path in sorted(folder.glob("*.ngc")):
        name = path.name
        sha = hashlib.sha256(path.read_bytes()).hexdigest()
        if name in LEFT_OUT:
            rows[name] = {"sha256": sha, "left_out": LEFT_OUT[name]}
            continue
        machine = machine_of(name)
        rows[name] = {"sha256": sha, "machine": machine, "rs274": rs274_verdict(path, machine)}
        outcome, detail = ours(path, machine)
        if outcome == "program":  # it never starts the spindle: the operator does, before cycle start
            rows[name].update(without_spindle=detail, spindle_ahead_rpm=SPINDLE_AHEAD_RPM)
            outcome, detail = ours(path, machine, SPINDLE_AHEAD_RPM)
        rows[name].update(outcome=outcome, detail=detail)
        if outcome == "plans":  # and what its report says of the predicted run
            rows[name]["judged"] = judged(path, machine, rows[name].get("spindle_ahead_rpm"))
    return rows


def machine_table(machine: str) -> Path:
    """The machine's own tool table (config/machines/<machine>.tbl), for rs274's ``-t``."""
    from cnc_msgs_py.machine import machine_dirs
    return next(d / f"{machine}.tbl" for d in machine_dirs() if (d / f"{machine}.tbl").is_file())


def inch_table(text: str) -> str:
    """A tool.tbl in mm as rs274 must be given it: standalone, it is an inch machine and reads
    the table's lengths and diameters (X..W, D) in inches."""
    def scale(m: re.Match) -> str:
        return f"{m.group(1)}{float(m.group(2)) / 25.4:.9f}"
    return "\n".join(re.sub(r"\b([XYZABCUVWD])([-+]?\d*\.?\d+)", scale, line.split(";")[0], flags=re.I)
                     for line in text.splitlines()) + "\n"


def rs274(path: Path, machine: str) -> str:
    """rs274 -g's output of a file with the machine's tool table (in its inches), COMMENT lines
    left out."""
    with tempfile.TemporaryDirectory() as tmp:
        table = Path(tmp) / "tool.tbl"
        table.write_text(inch_table(machine_table(machine).read_text()))
        out = subprocess.run(["rs274", "-t", str(table), "-g", str(path)], capture_output=True, text=True, timeout=60)
    return "\n".join(ln for ln in (out.stdout + "\n" + out.stderr).splitlines() if " COMMENT(" not in ln)


def record_must_show() -> dict[str, str]:
    """rs274 -g's output of each program of test/programs/ and test/gcode_oracle/, by the
    program's sha256; for a G71 of test/programs/ also of the program up to its line
    (oracle.upto), which oracle.check_program reads the roughing cycle from."""
    import oracle  # bench/peer/oracle.py, beside this script
    from cnc_msgs_py.gcode import machine_named
    outputs = {}
    for path in sorted([*MUST_SHOW.glob("*.ngc"), *ORACLE_PROGRAMS.glob("*.ngc")]):
        machine = machine_named(path.read_text()) or "mill3"
        outputs[oracle._key(path.read_text())] = rs274(path, machine)
        if path.parent == MUST_SHOW:
            outputs.update(_roughing_prefixes(path, machine))
    return outputs


def _roughing_prefixes(path: Path, machine: str) -> dict[str, str]:
    """rs274 -g's output of the program up to each of its G71 lines, by that text's sha256."""
    import tempfile

    import oracle
    from cnc_msgs_py.gcode.document import job_document
    from cnc_msgs_py.job import parse_job
    text, out = path.read_text(), {}
    for line, op, _ in parse_job(job_document(path)).program.operations:
        if op.kind == "turn":
            with tempfile.TemporaryDirectory() as folder:
                prefix = Path(folder) / path.name
                prefix.write_text(oracle.upto(text, line))
                out[oracle._key(prefix.read_text())] = rs274(prefix, machine)
    return out


def main() -> int:
    RS274_RECORDED.write_text(json.dumps(record_must_show(), indent=0, sort_keys=True) + "\n")
    rows = survey()
    machining = [r for r in rows.values() if "outcome" in r]
    plans = sum(r["outcome"] == "plans" for r in machining)
    count = {k: sum(r["outcome"] == k for r in machining) for k in ("machine", "program", "language")}
    for name, r in rows.items():
        print(f"{name:55s} {r.get('outcome', 'left out'):9s} {r.get('detail', r.get('left_out'))}")
    ahead = sum("spindle_ahead_rpm" in r and r["outcome"] == "plans" for r in machining)
    misses = [name for name, r in rows.items() if r.get("judged", "passes") != "passes"]
    print(f"{len(machining)} machining examples of {len(rows)}: {plans} plan ({ahead} of them with --spindle "
          f"{SPINDLE_AHEAD_RPM:g}); refused for a machine reason {count['machine']}, a program reason "
          f"{count['program']}, a language reason {count['language']}; judged on predicted feedback, "
          f"{plans - len(misses)} pass, {len(misses)} fail ({', '.join(misses) or 'none'})")
    RESULTS.write_text(json.dumps(rows, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
