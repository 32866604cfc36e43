"""What a program takes from the machine it runs on, as LinuxCNC's does: where the tool stands
when the program begins (a G91 move or G92 before any absolute move), the spindle an
operator started before cycle start (program.start.spindle_rpm, --spindle), the work offsets
the machine keeps in its var file (G55..), and the probe it lacks (G38.x refused for that
machine reason). Hand-computed positions, planned from given joints and judged by the
report on the drive model's predicted feedback."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

MILL = load_machine("mill3")
START = {"x": 0.012, "y": -0.034, "z": 0.05}  # joints (m): where the machine stands


def program(gcode: str, **block) -> dict:
    return {"schema": "cnc_job/1", "job_id": "p", "kind": "program", "machine": "mill3",
            "program": {"gcode": gcode, **block}}


def end_of(doc: dict, start: dict[str, float]) -> dict[str, float]:
    plan = plan_job(parse_job(doc), MILL, start)
    p, _, _ = plan.sample(np.array([plan.duration]))
    return {j: float(p[0, plan.joints.index(j)]) for j in "xyz"}


def test_an_incremental_move_before_any_absolute_one_starts_where_the_machine_stands():
    doc = program("G21 G91 G1 X5 Y-2 F600\nM2")
    job = parse_job(doc)
    assert job.program.start_from_machine
    end = end_of(doc, START)
    assert end["x"] == pytest.approx(START["x"] + 0.005, abs=1e-9)
    assert end["y"] == pytest.approx(START["y"] - 0.002, abs=1e-9)
    assert end["z"] == pytest.approx(START["z"], abs=1e-9)
    elsewhere = {"x": -0.1, "y": 0.0, "z": 0.02}
    assert end_of(doc, elsewhere)["x"] == pytest.approx(-0.095, abs=1e-9)


def test_g92_before_any_move_reads_the_machines_position():
    # G92 X0: here is X0; then G90 X10 is 10 mm on from where the machine stood
    end = end_of(program("G21 G90 G92 X0\nG1 X10 F600\nM2"), START)
    assert end["x"] == pytest.approx(START["x"] + 0.010, abs=1e-9)


def test_a_given_start_or_an_absolute_first_move_does_not_take_the_machines_position():
    assert not parse_job(program("G21 G90 G0 X1 Y2 Z3\nG91 G1 X5 F600\nM2")).program.start_from_machine
    given = program("G21 G91 G1 X5 F600\nM2", start={"x": 100.0, "y": 0.0, "z": 50.0})
    assert not parse_job(given).program.start_from_machine
    assert end_of(given, START)["x"] == pytest.approx(0.105, abs=1e-9)


def test_the_report_judges_the_operations_from_where_the_recording_starts():
    # G91 holes from where the machine stands (x 12, y -34, z 50 mm): R 45 mm below the
    # initial Z (5 mm), the bottom 5 mm below R, the holes 10 mm apart from x 12
    doc = program("G21 S1000 M3 F100\nG91 G98 G81 X10 Y0 R-45 Z-5 L2\nM2")
    plan = plan_job(parse_job(doc), MILL, START)
    report = build_report(predicted_run(doc, plan, MILL), MILL)
    drill = report["program"]["operations"][0]["drill"]
    assert [h["x_mm"] for h in drill["holes"]] == pytest.approx([22.0, 32.0], abs=1e-9)
    assert [h["depth_mm"] for h in drill["holes"]] == pytest.approx([3.0, 3.0], abs=0.005)  # from 2 mm below R
    assert drill["verdict"]["passed"] and report["program"]["verdict"]["passed"], report["program"]["verdict"]


def test_g55_comes_from_the_machines_var_file_and_the_program_overrides_it(tmp_path, monkeypatch):
    gcode = "G21 G90 G55 G0 X0 Y0 Z5\nG1 X10 F600\nM2"
    with pytest.raises(JobError, match=r"line 1: G55: machine 'mill3' keeps no G55 work offset"):
        parse_job(program(gcode))
    (tmp_path / "mill3.var").write_text("5221 0.0\n5241 100.0\n5242 -20.0\n5243 0.0\n5250 0.0\n")
    monkeypatch.setenv("CNC_MACHINE_PATH", str(tmp_path))
    op = parse_job(program(gcode)).program.operations[0][2]
    assert op["setup"]["origin"] == [100.0, -20.0, 0.0]
    op = parse_job(program(gcode, work_offsets={"G55": {"origin": [1.0, 2.0, 3.0]}})).program.operations[0][2]
    assert op["setup"]["origin"] == [1.0, 2.0, 3.0]
    (tmp_path / "mill3.var").write_text("5241 oops\n")
    with pytest.raises(JobError, match=r"mill3.var: line 1: expected '<parameter number> <value>'"):
        parse_job(program(gcode))


@pytest.mark.parametrize("line,reason", [("G38.2 Z-10 F100", "G38.2: machine 'mill3' has no probe input"),
                                         ("M64 P0", "M64: machine 'mill3' has no digital or analog I/O"),
                                         ("M66 P0 L3 Q5", "M66: machine 'mill3' has no digital or analog I/O")])
def test_probing_and_io_are_refused_for_what_the_machine_lacks(line, reason):
    with pytest.raises(JobError, match=rf"^line 2: {reason}"):
        parse_job(program(f"G21 G90 G0 X0 Y0 Z5\n{line}\nM2"))


@pytest.mark.parametrize("text", ["G21 G91 G1 X1 F60", "G21 G92 X1", "G21 G0 X#<_z>", "G21 G2 X1 Y1 R1 F60",
                                  "G21 S900 M3 F60 G98 G81 X1 Y1 R2 Z-1"])
def test_a_position_read_before_the_program_gives_it_is_the_machines(text):
    from cnc_msgs_py.gcode import Context, GcodeError, translate
    with pytest.raises(GcodeError) as err:
        translate(f"{text}\nM2", Context("t", "mill3"))
    assert err.value.needs_start, str(err.value)
    assert parse_job(program(f"{text}\nG90 G1 X7 F60\nM2")).program.start_from_machine


def test_a_program_that_never_starts_the_spindle_runs_with_the_one_the_operator_started():
    # hole-circle.ngc's shape: LinuxCNC's simulator examples drill without S or M3
    gcode = "G21 G90 G17\nG0 X10 Y10 Z5\nG98 G81 X10 Y10 Z-3 R2 F200\nG80\nM2"
    with pytest.raises(JobError, match=r"^line 3: G81: the spindle is off: give S and M3 before it, or start it "
                                       r"ahead \(program.start.spindle_rpm, --spindle RPM\)$"):
        parse_job(program(gcode))
    job = parse_job(program(gcode, start={"spindle_rpm": 1200}))
    drill = job.program.operations[1][1]
    assert drill.kind == "drill" and drill.spindle_rpm == pytest.approx(1200 * 2 * np.pi / 60)
    assert not job.program.start_from_machine  # the spindle given, the position still absolute
    # the program's own S and M5 change it as any S M3 would; #<_rpm> reads it
    with pytest.raises(JobError, match=r"^line 3: G81: the spindle is off"):
        parse_job(program(gcode.replace("G17", "G17 M5"), start={"spindle_rpm": 1200}))
    rpm = parse_job(program(gcode.replace("G17", "G17 S[#<_rpm>*2]"), start={"spindle_rpm": 600})).program
    assert rpm.operations[1][1].spindle_rpm == pytest.approx(1200 * 2 * np.pi / 60)
    with pytest.raises(JobError, match=r"^program.start.spindle_rpm: must be > 0 rpm, got 0$"):
        parse_job(program(gcode, start={"spindle_rpm": 0}))


def test_a_spindle_given_at_the_start_still_lets_the_program_start_where_the_machine_stands():
    doc = program("G21 G91 G98 G81 X10 Y0 R-45 Z-5 F100\nM2", start={"spindle_rpm": 1000})
    assert parse_job(doc).program.start_from_machine
    assert end_of(doc, START)["x"] == pytest.approx(START["x"] + 0.010, abs=1e-9)
