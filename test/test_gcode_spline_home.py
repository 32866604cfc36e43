"""G5.1 quadratic splines (cnc_msgs_py.gcode.splines) and G28/G30, G28.1/G30.1
(cnc_msgs_py.gcode.homes), as LinuxCNC 2.9 reads them.

- The oracle program (test/gcode_oracle/splines_g5_1_g28.ngc): every feed end and every rapid
  that moves which rs274 -g makes of it (recorded by bench/peer/examples.py in
  bench/results/rs274_examples.json) is ours, in order, within 1 um, program coordinates.
  rs274 prints a spline as NURBS_FEED with no points: our chords of it are what is left, and
  they are checked against the curve by hand (start, control point and end from the words),
  within the arcs' chord tolerance, the end exact.
- Hand values: a spline's midpoint, G28 with and without an intermediate point, G28.1 and
  G30.1 storing machine coordinates, the power-up home as the default; the refusals.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.arcs import CHORD_TOLERANCE_MM
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.gcode.translate import Translator
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAM = ROOT / "test" / "gcode_oracle" / "splines_g5_1_g28.ngc"
TIP_TOLERANCE_MM = 1e-3
# the program's splines by hand: start, start + (I, J), end (X, Y), at Z-1
SPLINES = [((0, 0), (5, 5), (10, 0)), ((10, -2), (15, -7), (20, -2)), ((20, -2), (20, 3), (15, 3))]
TOOLS = {1: {"length": 20.0, "diameter": 6.0}}


def _bezier(start, control, end, t: np.ndarray) -> np.ndarray:
    p0, p1, p2 = (np.asarray(p, float) for p in (start, control, end))
    t = t[:, None]
    return (1 - t) ** 2 * p0 + 2 * t * (1 - t) * p1 + t ** 2 * p2


def _farthest(curve: np.ndarray, polyline: np.ndarray) -> float:
    """How far the curve's samples get from the polyline (its segments)."""
    a, b = polyline[:-1], polyline[1:]
    d = b - a
    t = np.clip(np.einsum("psk,sk->ps", curve[:, None, :] - a[None], d) / np.einsum("sk,sk->s", d, d), 0, 1)
    near = a[None] + t[..., None] * d[None]
    return float(np.min(np.linalg.norm(curve[:, None, :] - near, axis=2), axis=1).max())


def test_every_feed_end_and_rapid_is_linuxcncs_and_the_chords_follow_the_curve():
    moves, error = oracle.canonical_moves(oracle.recorded(examples.RS274_RECORDED)(PROGRAM.read_text()))
    assert error is None, error
    theirs, at = [], None
    for m in moves:  # rs274 prints G28's and G30's moves that go nowhere too; our moves all move
        if m.end != at:
            theirs.append(("linear" if m.kind == "feed" else "rapid", m.end))
        at = m.end
    job = parse_job(job_document(PROGRAM))
    ours = [(k, tuple(m[k][a] for a in "xyz")) for _, _, doc in job.program.operations for m in doc["move"] for k in m
            if k in ("rapid", "linear")]
    # set LinuxCNC's ends in order among ours; what is left is the splines' chords
    left, j = [], 0
    for kind, end in ours:
        if j < len(theirs) and kind == theirs[j][0] and np.allclose(end, theirs[j][1], atol=TIP_TOLERANCE_MM):
            j += 1
        else:
            left.append(end)
    assert j == len(theirs) == 17
    assert [k for k, _ in theirs].count("rapid") == 9  # the G0s and G28/G30's legs that move
    start = 0
    for s, c, e in SPLINES:
        n = next(k for k in range(start, len(left)) if left[k][:2] == e) + 1 - start
        points = np.array(left[start:start + n])
        start += n
        assert np.all(points[:, 2] == -1.0) and tuple(points[-1, :2]) == e  # the end exact
        polyline = np.vstack([s, points[:, :2]])
        assert _farthest(_bezier(s, c, e, np.linspace(0, 1, 4001)), polyline) <= CHORD_TOLERANCE_MM
        assert np.allclose(points[:, :2], _bezier(s, c, e, np.arange(1, n + 1) / n), atol=1e-12)
    assert start == len(left) == 50 + 50 + 43  # ceil(sqrt(|c''| / 8 um)): |c''| = 20, 20, 2 sqrt(50) mm
    plan_job(job, load_machine("mill3"))


