"""The G-code front end (cnc_msgs_py.gcode, the program kind).

Round trip: the LinuxCNC programs bench/peer generates from its job documents (G81/G99,
G83, G76, G71) plan bit for bit the same setpoints as those documents. Bad programs are
refused at their line, before anything is planned: hand-picked cases and fuzzed ones
(hypothesis, derandomized) through the planner's Executive, which stays usable after each.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_msgs_py.gcode import machine_named
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.executive import Executive
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer"), str(ROOT / "bench")]
import gcode as peer_gcode  # noqa: E402  bench/peer/gcode.py: our jobs as LinuxCNC programs
import rows as peer_rows  # noqa: E402

FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=False, max_examples=150,
                suppress_health_check=[HealthCheck.too_slow])
LINE = re.compile(r"^line \d+: \S")


def program_doc(text: str, machine: str, **block) -> dict:
    return {"schema": "cnc_job/1", "job_id": "prog-1", "kind": "program", "machine": machine,
            "program": {"gcode": text, **block}}


def same_setpoints(job_doc: dict, prog_doc: dict, machine: str, start_mm: dict[str, float]) -> None:
    """Both plans sampled every ms (as cnc-plan and bench/plan_hashes sample them): identical."""
    m = load_machine(machine)
    start = {k: v * 1e-3 for k, v in start_mm.items()}
    a = plan_job(parse_job(job_doc), m, start)
    b = plan_job(parse_job(prog_doc), m, start)
    assert a.duration == b.duration
    t = np.arange(0.0, a.duration, 1e-3)
    for x, y in zip(a.sample(t), b.sample(t)):
        assert np.array_equal(x, y)


def _row(name: str):
    return next(r for r in peer_rows.all_rows() if r.name == name)


@pytest.mark.parametrize("name", ["drill X    p5 d3", "drill grid p40 d30"])
def test_g81_g99_round_trip(name):
    row = _row(name)
    text = peer_gcode.drill_program(row.name, row.doc, "G99")
    same_setpoints(row.doc, program_doc(text, "mill3"), "mill3", row.start)


def test_g83_round_trip():
    row = _row("deep holes 5xD G83")
    same_setpoints(row.doc, program_doc(peer_gcode.peck_program(row.name, row.doc), "mill3"), "mill3", row.start)


def test_g76_round_trip_with_and_without_our_vibration():
    row = _row("thread M12x1.75")
    text = peer_gcode.thread_program(row.name, row.reference_doc, peer_rows.THREAD_CLEARANCE_MM, back_to_start=True)
    start = {"x": row.start["x"], "z": row.start["z"]}
    same_setpoints(row.reference_doc, program_doc(text, "lathe", start=start), "lathe", row.start)
    vibrated = text.replace("\nG76", "\n(CNC,VIBRATION D=1.5 Q=1.2 PHASE=180 DSTEP=0)\nG76", 1)
    same_setpoints(row.doc, program_doc(vibrated, "lathe", start=start), "lathe", row.start)


def test_g71_round_trip_from_the_real_stock():
    row = _row("rough cone+steps")
    text = peer_gcode.turn_program(row.name, row.doc)
    prog = program_doc(text, "lathe", start=row.start, stock=row.doc["turn"]["stock"])
    same_setpoints(row.doc, prog, "lathe", row.start)


def test_g98_keeps_travels_at_the_initial_z():
    row = _row("drill X    p5 d3")
    text = peer_gcode.drill_program(row.name, row.doc, "G98")
    job = parse_job(program_doc(text, "mill3", start=row.start))
    (_, op, _), = job.program.operations
    assert op.drill.clearance_z == pytest.approx(peer_rows.CLEARANCE_MM * 1e-3)
    with pytest.raises(JobError, match=r"^line 4: G98: the initial Z is unknown"):
        parse_job(program_doc(text, "mill3"))


def test_a_program_of_several_operations_is_one_plan():
    text = """%
