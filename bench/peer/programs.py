"""Real programs: the .ngc files of config/programs/ (the ones test/test_gcode.py runs), the
same file on LinuxCNC and on ours, judged per operation.

Each file runs unchanged on both sides, from where its first rapid goes (so that move is
null and both start at rest at one point, spindle at speed). Our front end splits the
program into operations (line, kind, job document); the same split is applied to both
recordings: on ours by the operation marks the planner publishes on job_events, on
LinuxCNC by motion.program-line (the source line of the motion under way, sampled every
servo period): an operation runs from its own line up to the next operation's line. Each
operation's share of the feedback then goes through the judge the generated rows use
(run.judge: analyze_drilling, analyze_thread, the turning air replay), with the
operation's own job document.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_msgs_py.gcode import machine_named
from cnc_msgs_py.job import parse_job

import analysis
import linuxcnc_side

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "config" / "programs"


@dataclass
class ProgramRow:
    """One .ngc file: its machine, text, operations (line, kind, document in mm) and start (mm)."""

    name: str
    path: Path
    machine: str
    text: str
    operations: list[tuple[int, str, dict]]
    start: dict[str, float]

    def doc(self) -> dict:
        """The program job our side runs (machine and job id set by ours.run_over_topics)."""
        program = {"gcode": self.text, **({"start": self.start} if self.start else {})}
        return {"schema": "cnc_job/1", "job_id": self.name, "kind": "program", "machine": self.machine,
                "program": program}

    def linuxcnc_program(self) -> linuxcnc_side.Program:
        """The file as it is; MDI sets mm, absolute and radius mode before moving to the start
        (an earlier program may have left G20 or G7 modal)."""
        modes = "G21 G90 G8" if self.machine == "lathe" else "G21 G90"
        start = f"{modes} G0 " + " ".join(f"{k.upper()}{v:.4f}" for k, v in self.start.items())
        return linuxcnc_side.Program(f"program {self.name}", start, self.text)


def program_rows(only: str | None = None) -> list[ProgramRow]:
    """The files of config/programs/ (those whose name matches ``only``), in name order."""
    return [program_row(path) for path in sorted(PROGRAMS.glob("*.ngc")) if not only or re.search(only, path.stem)]


def program_row(path: Path) -> ProgramRow:
    """One .ngc file as both sides run it: from where its first rapid goes, as our front end
    reads it (its machine named in the file)."""
    text = path.read_text()
    row = ProgramRow(path.stem, path, machine_named(text), text, [], {})
    first = parse_job(row.doc()).program.operations[0][2]
    if first["kind"] != "move" or "rapid" not in first["move"][0]:
        raise ValueError(f"{path.name}: the first operation must be a rapid (the start both sides share)")
    row.start = dict(first["move"][0]["rapid"])
    # from there (the program's start block), that rapid is no operation: as our side runs it
    row.operations = [(line, op.kind, doc) for line, op, doc in parse_job(row.doc()).program.operations]
    return row


def _windows_ours(t: np.ndarray, marks: list[tuple[int, float]], count: int) -> list[np.ndarray]:
    """Feedback samples of each operation, from its mark (index, time) to the next one's."""
    at = dict(marks)
    edges = [at.get(k) for k in range(count)] + [np.inf]
    out = []
    for k in range(count):
        end = next((e for e in edges[k + 1:] if e is not None), np.inf)
        out.append(np.zeros(len(t), bool) if edges[k] is None else (t >= edges[k] - 1e-9) & (t < end - 1e-9))
    return out


def _windows_lines(line: np.ndarray, lines: list[int]) -> list[np.ndarray]:
    """Samples of each operation by the program line under way: [its line, the next one's).
    Inside a G71 (its contour an O-word subroutine) LinuxCNC reports line -1: such samples
    belong to the line before them."""
    known = np.where(line >= 0, np.arange(len(line)), 0)
    line = np.asarray(line)[np.maximum.accumulate(known)]
    edges = list(lines) + [np.iinfo(np.int64).max]
    return [(line >= a) & (line < b) for a, b in zip(edges, edges[1:])]


@dataclass
class _AsRow:
    """An operation seen as run.judge sees a row."""

    kind: str
    doc: dict


def _judge_part(judge, row: ProgramRow, k: int, t, axes, spindle, part, machine) -> dict:
    """One operation's figures from its share of a recording (``part``)."""
    _, kind, doc = row.operations[k]
    if not part.any():
        return {"error": "no samples"}
    tt = t[part] - t[part][0]
    ax = {a: v[part] for a, v in axes.items()}
    sp = None if spindle is None else spindle[part]
    if kind in ("drill", "thread", "turn"):
        try:
            return judge(_AsRow(kind, doc), tt, ax, sp, machine)
        except Exception as err:  # noqa: BLE001 - one operation's judge failing is a table entry
            return {"error": f"{type(err).__name__}: {err}"[:120]}
    return {"time": analysis.cycle_time(tt, ax) if len(tt) > 2 else 0.0}


def judge_recording(judge, row: ProgramRow, t, axes, spindle, machine, starts=None, line=None) -> dict:
    """{'time': whole program, 'ops': [figures per operation]} of one recording; windows by the
    operation marks (ours, starts) or the program line (LinuxCNC, line)."""
    t = np.asarray(t)
    n = len(row.operations)
    parts = _windows_ours(t, starts, n) if starts is not None else _windows_lines(line, [o[0] for o in row.operations])
    ops = [_judge_part(judge, row, k, t, axes, spindle, parts[k], machine) for k in range(n)]
    return {"time": analysis.cycle_time(t, axes), "ops": ops}


