"""Tool tables and program files (cnc_msgs_py.gcode.tools, .document): LinuxCNC's tool.tbl
read whole with errors naming file and line, T/M6/M61/G43/G43 H/G49 applying its lengths,
a machine's own table, ``--tools FILE``, ``--spindle RPM``, and subroutine files found on the
search path."""
from __future__ import annotations

import json

import pytest

from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.gcode.tools import load_tool_table, parse_tool_table
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job
from cnc_msgs_py.machine import load_machine

TABLE = """; two drills
T1 P1 Z30.0 D6.0 ;6 mm drill
t2 p2 z45.5 d10 i0 j0 q0 ; 10 mm drill, lower case as some tables write it
"""

TWO_DRILLS = """(CNC,MACHINE mill3)
G21 G90 G17 G94
T1 M6
G43
M3 S3000
G0 X0 Y0 Z10
G99 G81 X0 Y0 Z-3 R2 F600
X10
G80
T2 M6
G43 H2
G0 Z10
G98 G81 X30 Y0 Z-6 R2 F400
G80
G49
G0 Z20
M5
M2
"""


def test_a_tool_table_in_linuxcncs_format():
    assert parse_tool_table(TABLE) == [{"tool": 1, "length": 30.0, "diameter": 6.0},
                                       {"tool": 2, "length": 45.5, "diameter": 10.0}]


@pytest.mark.parametrize("text,reason", [
    ("T1 Z3\nT1 Z4", "t.tbl line 2: T1 given twice"),
    ("T1 X2 Z3", "t.tbl line 1: T1: X2: only the Z length is applied"),
    ("Z3 D1", "t.tbl line 1: needs T"),
    ("T1.5 Z3", "t.tbl line 1: needs T"),
    ("T1 Z3 R2", "t.tbl line 1: T1: R is not a tool table word"),
    ("T1 Z=3", "t.tbl line 1: cannot read"),
])
def test_bad_tool_tables_are_refused_by_line(text, reason):
    with pytest.raises(JobError) as err:
        parse_tool_table(text, "t.tbl")
    assert str(err.value).startswith(reason), str(err.value)


def test_two_drills_from_the_tool_table_with_g43(tmp_path):
    (tmp_path / "two.ngc").write_text(TWO_DRILLS)
    (tmp_path / "tool.tbl").write_text(TABLE)
    doc = job_document(tmp_path / "two.ngc", tools=tmp_path / "tool.tbl")
    job = parse_job(doc)
    drills = [(op.tool.length, op.tool.diameter, [list(map(float, h)) for h in op.drill.holes]) for _, op, _ in job.program.operations
              if op.kind == "drill"]
    assert drills == [(pytest.approx(30e-3), pytest.approx(6e-3), [[0.0, 0.0], [0.01, 0.0]]),
                      (pytest.approx(45.5e-3), pytest.approx(10e-3), [[0.03, 0.0]])]
    last = job.program.operations[-1][1]
    assert last.kind == "move" and last.tool.length == 0.0  # G49: no length applied
    assert plan_job(job, load_machine("mill3"), {"x": 0.0, "y": 0.0, "z": 0.06}).duration > 0.0


def test_the_machines_own_table_m61_and_g43_h():
    text = "G21 G90 G17\nM61 Q3\nG43 H5\nM3 S1000\nG0 X0 Y0 Z5\nG1 Z0 F100\nM2"
    (_, op, _), = parse_job({"schema": "cnc_job/1", "job_id": "t", "kind": "program", "machine": "mill3",
                             "program": {"gcode": text}}).program.operations
    mill = load_tool_table("config/machines/mill3.tbl")
    assert op.tool.diameter == pytest.approx(mill[2]["diameter"] * 1e-3)  # T3 in the spindle
    assert op.tool.length == pytest.approx(mill[4]["length"] * 1e-3)  # T5's length (H5)
    with pytest.raises(JobError, match=r"^line 2: T42: no such tool in the tool table"):
        parse_job({"schema": "cnc_job/1", "job_id": "t", "kind": "program", "machine": "mill3",
                   "program": {"gcode": "G21\nT42 M6\nM2"}})