(CNC,MACHINE mill3)
G21 G90 G17 G94
T1 M6 G43
M3 S3000
G0 X0 Y0 Z5
G99 G81 X0 Y0 Z-3 R2 F1200
X10
G80
G0 Z10
G98 G83 X20 Y0 Z-8 R2 Q2 F600
X30
G80
M5
M2
%"""
    assert machine_named(text) == "mill3"
    doc = program_doc(text, "mill3", tool_table=[{"tool": 1, "length": 0.0, "diameter": 6.0}])
    job = parse_job(doc)
    assert [(line, op.kind) for line, op, _ in job.program.operations] == [
        (6, "move"), (7, "drill"), (10, "move"), (11, "drill")]
    drill2 = job.program.operations[3][1].drill
    assert drill2.peck.depth == pytest.approx(2e-3) and drill2.clearance_z == pytest.approx(10e-3)
    plan = plan_job(job, load_machine("mill3"), {"x": 0.0, "y": 0.0, "z": 0.02})
    marks = [e for e in plan.events if e.name == "operation"]
    assert [e.data["line"] for e in marks] == [6, 7, 10, 11]
    assert all(a.time <= b.time for a, b in zip(marks, marks[1:]))


BAD = [
    ("G21 G90\nG0 X0 Y0 Z5\nG1 X10 F100\nG20 G21\nM2", "line 4: G21: conflicts with G20"),
    ("G21 G90\nG0 X0 Y0 Z5\nM3 S1000\nG81 X0 Y0 Z-3 F100\nM2", "line 4: G81: needs R"),
    ("G21 G90 G17\nG0 X0 Y0\nG2 X10 Y0 R4 F100\nM2", "line 3: G2: radius 4 mm cannot reach the end"),
    ("G21\nG0 X0 Y0 Z5\nG1 X1 ^45 F100\nM2", "line 3: ^: polar coordinates"),
    ("G21\nG0 X0 Y0 Z5\nG96 S100\nM2", "line 3: G96: constant surface speed cannot be held"),
    ("G21\nG0 X0 Y0 Z5\nG1 X3 F100", "line 4: end of file: the program ends without M2 or M30"),
    ("G21\nG0 X0 Y0 Z5\nG1 X3\nM2", "line 3: G1: no feed given (F)"),
    ("G21\nG0 X0 Y0 Z5 Q3\nM2", "line 2: Q3: not used by anything in this line"),
    ("G21\no100 while [1]\nM2", "line 2: ["),
    ("G21\nM3 S500\nG0 X0 Y0 Z5\nG81 X0 Y0 Z-3 R2 F0.5\nM2", "line 4: drill: drill.feed"),
]


@pytest.mark.parametrize("text,reason", BAD)
def test_bad_programs_are_refused_by_line_and_word(text, reason):
    with pytest.raises(JobError) as err:
        parse_job(program_doc(text, "mill3"))
    assert str(err.value).startswith(reason), str(err.value)
    assert err.value.field.startswith("line ")


# --- fuzzed programs -------------------------------------------------------------------------
GOOD = """G21 G90 G17 G94
M3 S3000
G0 X0 Y0 Z5
G99 G81 X0 Y0 Z-3 R2 F1200
X10 Y0
G80
G0 Z10
G1 X20 F600
M5
M2"""
GOOD_LINES = GOOD.splitlines()
CONFLICTS = ["G20 G21", "G90 G91", "G0 G1 X1", "G17 G18", "G94 G95", "M3 M5", "G98 G99", "G81 G83 X1",
             "G54 G55", "G7 G8", "G43 G49", "G90.1 G91.1"]
UNSUPPORTED = ["G19", "G41 D1", "G42", "G96 S100", "M0", "M1", "#1=2", "G1 X[1+2]", "G1 ^10 @5", "A10", "G33 Z1 K1",
               "G84 Z-1 R1", "G93", "O100 WHILE [1]", "/G1 X1", "G28", "G38.2 Z-1", "G1 X1 X2", "N5 N6", "M4",
               "G81 X0 Y0 Z-3 F100", "G83 X0 Y0 Z-3 R2 F100", "G2 X5 Y5 R1 F100", "G76 P1 Z-1 I-1 J0.1 K0.5",
               "G71 Q5 I1", "G1 Y5", "T99 M6", "G55", "(CNC,WOBBLE ON)", "G1 F-5 X1", "(unclosed", "G0 X1 Q2"]


@st.composite
def bad_programs(draw) -> tuple[str, int]:
    """A bad program and the line it must be refused at (or before)."""
    how = draw(st.sampled_from(["truncate", "conflict", "unsupported", "garbage"]))
    lines = list(GOOD_LINES)
    if how == "truncate":  # cut before its M2: LinuxCNC refuses a program without an end
        cut = draw(st.integers(1, len(lines) - 1))
        tail = draw(st.text(alphabet="GXYZ0123456789. ", max_size=6))
        lines = lines[:cut] + ([tail] if tail.strip() else [])
        return "\n".join(lines), len(lines) + 1
    at = draw(st.integers(1, len(lines) - 1))  # after line `at`, before the M2
    if how == "conflict":
        word = draw(st.sampled_from(CONFLICTS))
    elif how == "unsupported":
        word = draw(st.sampled_from(UNSUPPORTED))
    else:
        word = draw(st.sampled_from(["G", "X", "Q", "@", "G1 X", "M", "%%", "G999", "M77", "Z--1", "K"]))
    lines.insert(at, word)
    return "\n".join(lines), at + 1


_executive = Executive(load_machine("mill3"))


@FUZZ
@given(bad_programs())
def test_fuzzed_programs_are_refused_with_their_line_and_plan_nothing(case):
    text, line = case
    status = _executive.submit(json.dumps(program_doc(text, "mill3")))
    assert status.state == "rejected", text
    assert LINE.match(status.reason), status.reason
    assert int(status.reason.split(":")[0].split()[1]) <= line, (status.reason, text)
    assert "\n" not in status.reason


def test_the_executive_plans_a_good_program_after_the_fuzz():
    status = _executive.submit(json.dumps(program_doc(GOOD, "mill3")))
    assert status.state == "accepted", status.reason


# --- the pages' and config's programs ----------------------------------------------------------
def _ngc_blocks() -> list[str]:
    return re.findall(r"```ngc\n(.*?)```", (ROOT / "docs" / "gcode.md").read_text(), re.S)


@pytest.mark.parametrize("text", _ngc_blocks() + [p.read_text() for p in sorted((ROOT / "config" / "programs").glob("*.ngc"))])
def test_every_documented_program_translates_and_plans(text):
    machine = machine_named(text)
    job = parse_job(program_doc(text + ("" if "M2" in text else "\nM2\n"), machine))
    assert job.program.operations
    assert plan_job(job, load_machine(machine)).duration > 0.0


# --- over topics --------------------------------------------------------------------------------
def test_a_mill_program_of_g81_g99_and_g83_g98_runs_as_one_goal_over_topics(tmp_path):
    """cnc-run on a .ngc file: one job, statuses counting operations, one report whose program
    section holds each operation's own drill section, judged on the recorded feedback."""
    from support import cnc, load_report
    out = tmp_path / "run"
    result = cnc("cnc-run", ROOT / "config" / "programs" / "mill_g81_g83.ngc", "--out", out)
    assert result.returncode == 0, result.stderr[-2000:]
    report = load_report(out)
    assert report["state"] == "succeeded" and report["job_id"] == "mill_g81_g83"
    ops = report["program"]["operations"]
    assert [(op["line"], op["kind"]) for op in ops] == [(8, "move"), (9, "drill"), (13, "move"), (14, "drill")]
    for op, depth, holes in ((ops[1], 3.0, 3), (ops[3], 8.0, 2)):
        drill = op["drill"]
        assert drill["safety_violations"] == 0  # X/Y never off a hole below R, on feedback
        assert len(drill["holes"]) == holes
        for hole in drill["holes"]:
            assert abs(hole["depth_mm"] - depth) <= 0.005  # every hole at its own depth within 5 um
    assert ops[3]["drill"]["pecks"]["reentries"] == 6  # Q2 into 8 mm: 3 re-entries per hole
    assert "operation" in result.stdout and "4/4" in result.stdout