def our_side(row: ProgramRow, variants: dict, run_over_topics, judge) -> dict:
    """fair and jerk: the file over topics on both machine descriptions, judged per operation."""
    out = {}
    for key, machine in variants[row.machine].items():
        try:
            o = run_over_topics(row.doc(), machine, row.start)
            out[key] = judge_recording(judge, row, o["t"], o["axes"], o["spindle"], machine, starts=o["operations"])
        except Exception as err:  # noqa: BLE001 - shown in the table
            out[key] = {"error": f"{type(err).__name__}: {err}"[:200]}
    return out


def linuxcnc_recording(row: ProgramRow, sessions: dict) -> linuxcnc_side.Recording | str:
    """LinuxCNC's recording of the file, or why there is none."""
    session = sessions.get(row.machine)
    rec = session.recordings.get(row.linuxcnc_program().name) if session else None
    if rec is None:
        return sessions.get("error") or "not recorded"
    if rec.errors or not rec.finished:
        return "; ".join(rec.errors) or "did not finish"
    return rec


def linuxcnc_figures(row: ProgramRow, sessions: dict, machine, judge) -> dict:
    """'fb' (through our drive model) and 'raw' (the ideal loop) figures, or 'error'."""
    rec = linuxcnc_recording(row, sessions)
    if isinstance(rec, str):
        return {"error": rec}
    fb = analysis.through_servo(rec.t, rec.axes, machine)
    return {"fb": judge_recording(judge, row, rec.t, fb, rec.spindle, machine, line=rec.line),
            "raw": judge_recording(judge, row, rec.t, rec.axes, rec.spindle, machine, line=rec.line)}


def _f(v, spec=".3f") -> str:
    return "-" if v is None else format(v, spec)


def _figures(kind: str, sides: list[dict | None]) -> str:
    """The judged figures of one operation, LinuxCNC (drive-model feedback) / fair / jerk."""
    def each(key, scale=1.0, spec=".0f"):
        return "/".join("-" if s is None or s.get(key) is None else format(s[key] * scale if scale != 1.0 else s[key], spec) for s in sides)
    if kind == "drill":
        return f"viol {each('viol', spec='d')}, worst hole depth error {each('depth_um', spec='.1f')} um"
    if kind == "thread":
        return (f"depth error {each('depth_error_mm', 1e3, '.1f')} um, {each('passes', spec='d')} cutting passes, "
                f"longest chip {each('chip', spec='.2f')} rev")
    if kind == "turn":
        return f"feed in air {each('air', 100.0, '.1f')} %, rapids into stock {each('rapid_cut_mm', spec='.2f')} mm"
    return ""


def table(rows: list[ProgramRow], lc: dict, us: dict) -> list[str]:
    """One line per program (whole program) and one per operation."""
    head = (f"{'program / line kind':<30} {'LC s':>7} {'ideal s':>7} {'fair s':>7} {'jerk s':>7} {'fair/LC':>7} "
            f"{'jerk/LC':>7}  figures LC / fair / jerk (LC on the drive-model feedback)")
    lines = [f"Real programs (config/programs/*.ngc, the files test/test_gcode.py runs): each file unchanged on both sides",
             head, "-" * (len(head) + 30)]
    for row in rows:
        figs = lc.get(row.name, {})
        fb, raw = figs.get("fb"), figs.get("raw")
        fair, jerk = us[row.name].get("fair", {}), us[row.name].get("jerk", {})

        def line_of(label, lc_t, ideal, f_t, j_t, extra):
            ratio = (lambda x: _f(x / lc_t) if x is not None else "-") if lc_t else (lambda x: "-")
            return (f"{label:<30} {_f(lc_t):>7} {_f(ideal):>7} {_f(f_t):>7} {_f(j_t):>7} {ratio(f_t):>7} "
                    f"{ratio(j_t):>7}  {extra}")
        lines.append(line_of(f"{row.name} ({row.machine})", fb and fb["time"], raw and raw["time"], fair.get("time"),
                             jerk.get("time"), "whole program, first to last axis motion"))
        for k, (line, kind, doc) in enumerate(row.operations):
            sides = [s["ops"][k] if s and "ops" in s else None for s in (fb, fair, jerk)]
            label = f"  {line:>3} {kind}" + (f" ({len(doc['drill']['holes'])} holes)" if kind == "drill" else "")
            lines.append(line_of(label, sides[0] and sides[0].get("time"), raw and raw["ops"][k].get("time"),
                                 sides[1] and sides[1].get("time"), sides[2] and sides[2].get("time"),
                                 _figures(kind, sides)))
            for name, s in zip(("LC", "fair", "jerk"), sides):
                if s and "error" in s:
                    lines.append(f"      {name}: {s['error']}")
        if "error" in figs:
            lines.append(f"  LinuxCNC: {figs['error'][:160]}")
        for key in ("fair", "jerk"):
            if "error" in us[row.name].get(key, {}):
                lines.append(f"  ours {key}: {us[row.name][key]['error']}")
    return lines
