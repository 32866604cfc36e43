"""G64 P as our path tolerance (cnc_msgs_py.gcode.path_tolerance): under G64 P consecutive feed
moves at one feed are one path operation, run on without stopping at each point, the tip
within P of the programmed path on the drive model's feedback; G61 stops at every point again.

- The oracle program (test/gcode_oracle/path_tolerance_g64.ngc): every feed and arc end rs274 -g
  makes of it (recorded by bench/peer/examples.py) is one of our path points or feed ends, in
  order, within 1 um, and every one of ours lies on LinuxCNC's path.
- Planned and judged on the predicted feedback: the path verdict passes within P, and the
  program is quicker than the same one under G61.
- What stays a move (stopping at its end) and why; P in inches under G20.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import compensation_oracle  # noqa: E402  bench/peer/compensation_oracle.py
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAM = ROOT / "test" / "gcode_oracle" / "path_tolerance_g64.ngc"
MILL = load_machine("mill3")


def test_the_path_runs_through_linuxcncs_feed_ends():
    output, cuts, job, ours = compensation_oracle.compared(PROGRAM, oracle.recorded(examples.RS274_RECORDED))
    assert oracle.canonical_moves(output)[1] is None
    assert compensation_oracle.agree(cuts, ours)  # LinuxCNC's ends among ours in order, ours on its path
    kinds = [(line, op.kind) for line, op, _ in job.program.operations]
    assert kinds == [(6, "move"), (9, "path"), (16, "move"), (18, "path"), (19, "move")]
    (_, path, doc) = job.program.operations[1]
    assert doc["path"]["chord_tolerance"] == 0.02 and doc["path"]["feed"] == 1200.0
    assert doc["path"]["points"][:3] == [[0.0, 0.0, -1.0], [30.0, 0.0, -1.0], [30.0, 15.0, -1.0]]


def test_the_path_is_judged_within_p_and_is_quicker_than_exact_stops():
    doc = job_document(PROGRAM)
    plan = plan_job(parse_job(doc), MILL)
    report = build_report(predicted_run(doc, plan, MILL), MILL)
    sections = report["program"]["operations"]
    judged = [s["kinematics"] for s in sections if s["kind"] == "path"]
    assert len(judged) == 2 and all(k["verdict"]["passed"] for k in judged), judged
    assert all(k["max_tip_deviation_mm"] <= 0.02 for k in judged), judged
    exact = dict(doc, program={**doc["program"], "gcode": doc["program"]["gcode"].replace("G64 P0.02", "G61")})
    stopping = plan_job(parse_job(exact), MILL)
    assert [op.kind for _, op, _ in parse_job(exact).program.operations] == ["move"]
    assert plan.duration < stopping.duration - 1.0, (plan.duration, stopping.duration)


def _kinds(text: str, machine: str = "mill3") -> list[str]:
    return [op.doc["kind"] for op in translate(text + "\nM2", Context("t", machine))]


@pytest.mark.parametrize("text", [
    "G21 G94 G0 X0 Y0 Z0\nG64\nG1 X5 F100\nG1 Y5",  # G64 without P: stops, as without G64
    "G21 G94 G0 X0 Y0 Z0\nG64 P0\nG1 X5 F100\nG1 Y5",  # P0: LinuxCNC's unbounded blending
    "G21 G94 S1000 M3 G0 X0 Y0 Z0\n(CNC,VIBRATION D=1.5 Q=1.2)\nG64 P0.01\nG1 X5 F100\nG1 Y5",  # vibrated
    "G21 G94 G0 X0 Y0 Z0\nG64 P0.01\nG61\nG1 X5 F100\nG1 Y5",  # G61 after it
])
def test_what_stays_a_move(text):
    assert "path" not in _kinds(text)


def test_a_lathe_keeps_its_moves_and_inches_convert_p():
    assert _kinds("G21 G18 G94 G0 X10 Z5\nG64 P0.01\nG1 Z0 F100\nG1 X12", "lathe") == ["move"]
    ops = translate("G20 G94 G0 X0 Y0 Z0\nG64 P0.002\nG1 X1 F10\nG1 Y1\nM2", Context("t", "mill3"))
    assert ops[1].doc["path"]["chord_tolerance"] == pytest.approx(0.0508)
    assert ops[1].doc["path"]["points"] == [[0.0, 0.0, 0.0], [25.4, 0.0, 0.0], [25.4, 25.4, 0.0]]
    with pytest.raises(GcodeError, match=r"^line 1: P-1: a path tolerance must be >= 0"):
        translate("G21 G64 P-1\nM2", Context("t", "mill3"))