def test_a_splines_midpoint_and_end():
    ops = translate("G21 G90 G17\nG0 X0 Y0 Z0\nG1 F100\nG5.1 X10 Y0 I5 J5\nM2", Context("t", "mill3"))
    feeds = [m["linear"] for m in ops[0].doc["move"] if "linear" in m]
    assert len(feeds) == 50  # |c''| = 2 |(0,0) - 2 (5,5) + (10,0)| = 20 mm: 20 / 8 / 50^2 = 1 um
    assert feeds[24] == {"x": 5.0, "y": 2.5, "z": 0.0}  # start/4 + control/2 + end/4, t = 1/2
    assert feeds[-1] == {"x": 10.0, "y": 0.0, "z": 0.0}
    # G91: X Y from the start; I J always from the start; Y left out stays; inches under G20
    ops = translate("G20 G90 G17\nG0 X1 Y1 Z0\nG91 G5.1 X1 I0.5 J1 F10\nM2", Context("t", "mill3"))
    feeds = np.array([[m["linear"][a] for a in "xy"] for m in ops[0].doc["move"] if "linear" in m])
    assert tuple(feeds[-1]) == (50.8, 25.4)
    mid = 25.4 * np.array([1 / 4 + 1.5 / 2 + 2 / 4, 1 / 4 + 2 / 2 + 1 / 4])  # start (1, 1), control (1.5, 2), end (2, 1)
    assert _farthest(mid[None], np.vstack([[25.4, 25.4], feeds])) <= CHORD_TOLERANCE_MM


def test_g5_1_leaves_the_motion_mode_in_force():
    """As rs274 reads it: after G0, G5.1, the next line's X20 is a rapid (#<_motion_mode> 0)."""
    tr = Translator(Context("t", "mill3"))
    ops = tr.run("G21 G0 X0 Y0 Z0\nG5.1 X10 Y0 I5 J5 F100\n#1=#<_motion_mode>\nX20\nM2")
    assert ops[0].doc["move"][-1] == {"rapid": {"x": 20.0, "y": 0.0, "z": 0.0}}
    assert tr.params.read(1) == 0.0


@pytest.mark.parametrize("text,reason", [
    ("G5.1 X10 Y0 I5", "line 3: G5.1: needs both I and J"),
    ("G5.1 X10 Y0 J5", "line 3: G5.1: needs both I and J"),
    ("G5.1 I5 J5", "line 3: G5.1: needs X or Y"),
    ("G18 G5.1 X10 I5 J5", "line 3: G5.1: splines lie in the XY plane (G17)"),
    ("G5.1 X10 Z1 I5 J5", "line 3: Z1: a G5.1 spline moves X and Y only"),
    ("G5.1 X10 I5 J5 P1", "line 3: P1: not used by anything in this line"),
    ("G1 G5.1 X10 I5 J5", "line 3: G5.1: conflicts with G1"),
    ("G53 G5.1 X10 I5 J5", "line 3: G53: machine coordinates are for straight moves"),
    ("T1 M6\nG41 G1 X1\nG5.1 X10 I5 J5", "line 5: G5.1: cannot convert a spline (G5.1) with cutter radius compensation"),
    ("G1 G28 X2", "line 3: G28: cannot share a line with G1: both take the axis words"),
    ("G28 @1", "line 3: G28: polar words (@ ^) are for motion"),
    ("G53 G28", "line 3: G28: conflicts with G53 in the same line"),
    ("G10 L2 P1 R30\nG28 X0", "line 4: G28: machine coordinates under a rotated coordinate system"),
    ("T1 M6\nG41 G1 X1\nG30", "line 5: G30: cannot use G28 or G30 with cutter radius compensation on"),
    ("#5161=1", "line 3: #5161: LinuxCNC keeps it in its var file"),
])
def test_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        translate(f"G21 G90 G17 F100\nG0 X0 Y0 Z0\n{text}\nM2", Context("t", "mill3", tool_table=TOOLS))
    assert str(err.value).startswith(reason), str(err.value)


def test_a_spline_from_an_unknown_position_waits_for_the_start():
    with pytest.raises(GcodeError) as err:
        translate("G21 G5.1 X1 I1 J1 F100\nM2", Context("t", "mill3"))
    assert err.value.needs_start


def _rapids(text: str, machine: str = "mill3") -> list[dict]:
    ops = translate(f"G21 G90 G17\n{text}\nM2", Context("t", machine, tool_table=TOOLS))
    return [m["rapid"] for op in ops for m in op.doc["move"] if "rapid" in m]


