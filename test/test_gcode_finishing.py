"""G70 finishing (cnc_msgs_py.gcode.finishing) and the offset paths it shares with cutter
compensation (cnc_msgs_py.gcode.compensation), and a G7x contour LinuxCNC refuses.

- test/gcode_oracle/lathe_g70.ngc (two passes, a chamfer, an inside shoulder, an outside
  round, an inside fillet): every feed and arc end rs274 -g makes of it (recorded by
  bench/peer/examples.py in bench/results/rs274_examples.json) is one of our feed moves'
  ends, in order, within 1 um; every one of ours lies on LinuxCNC's path (compensation_oracle.agree:
  ends within 1 um, chord middles within 1.5 um); the operation plans on the lathe.
- The offset geometry against hand-computed corners.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.compensation import Segment, offset_path
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import compensation_oracle  # noqa: E402  bench/peer/compensation_oracle.py
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

TIP_TOLERANCE_MM = 1e-3
LATHE = "G18 G21 G8 G90 G94\nM3 S1000\nF100\nG0 X12 Z3\n"


@pytest.mark.parametrize("name,count", [("lathe_g70.ngc", 20), ("lathe_g70_sides.ngc", 24)])
def test_g70_ends_every_feed_move_where_linuxcnc_does_and_plans(name, count):
    output, cuts, job, ours = compensation_oracle.compared(ROOT / "test" / "gcode_oracle" / name,
                                                           oracle.recorded(examples.RS274_RECORDED))
    assert oracle.canonical_moves(output)[1] is None
    assert len(cuts) == count and len(ours) >= len(cuts)
    assert compensation_oracle.agree(cuts, ours)  # LinuxCNC's ends among ours in order, ours on its path
    assert plan_job(job, load_machine("lathe")).duration > 0.0


def test_outside_corners_get_an_arc_and_inside_corners_meet():
    # a square's corner turning left, offset 1 to the right (outside): an arc about the corner
    path = [Segment((0.0, 0.0), (10.0, 0.0)), Segment((10.0, 0.0), (10.0, 10.0))]
    right = offset_path(path, 1.0)
    assert right == [Segment((0.0, -1.0), (10.0, -1.0)), Segment((10.0, -1.0), (11.0, 0.0), (10.0, 0.0), False),
                     Segment((11.0, 0.0), (11.0, 10.0))]
    left = offset_path(path, -1.0)  # the inside: both lines end where they cross
    assert left == [Segment((0.0, 1.0), (9.0, 1.0)), Segment((9.0, 1.0), (9.0, 10.0))]
    # a G3 quarter arc of radius 5 (its center on the left of travel) grows to 6 on the right, shrinks on the left
    arc = [Segment((5.0, 0.0), (0.0, 5.0), (0.0, 0.0), False)]
    assert offset_path(arc, 1.0)[0] == Segment((6.0, 0.0), (0.0, 6.0), (0.0, 0.0), False)
    assert offset_path(arc, -1.0)[0] == Segment((4.0, 0.0), (0.0, 4.0), (0.0, 0.0), False)
    # a line running tangent into an arc: the offsets meet, nothing added
    tangent = [Segment((0.0, 5.0), (-5.0, 5.0)), Segment((-5.0, 5.0), (-8.0, 2.0), (-5.0, 2.0), False)]
    assert offset_path(tangent, 1.0) == [Segment((0.0, 6.0), (-5.0, 6.0)),
                                         Segment((-5.0, 6.0), (-9.0, 2.0), (-5.0, 2.0), False)]
    # a line into an arc turning away on the inside (G70's shoulder into a round, in (z, x)): they meet
    # where the shifted line x = 8.35 crosses the grown circle of radius 2.35 about (-17, 8)
    inside = offset_path([Segment((-10.0, 8.0), (-15.0, 8.0)), Segment((-15.0, 8.0), (-17.0, 10.0), (-17.0, 8.0), False)],
                         0.35)
    meet = (-17.0 + math.sqrt(2.35 ** 2 - 0.35 ** 2), 8.35)
    assert len(inside) == 2 and inside[0].end == pytest.approx(meet, abs=1e-12) and inside[1].start == inside[0].end
    assert inside[1].end == pytest.approx((-17.0, 10.35), abs=1e-12)


@pytest.mark.parametrize("path,d,reason", [
    ([Segment((5.0, 0.0), (0.0, 5.0), (0.0, 0.0), False)], -5.0, "an inside arc of radius 5 mm is not larger"),
    ([Segment((0.0, 0.0), (10.0, 0.0)), Segment((10.0, 0.0), (10.0, 1.0)), Segment((10.0, 1.0), (0.0, 1.0))], -1.0,
     "the inside corner at (10, 0) is too small"),
    ([Segment((0.0, 0.0), (10.0, 0.0)), Segment((10.0, 0.0), (0.0, 0.0))], 1.0, "the path turns back on itself at (10, 0)"),
])
def test_offsets_the_contour_cannot_follow_are_refused(path, d, reason):
    with pytest.raises(ValueError) as err:
        offset_path(path, d)
    assert str(err.value).startswith(reason), str(err.value)


@pytest.mark.parametrize("text,reason", [
    ("o1 sub\nG1 X5 Z0\nG1 Z-5\no1 endsub\nG70 Q1 P0\nM2", "line 9: P0: the number of passes must be a whole number >= 1"),
    ("o1 sub\nG1 X5 Z0\no1 endsub\nG70 Q1\nM2", "line 8: G70: the contour needs at least two points"),
    ("o1 sub\nG1 X5 Z0\nG1 X3 Z-2\nG1 Z-3\no1 endsub\nG70 Q1 D6 P2\nM2", "line 10: G70: the inside corner"),
    ("o1 sub\nG1 X5 Z0\nG1 Z-5\nG1 X8 Z-3\nG1 X10 Z-8\no1 endsub\nG71.1 Q1 X12 Z3 I1 D0\nM2",
     "line 11: G71.1: G7X error: Not monotonic: the contour runs back against the passes (-z) at Z-3"),
])
def test_g70_and_g7x_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        translate(LATHE + text, Context("t", "lathe"))
    assert str(err.value).startswith(reason), str(err.value)


def test_g70_p_q_after_a_g71_p_q_finishes_that_contour_as_the_sub_form_does():
    contour = "G1 X10 Z5\nG1 X12 Z-1\nG1 Z-16\nG2 X16 Z-18 R2\nG1 Z-25\n"
    head = "G21 G18 G7 G90 G94\nM3 S1500\nG0 X22 Z7\nF225\n"
    blocks = "N10 G1 X10 Z5\nG1 X12 Z-1\nG1 Z-16\nG2 X16 Z-18 R2\nN20 G1 Z-25\n"
    numbered = head + "G71 P10 Q20 X20 Z5 D0.2 I1.5 R0.5\n" + blocks + "G70 P10 Q20 X22 Z7\nG0 X30\nM2"
    sub = head + "o100 sub\n" + contour + "o100 endsub\nG71 Q100 X20 Z5 D0.2 I1.5 R0.5\nG70 Q100 X22 Z7\nG0 X30\nM2"
    finish = [[op.doc for op in translate(text, Context("t", "lathe")) if op.doc["kind"] == "move"][-1]["move"]
              for text in (numbered, sub)]
    assert finish[0] == finish[1] and sum("linear" in m for m in finish[0]) > 4
    assert finish[0][1]["linear"] == {"x": 6.0, "z": -1.0}  # the contour itself (one pass, D0): the chamfer's end