def test_spindle_gives_a_program_the_spindle_an_operator_started(tmp_path):
    from support import ROOT, cnc
    program = tmp_path / "no_m3.ngc"  # as LinuxCNC's hole-circle.ngc: no S, no M3
    program.write_text("(CNC,MACHINE mill3)\nG21 G90 G17\nG0 X0 Y0 Z5\nG98 G81 X5 Y0 Z-2 R1 F300\nG80\nM2\n")
    assert job_document(program, spindle_rpm=1500)["program"]["start"] == {"spindle_rpm": 1500}
    result = cnc("cnc-plan", program, "--out", tmp_path / "off", timeout=60)
    assert result.returncode == 2 and result.stderr.startswith("cnc-plan: line 4: G81: the spindle is off: ")
    result = cnc("cnc-plan", program, "--spindle", "1500", "--out", tmp_path / "on", timeout=60)
    assert result.returncode == 0, result.stderr
    summary = json.loads((tmp_path / "on" / "summary.json").read_text())
    assert [e["name"] for e in summary["events"]].count("S3") == 1  # the hole drilled to its bottom
    with pytest.raises(JobError, match=r"^spindle: the spindle at a program's start is for G-code programs"):
        job_document(ROOT / "config" / "jobs" / "drill_row.yaml", spindle_rpm=1500)


def test_a_subroutine_file_on_the_search_path_goes_into_the_document(tmp_path, monkeypatch):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "hole.ngc").write_text("o<hole> sub\n  G98 G81 X#1 Y#2 Z-2 R1 F300\n  G80\no<hole> endsub\nM2\n")
    (tmp_path / "main.ngc").write_text("(CNC,MACHINE mill3)\nG21 G90 G17\nM3 S2000\nG0 X0 Y0 Z5\n"
                                       "o<hole> call [5] [5]\no<HOLE> call [15] [5]\nM2\n")
    with pytest.raises(JobError, match=r"^line 5: o<hole> call: no such subroutine"):
        parse_job(job_document(tmp_path / "main.ngc"))
    monkeypatch.setenv("CNC_SUBROUTINE_PATH", str(lib))
    doc = job_document(tmp_path / "main.ngc")
    assert [s["name"] for s in doc["program"]["subroutines"]] == ["hole"]
    holes = [[list(map(float, h)) for h in op.drill.holes] for _, op, _ in parse_job(doc).program.operations if op.kind == "drill"]
    assert holes == [[[0.005, 0.005], [0.015, 0.005]]]  # one drill operation: the same cycle words


def test_g10_sets_a_tool_length_or_touches_one_off():
    """G10 L1 writes tool 2's length and radius into the program's copy of the table; G10
    L10 sets tool 1's length so that where it stands reads Z2 (a touch-off); L2/L11 and
    axis offsets are refused with the reason."""
    def operations(text: str) -> list:
        return parse_job({"schema": "cnc_job/1", "job_id": "t", "kind": "program", "machine": "mill3",
                          "program": {"gcode": text, "tool_table": [{"tool": 1, "length": 30.0},
                                                                    {"tool": 2, "length": 40.0}]}}).program.operations
    prefix = "G21 G90 G17\nM3 S1000\nT1 M6\nG43\nG0 X0 Y0 Z10\n"
    ops = operations(prefix + "G10 L1 P2 Z52.5 R3\nT2 M6\nG43\nG1 Z5 F100\nG10 L10 P2 Z2\nG1 X1\nM2")
    assert [round(op.tool.length * 1e3, 9) for _, op, _ in ops] == [30.0, 52.5, 55.5]
    assert ops[1][1].tool.diameter == pytest.approx(6e-3)
    _, _, last = ops[-1]
    assert last["move"][-1]["linear"] == {"x": 1.0, "y": 0.0, "z": 2.0}  # the axis stayed; its reading is Z2
    for text, reason in (("G10 L2 P10 X5", "line 6: P10: names no coordinate system"),
                         ("G10 L11 P1 Z1", "line 6: G10 L11: the G59.3 fixture's offsets are the machine's"),
                         ("G10 L1 P1 X1 Z5", "line 6: X1: only the Z length is applied"),
                         ("G10 L1 P7 Z5", "line 6: P7: no such tool in the tool table")):
        with pytest.raises(JobError) as err:
            operations(prefix + text + "\nM2")
        assert str(err.value).startswith(reason), str(err.value)
