"""Cutter radius compensation as LinuxCNC 2.9 makes it (cnc_msgs_py.gcode.compensation):
G41/G42 (D a tool of the table, else the tool in the spindle), G41.1/G42.1 (D the diameter),
G40, in the XY (G17) and XZ (G18, the lathe) planes.

- The oracle programs (test/gcode_oracle/mill_g41_g42.ngc, lathe_g42.ngc): every feed and arc
  end rs274 -g makes of them (recorded by bench/peer/examples.py) is one of our feed moves'
  ends, in order, within 1 um, and every one of ours lies on LinuxCNC's path; they plan.
- The geometry by hand: the entry ends offset perpendicular to it, outside corners get an
  arc of the tool radius about the corner, inside corners end where the offsets cross, an
  arc's radius grows or shrinks by the tool radius, the move after G40 runs from the last
  offset point to the programmed one.
- LinuxCNC's refusals, in our form.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import compensation_oracle  # noqa: E402  bench/peer/compensation_oracle.py
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

TIP_TOLERANCE_MM = 1e-3


@pytest.mark.parametrize("name,machine", [("mill_g41_g42.ngc", "mill3"), ("lathe_g42.ngc", "lathe")])
def test_compensated_paths_end_where_linuxcncs_do_and_plan(name, machine):
    output, cuts, job, ours = compensation_oracle.compared(ROOT / "test" / "gcode_oracle" / name,
                                                           oracle.recorded(examples.RS274_RECORDED))
    assert oracle.canonical_moves(output)[1] is None
    assert compensation_oracle.TOLERANCE_MM == TIP_TOLERANCE_MM
    assert compensation_oracle.agree(cuts, ours)  # LinuxCNC's ends among ours in order, ours on its path
    assert len(cuts) >= 9
    assert plan_job(job, load_machine(machine)).duration > 0.0


MILL = "G21 G90 G17 G94 F100\nG0 X-10 Y-10 Z1\nG1 Z-1\n"


def _moves(text: str, **ctx) -> list[dict]:
    ops = translate(MILL + text + "\nM2", Context("t", "mill3", **ctx))
    return [m for op in ops for m in op.doc["move"]][2:]


def _ends(moves: list[dict]) -> list[tuple[float, float]]:
    return [(round(m["linear"]["x"], 9), round(m["linear"]["y"], 9)) for m in moves if "linear" in m]


def test_the_offset_path_by_hand():
    # G41 (left), tool radius 1 from the table (T1 D2): entry to (0, 0) along 45 deg, then a square's corner
    moves = _moves("T1 M6\nG41 G1 X0 Y0\nG1 X10\nG1 Y10\nG2 X20 Y20 R10\nG40 G1 X25 Y25", tool_table={1: {"diameter": 2.0}})
    ends = _ends(moves)
    h = math.sqrt(0.5)
    assert ends[0] == (round(-h, 9), round(h, 9))  # the entry ends offset perpendicular to itself
    assert ends[ends.index((0.0, 1.0)) + 1] == (9.0, 1.0)  # an outside corner's arc ends on y = 1; the inside corner at (9, 1)
    assert (9.0, 10.0) in ends and ends[-2] == (20.0, 21.0)  # the G2 arc grew from radius 10 to 11 about (20, 10)
    assert ends[-1] == (25.0, 25.0)  # after G40, straight to the programmed point
    arc = ends[ends.index((9.0, 10.0)) + 1:-1]
    assert all(abs(math.hypot(x - 20.0, y - 10.0) - 11.0) < 1e-9 for x, y in arc)
    corner = ends[1:ends.index((0.0, 1.0)) + 1]  # the arc about the entry's corner, radius 1 about (0, 0)
    assert all(abs(math.hypot(x, y) - 1.0) < 1e-9 for x, y in corner)
    # G42.1 D4 (right, radius 2), the same square: the other side; a Z step waits at the offset point
    ends = _ends(_moves("G42.1 D4 G1 X0 Y0\nG1 X10\nG1 Z-2\nG1 Y10\nG40 G1 X20"))
    # the entry's offset (parallel, through its perpendicular end) meets y = -2 at the inside corner, as LinuxCNC's
    assert ends[0] == (round(2 * math.sqrt(2.0) - 2.0, 9), -2.0) and (10.0, -2.0) in ends and ends[-2] == (12.0, 10.0)
    assert ends[ends.index((10.0, -2.0)) + 1] == (10.0, -2.0)  # the Z step, where the path stands
    # a corner turning less than 0.05 rad is taken as tangent, as LinuxCNC's: no trim (inside), no arc
    # (outside); a corner turning more gets its arc (rs274: (10, 1), (19.97, 1.2996), arc, (30.03, 0.9996))
    ends = _ends(_moves("G41.1 D2 G1 X0 Y0\nG1 X10\nG1 X20 Y0.3\nG1 X30 Y0\nG40 G1 X40"))
    k = ends.index((10.0, 1.0))
    assert ends[k + 1] == pytest.approx((20.0 - 0.3 / math.hypot(10, 0.3), 0.3 + 10 / math.hypot(10, 0.3)), abs=1e-9)
    assert ends[-2] == pytest.approx((30.0 + 0.3 / math.hypot(10, 0.3), 10 / math.hypot(10, 0.3)), abs=1e-9)
    assert len(ends) > k + 4  # the arc about (20, 0.3): it turns 3.4 deg
    ends = _ends(_moves("G41.1 D2 G1 X0 Y0\nG1 X10\nG1 X20 Y-0.3\nG1 X30 Y-0.3\nG40 G1 X40"))
    k = ends.index((10.0, 1.0))  # turning right by 1.7 deg on the outside: straight on, no arc
    assert ends[k + 1] == pytest.approx((20.0 + 0.3 / math.hypot(10, 0.3), -0.3 + 10 / math.hypot(10, 0.3)), abs=1e-9)
    assert ends[k + 2] == (30.0, 0.7)
    # a dwell waits in its place, at the inside corner's point
    moves = _moves("G41.1 D2 G1 X0 Y0\nG1 X10\nG4 P1\nG1 Y10\nG40 G1 X20")
    k = moves.index({"dwell": 1.0})
    assert moves[k - 1]["linear"] == {"x": 9.0, "y": 1.0, "z": -1.0} and moves[k + 1]["linear"]["y"] == 10.0
    # a tool of radius 0 (G41.1 D0) leaves the path as programmed
    assert _ends(_moves("G41.1 D0 G1 X0 Y0\nG1 X10\nG40 G1 X20")) == [(0.0, 0.0), (10.0, 0.0), (20.0, 0.0)]


@pytest.mark.parametrize("text,reason", [
    ("G41.1 D2 G1 X5 Y0\nG41.1 D2 G1 X10", "line 5: G41.1: cannot turn cutter radius compensation on when it is on"),
    ("G19 G41.1 D2 G1 Y5", "line 4: G41.1: cutter radius compensation is allowed only in the XY and XZ planes"),
    ("G41.1 D2 G1 X5 Y0\nG81 X1 Y1 Z-1 R1", "line 5: G81: cannot use canned cycles with cutter radius compensation on"),
    ("G41.1 D2 G1 X5 Y0\nG53 G1 X1", "line 5: G53: cannot use G53 with cutter radius compensation on"),
    ("G41.1 D2 G1 X5 Y0\nT1 M6", "line 5: M6: cannot change tools with cutter radius compensation on"),
    ("G41.1 D2 G1 X5 Y0\nG92 X0", "line 5: G92: cannot change axis offsets with cutter radius compensation on"),
    ("G41.1 D2 G1 X5 Y0\nG1 X10\nG40 G2 X20 Y0 R5", "line 6: G2: the move just after cutter compensation goes off"),
    ("G41.1 D2 G1 X-9.5 Y-10\nG1 X10", "line 4: G41/G42: the entry move is not longer than the tool radius (1 mm)"),
    ("G41.1 D2 G1 X5 Y0\nG1 X10\nG1 Y0.5\nG1 X0", "line 6: G41/G42: the inside corner at (10, 0) is too small"),
    ("G41.1 D4 G1 X5 Y0\nG1 X10\nG3 X12 Y2 R2\nG1 Y5", "line 6: G41/G42: an inside arc of radius 2 mm is not larger"),
    ("G41.1 G1 X5", "line 4: G41.1: needs D, the cutter's diameter"),
    ("G41 D7 G1 X5", "line 4: D7: no such tool in the tool table"),
])
def test_linuxcncs_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        _moves(text + "\nG40", tool_table={1: {"diameter": 2.0}})
    assert str(err.value).startswith(reason), str(err.value)


def test_a_lathe_tool_compensates_by_nothing_and_its_move_operation_plans():
    text = ("(CNC,MACHINE lathe)\nG18 G21 G8 G90 G95\nT2 M6\nM3 S1000\nF0.1\nG0 X12 Z4\nG42 G1 X5 Z1\nG1 Z-10\n"
            "G1 X8\nG40 G0 X14 Z4\nM2\n")
    job = parse_job({"schema": "cnc_job/1", "job_id": "t", "kind": "program", "machine": "lathe",
                     "program": {"gcode": text}})  # the machine's table: T2 is an insert, D0
    (_, op, doc), = job.program.operations
    assert "diameter" not in doc["tool"]
    assert [(m["linear"]["x"], m["linear"]["z"]) for m in doc["move"] if "linear" in m] == [
        (5.0, 1.0), (5.0, -10.0), (8.0, -10.0)]
    assert plan_job(job, load_machine("lathe")).duration > 0.0
