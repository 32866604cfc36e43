"""Coordinate systems as LinuxCNC 2.9 keeps them (cnc_msgs_py.gcode.offsets): G10 L2/L20, G92,
G52, G92.1/.2/.3, G54..G59.3 and G53.

- The oracle program (test/gcode_oracle/offsets_g10_g92_g53.ngc) ends every feed move where
  rs274 -g ends it (recorded by bench/peer/examples.py in bench/results/rs274_examples.json),
  within 1 um, in program coordinates, and each operation's setup puts it on the table
  where LinuxCNC's offsets put it.
- The parameters read what rs274 prints for them (#5210-#5213, #5221, #5222, #5230, #5420,
  #5421; in mm, as a LinuxCNC machine in mm keeps its var file).
- G53 is a machine position: the tool length and every offset taken off.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.gcode.translate import Translator
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAM = ROOT / "test" / "gcode_oracle" / "offsets_g10_g92_g53.ngc"
TIP_TOLERANCE_MM = 1e-3


def _table(doc: dict, point: dict) -> np.ndarray:
    """A program point on the table through an operation's setup (the planner's formula)."""
    setup = doc["setup"]
    ax, ay, az = (math.radians(a) for a in setup.get("rotation_deg", [0, 0, 0]))
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    p = np.array([point["x"], point["y"], point["z"]])
    return rz @ ry @ rx @ p + np.array(setup.get("origin", [0, 0, 0]))


def test_every_feed_end_is_linuxcncs_and_the_setups_place_it_on_the_table():
    text = PROGRAM.read_text()
    moves, error = oracle.canonical_moves(oracle.recorded(examples.RS274_RECORDED)(text))
    assert error is None, error
    theirs = np.array([m.end for m in moves if m.kind == "feed"])
    job = parse_job(job_document(PROGRAM))
    docs = [doc for _, _, doc in job.program.operations]
    ours = np.array([[m["linear"][a] for a in "xyz"] for d in docs for m in d["move"] if "linear" in m])
    assert theirs.shape == ours.shape == (10, 3)
    assert np.max(np.abs(theirs - ours)) <= TIP_TOLERANCE_MM
    # the table (machine) points, by hand: G92 X0 Y0 at X10 Y20 shifts the program by (10, 20)
    first_feed = next(d for d in docs if any("linear" in m for m in d["move"]))
    assert np.allclose(_table(first_feed, first_feed["move"][0]["linear"]), [11.0, 20.0, 30.0], atol=1e-12)
    # G10 L2 P1 X100 R30 then G1 X5: the tool stays on its Y; on the table X5 lies 30 deg turned about (100, 0)
    rotated = docs[5]
    assert rotated["setup"] == {"origin": [100.0, 0.0, 0.0], "rotation_deg": [0.0, 0.0, 30.0]}
    end = _table(rotated, rotated["move"][0]["linear"])
    assert np.allclose(end, [100 + 5 * math.cos(math.radians(30)) - 62.820508075688764 * 0.5,
                             5 * 0.5 + 62.820508075688764 * math.cos(math.radians(30)), 30.0], atol=1e-9)
    # G10 L20 P1 X7: the tool stands still on the table while its reading becomes X7
    touched = docs[6]
    assert np.allclose(_table(touched, {"x": 7.0, "y": 62.820508075688764, "z": 30.0}), end, atol=1e-9)
    # G53 G0 Z0 on mill3 with no tool length: the table Z is 0
    g53 = docs[7]["move"][1]["rapid"]
    assert _table(docs[7], g53)[2] == 0.0
    plan_job(job, load_machine("mill3"))


def _params(text: str, numbers: list[int], **ctx) -> list[float]:
    tr = Translator(Context("t", "mill3", **ctx))
    reads = "".join(f"#{100 + k}=#{n}\n" for k, n in enumerate(numbers))
    tr.run(text + reads + "G1 X1 F100\nM2")
    return [tr.params.read(100 + k) for k in range(len(numbers))]


@pytest.mark.parametrize("words,numbers,values", [
    ("G92 X0 Y0", [5210, 5211, 5212, 5213], [1, 10, 20, 0]),
    ("G92 X0 Y0\nG52 X5", [5210, 5211, 5212, 5420, 5421], [1, 5, 20, 5, 0]),
    ("G92 X0 Y0\nG52 X5\nG92.2", [5210, 5211, 5212, 5420], [0, 5, 20, 10]),
    ("G92 X0 Y0\nG52 X5\nG92.2\nG92.3", [5210, 5211, 5212, 5420], [1, 5, 20, 5]),
    ("G92 X0 Y0\nG92.1", [5210, 5211, 5212, 5420], [0, 0, 0, 10]),
    ("G10 L2 P1 X100 R30", [5221, 5230, 5420, 5421], [100, 30, -67.942286, 62.320508]),
    ("G10 L2 P1 X100 R30\nG10 L20 P1 X7", [5221, 5222, 5230, 5420, 5421], [35.0981, -37.4711, 30, 7, 62.320508]),
    ("G10 L2 P2 X7\nG55", [5220, 5420, 5241], [2, 3, 7]),
    ("G10 L2 P9 Z1\nG59.3", [5220, 5383, 5422], [9, 1, 29]),
    ("G91 G10 L2 P1 X5\nG10 L2 P1 X5", [5221], [5]),  # absolute under G91, as rs274 reads it
    ("G7 G18 G92 X10", [5211, 5420], [5, 5]),  # X a diameter under G7
])
def test_the_offset_parameters_read_as_rs274s(words, numbers, values):
    got = _params(f"G21 G90 G17\nG0 X10 Y20 Z30\n{words}\n", numbers)
    assert got == pytest.approx(values, abs=1e-4)


def test_coordinate_system_names_and_the_jobs_own_offsets():
    got = _params("G21 G90 G17\nG0 X10 Y20 Z30\nG55\n", [5220, 5241, 5420, 5230],
                  setup={"origin": [1, 2, 3], "rotation_deg": [0, 0, 15]}, work_offsets={"G55": {"origin": [4, 5, 6]}})
    c, s = math.cos(math.radians(15)), math.sin(math.radians(15))
    assert got == pytest.approx([2.0, 4.0, 1 + 10 * c - 20 * s - 4, 15.0], abs=1e-12)  # the tool stood still
    tr = Translator(Context("t", "mill3"))
    tr.run("G21 G10 L2 P8 X1\nG59.2\nG0 X0\n#1=#<_coord_system>\nM2")
    assert tr.params.read(1) == 592.0
    # an operation keeps the job's setup as written while the program changes nothing
    ops = translate("G21 G90\nG0 X1 Y1 Z1\nG55\nG0 X2\nM2", Context("t", "mill3", setup={"origin": [1, 2, 3]},
                                                                   work_offsets={"G55": {"origin": [4, 5, 6]}}))
    assert [op.doc["setup"] for op in ops] == [{"origin": [1, 2, 3]}, {"origin": [4, 5, 6]}]


def test_g53_is_the_machine_position_with_the_tool_length_and_the_offsets_taken_off():
    ops = translate("G21 G90 G17\nT1 M6 G43\nG10 L2 P1 X4 Z3\nG52 Z1\nG0 X0 Y0 Z0\nG53 G0 Z0 X10\nG1 X1 F100\nM2",
                    Context("t", "mill3", tool_table={1: {"length": 25.0, "diameter": 6.0}}))
    doc = ops[-1].doc
    assert doc["move"][1] == {"rapid": {"x": 6.0, "y": 0.0, "z": -29.0}}  # 10 - 4; 0 - 25 - 3 - 1
    assert doc["move"][2]["linear"] == {"x": 1.0, "y": 0.0, "z": -29.0}  # G53 is for its line only
    table = _table(doc, doc["move"][1]["rapid"])
    assert table[0] == 10.0 and table[2] + 25.0 == 0.0  # the spindle nose at machine Z0


@pytest.mark.parametrize("text,reason", [
    ("G0 X0 Y0 Z0\nG55", "line 2: G55: machine 'mill3' keeps no G55 work offset"),
    ("G0 X0\nG10 L2 X1", "line 2: G10 L2: needs P"),
    ("G0 X0\nG10 L20 P1 X1 R3", "line 2: R3: G10 L20 sets no rotation"),
    ("G10 L20 P1 X1", "line 1: G10 L20: the tool's X position is unknown here"),
    ("G92 X1", "line 1: G92: the X position is unknown here"),
    ("G0 X0\nG92", "line 2: G92: needs an axis word"),
    ("G0 X0 Y0 Z0\nG53 G2 X1 Y1 R1", "line 2: G53: needs G0 or G1"),
    ("G0 X0 Y0 Z0\nG10 L2 P1 R10\nG53 G0 X1", "line 3: G53: machine coordinates under a rotated coordinate system"),
    ("G0 X0 Y0 Z0\nG53 G92 X1", "line 2: G92: conflicts with G53"),
])
def test_offset_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        translate(f"{text}\nG1 X1 F1\nM2", Context("t", "mill3"))
    assert str(err.value).startswith(reason), str(err.value)


def test_g53_on_a_machine_whose_rotaries_carry_the_setup_is_refused_for_the_machine():
    with pytest.raises(GcodeError) as err:
        translate("G21 G0 X0 Y0 Z0\nG53 G0 Z0\nM2", Context("t", "5ax_table_table"))
    assert "has no fixed frame for machine coordinates" in str(err.value), str(err.value)