def test_g76_in_inches_radius_mode_with_degression():
    """LinuxCNC's G76 as its documentation writes it, in inches and radius mode (G8), degression
    R1.5: our thread cycle with LinuxCNC's pass depths J * k^(1/R), then 2 spring passes."""
    text = """G20 G18 G8 G90 G94
M3 S600
G0 X0.3 Z0.1
G76 P0.0625 Z-0.75 I-0.05 J0.005 R1.5 K0.04 Q29.5 H2 E0 L0
M5
M2"""
    job = parse_job(program_doc(text, "lathe"))
    assert [op.kind for _, op, _ in job.program.operations] == ["move", "thread"]
    line, op, doc = job.program.operations[1]
    t = doc["thread"]
    assert line == 4 and op.kind == "thread"
    assert t["major_radius"] == pytest.approx(0.25 * 25.4) and t["pitch"] == pytest.approx(1.5875)
    assert t["start_z"] == pytest.approx(2.54) and t["end_z"] == pytest.approx(-19.05)
    k = np.arange(1, len(t["depths"]))
    assert t["depths"][:-1] == pytest.approx(0.127 * k ** (1 / 1.5))
    assert t["depths"][-1] == pytest.approx(1.016) and len(t["depths"]) == 23
    assert t["spring_passes"] == 2 and t["infeed_angle"] == 29.5
    assert plan_job(job, load_machine("lathe")).duration > 0.0


def test_g71_with_p_q_blocks_in_diameter_mode():
    """G71 P/Q in diameter mode: the contour's chamfer and fillet become the profile (X halved,
    the G2 fillet a concave arc), G71's own stock the cylinder at its start point."""
    text = (ROOT / "config" / "programs" / "lathe_g71_g76.ngc").read_text()
    job = parse_job(program_doc(text, "lathe"))
    line, op, doc = job.program.operations[1]
    turn = doc["turn"]
    assert line == 10 and op.kind == "turn"
    assert turn["stock"] == [[5.0, 10.0], [-25.0, 10.0]] and turn["origin"] == [7.0, 11.0]
    assert turn["profile"][:3] == [[5.0, 5.0], [-1.0, 6.0], [-16.0, 6.0]]
    assert turn["profile"][3] == {"arc_to": [-18.0, 8.0], "center": [-16.0, 8.0], "radius": -2.0}
    assert turn["feed"] == pytest.approx(0.15) and turn["depth_of_cut"] == 1.5