def test_g28_without_a_stored_position_goes_to_the_machines_power_up_home():
    # mill3's home: X0 Y0 and Z 50 mm (machine coordinates); with T1's 20 mm under G43 the tip reads Z30
    assert _rapids("G0 X1 Y2 Z3\nG28") == [{"x": 1.0, "y": 2.0, "z": 3.0}, {"x": 0.0, "y": 0.0, "z": 50.0}]
    assert _rapids("T1 M6 G43\nG28")[-1] == {"x": 0.0, "y": 0.0, "z": 30.0}
    # G54 at X10 (the job's setup): machine X0 reads X-10; the lathe's home is X30 Z10 (mm), it has no Y
    ops = translate("G21 G0 X1 Y2 Z3\nG28\nM2", Context("t", "mill3", setup={"origin": [10.0, 0.0, 0.0]}))
    assert ops[0].doc["move"][-1] == {"rapid": {"x": -10.0, "y": 0.0, "z": 50.0}}
    assert _rapids("G28", "lathe") == [{"x": 30.0, "z": 10.0}]
    # the parameters read it (mm, machine coordinates), A B C U V W 0
    tr = Translator(Context("t", "mill3"))
    tr.run("G21 G0 X1\n" + "".join(f"#{k + 1}=#{n}\n" for k, n in enumerate((5161, 5162, 5163, 5164, 5183)))
           + "M2")
    assert [tr.params.read(k) for k in range(1, 6)] == [0.0, 0.0, 50.0, 0.0, 50.0]


def test_g28_through_an_intermediate_point_moves_only_the_named_axes_home():
    # absolute: to Z12 first, then Z alone home; incremental: G91 G28 Z0 goes straight up from where it is
    assert _rapids("G0 X1 Y2 Z3\nG28 Z12") == [{"x": 1.0, "y": 2.0, "z": 3.0}, {"x": 1.0, "y": 2.0, "z": 12.0},
                                             {"x": 1.0, "y": 2.0, "z": 50.0}]
    assert _rapids("G0 X1 Y2 Z3\nG91 G28 Z1") == [{"x": 1.0, "y": 2.0, "z": 3.0}, {"x": 1.0, "y": 2.0, "z": 4.0},
                                                {"x": 1.0, "y": 2.0, "z": 50.0}]
    # the motion mode in force stays: G1 before G28, so X5 after it is a feed
    ops = translate("G21 G0 X1 Y2 Z3\nG1 X2 F100\nG28 Z12\nX5\nM2", Context("t", "mill3"))
    assert ops[0].doc["move"][-1] == {"linear": {"x": 5.0, "y": 2.0, "z": 50.0}, "feed": 100.0}


def test_g28_1_and_g30_1_store_the_machine_position():
    # at program X1 Y2 Z3 under G43 (20 mm), G54 at X10, G92 Z0 (offset 3): machine X11 Y2 Z23
    tr = Translator(Context("t", "mill3", tool_table=TOOLS, setup={"origin": [10.0, 0.0, 0.0]}))
    ops = tr.run("G21 G90 T1 M6 G43\nG0 X1 Y2 Z3\nG92 Z0\nG28.1 X4\nG30.1\n#1=#5161\n#2=#5163\n#3=#5181\n#4=#5183\n"
                 "G0 X0 Y0 Z5\nG28 Y1\nG30\nM2")
    assert [tr.params.read(k) for k in range(1, 5)] == [11.0, 23.0, 14.0, 23.0]  # G28.1 X4 stores, then moves
    rapids = [m["rapid"] for op in ops for m in op.doc["move"]]
    assert rapids[-3:] == [{"x": 0.0, "y": 1.0, "z": 5.0}, {"x": 0.0, "y": 2.0, "z": 5.0},
                           {"x": 4.0, "y": 2.0, "z": 0.0}]


def test_g28_is_refused_for_the_machine_where_it_cannot_go():
    with pytest.raises(GcodeError) as err:
        translate("G21 G28\nM2", Context("t", "5ax_table_table"))
    assert "has no fixed frame for machine coordinates" in str(err.value)
    with pytest.raises(GcodeError) as err:
        translate("G21 G28.1\nM2", Context("t", "mill3"))
    assert str(err.value).startswith("line 1: G28.1: the X position is unknown here") and err.value.needs_start


def test_a_g28_out_of_travel_is_refused_for_the_machine(tmp_path):
    program = tmp_path / "far.ngc"
    program.write_text("(CNC,MACHINE mill3)\nG21 G90 G0 X0 Y0 Z5\nG28 Z500\nG1 X1 F100\nM2\n")
    with pytest.raises(JobError) as err:
        plan_job(parse_job(job_document(program)), load_machine("mill3"))
    assert str(err.value).startswith("line 2: move: move[1].rapid: puts axis z at 500.000 mm, outside its travel")