def test_a_speed_change_between_operations_happens_after_the_first_one():
    """S1500 roughing then S600 threading: the spindle turns at 1500 rpm until the roughing
    ends, then slows to 600 rpm before the thread's first pass meets its helix (the axes
    may approach meanwhile, as a rapid would)."""
    text = (ROOT / "config" / "programs" / "lathe_g71_g76.ngc").read_text()
    m = load_machine("lathe")
    plan = plan_job(parse_job(program_doc(text, "lathe")), m, {"x": 0.03, "z": 0.0})
    marks = [(e.data["kind"], e.time) for e in plan.events if e.name == "operation"]
    assert [k for k, _ in marks] == ["move", "turn", "move", "thread", "move"]
    t_turn, t_after, t_thread = marks[1][1], marks[2][1], marks[3][1]
    passes = [e.time for e in plan.events if e.name == "sync" and e.time > t_thread]
    t = np.concatenate([np.linspace(t_turn + 1.0, t_after - 1e-3, 50), [passes[0] if passes else t_thread + 3.0]])
    _, v, _ = plan.sample(t)
    rpm = v[:, plan.joints.index("spindle")] * 60.0 / (2.0 * np.pi)
    assert np.allclose(rpm[:-1], 1500.0) and rpm[-1] == pytest.approx(600.0)


LATHE_PROGRAM = """(CNC,MACHINE lathe)
G21 G18 G7 G90 G94
M3 S1500
G0 X18 Z3
F300
G71 P10 Q20 X16 Z2 D0.1 I1.0 R0.5
N10 G1 X10 Z2
G1 X12 Z-1
N20 G1 Z-12
G0 X18 Z3
M3 S1000
G0 X14 Z2
G76 P1.5 Z-8 I-2 J0.6 R2 K1.84 Q29.5 H1 E0 L0
G0 X18
M5
M2
"""


def test_a_lathe_program_of_g71_and_g76_runs_as_one_goal_over_topics(tmp_path):
    """Rough (G71 P/Q, diameter mode, a chamfer) at 1500 rpm then thread (G76, degression)
    at 1000 rpm, one goal: the turn section finds no gouge, the thread reaches full depth
    along its 29.5 deg flank, each judged on its own operation's feedback."""
    from support import cnc, load_report
    path = tmp_path / "rough_thread.ngc"
    path.write_text(LATHE_PROGRAM)
    out = tmp_path / "run"
    result = cnc("cnc-run", path, "--out", out)
    assert result.returncode == 0, result.stderr[-2000:]
    ops = load_report(out)["program"]["operations"]
    assert [op["kind"] for op in ops] == ["move", "turn", "move", "thread", "move"]
    turn, thread = ops[1]["turn"], ops[3]["thread"]
    assert turn["max_gouge_part_mm"] <= 0.005 and turn["max_gouge_commanded_mm"] == 0.0
    assert thread["full_depth"] and thread["doc_never_grows"]
    assert thread["infeed_angle_deg"] == pytest.approx(29.5, abs=0.01)


def test_cancel_mid_program_ends_in_a_controlled_stop(tmp_path):
    """A program canceled in its first drill operation: canceled, the commanded motion
    jerk-limited to rest within the axes' acceleration limits, the program not finished."""
    from cnc_analysis.recording import read_run
    from cnc_planner.runner import Session
    from support import running_past
    doc = yaml.safe_load((ROOT / "config" / "jobs" / "program_mill3.yaml").read_text())
    machine = load_machine("mill3")
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(json.dumps(doc))
        running_past(session, doc["job_id"], 0.3)
        session.cancel(doc["job_id"])
        final = session.wait(doc["job_id"], 60)
        assert final["state"] == "canceled", final
        session.settle(final)
    run = read_run(tmp_path / "bag")
    for axis in ("x", "y", "z"):
        v = run.command_velocity[:, run.column(axis)]
        assert np.abs(np.diff(v) / np.diff(run.command_t)).max() <= machine.axes[axis].max_acceleration * 1.01
        assert abs(v[-1]) < 1e-9 and abs(run.feedback_velocity[-1, run.column(axis)]) < 1e-4  # at rest
    # The program did not run to its end: no job_end was published (where the stop lands
    # depends on how late the cancel arrives, which a loaded host changes; that it stops does not).
    assert not [e for e in run.events if e.get("job_id") == doc["job_id"] and e["name"] == "job_end"]
