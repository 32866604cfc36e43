"""M70-M73 (cnc_msgs_py.gcode.saved_state): the modal state saved and restored as LinuxCNC
2.9 does it. The oracle program (test/gcode_oracle/modal_state_m70_m73.ngc) ends every feed
move where rs274 -g ends it (recorded by bench/peer/examples.py in
bench/results/rs274_examples.json), within 1 um; its moves are also checked by hand."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAM = ROOT / "test" / "gcode_oracle" / "modal_state_m70_m73.ngc"


def _feeds(docs: list[dict]) -> list[tuple[list[float], float]]:
    return [([m["linear"][a] for a in "xyz"], m["feed"]) for d in docs for m in d["move"] if "linear" in m]


def test_every_feed_end_is_linuxcncs_and_each_restore_brings_back_units_distance_mode_and_feed():
    moves, error = oracle.canonical_moves(oracle.recorded(examples.RS274_RECORDED)(PROGRAM.read_text()))
    assert error is None, error
    theirs = np.array([m.end for m in moves if m.kind == "feed"])
    job = parse_job(job_document(PROGRAM))
    feeds = _feeds([doc for _, _, doc in job.program.operations])
    ours = np.array([end for end, _ in feeds])
    assert theirs.shape == ours.shape == (10, 3)
    assert np.max(np.abs(theirs - ours)) <= 1e-3  # rs274 prints inches to 4 places under G20
    # By hand: G20 G91 X1 is 25.4 mm on; M72 brings back G21 G90 F200, so X10 is absolute;
    # the subroutine's M73 brings them back at its endsub (X20 absolute, F200 again); M71
    # forgets without restoring, so G20 stays (F200 is then 200 in/min) until the end.
    assert [round(x, 6) for x in ours[:, 0]] == [0.0, 25.4, 10.0, 22.7, 22.7, 20.0, 20.0, 32.7, 32.7, 0.0]
    assert [round(f, 6) for _, f in feeds] == [200.0, 127.0, 200.0, 50.8, 50.8, 200.0, 5080.0, 50.8, 50.8, 5080.0]
    plan_job(job, load_machine("mill3"))


@pytest.mark.parametrize("text, reason", [
    ("M72\n", "line 2: M72: no state saved with M70 here to restore (or M71 forgot it)"),
    ("M70\nM71\nM72\n", "line 4: M72: no state saved with M70 here to restore (or M71 forgot it)"),
    ("M71\n", "line 2: M71: no state saved with M70 here to forget"),
    ("M73\n", "line 2: M73: saves the state for a subroutine's return: outside one, use M70"),
    ("M70 M72\n", "line 2: M72: conflicts with M70 in the same line (both modal state)"),
])
def test_a_restore_with_nothing_saved_is_refused_at_its_line(text, reason):
    with pytest.raises(GcodeError) as err:
        translate("G0 X0 Y0 Z1\n" + text + "G1 X1 F100\nM2\n", Context("m7x", "mill3"))
    assert str(err.value) == reason


def test_m70_in_a_subroutine_is_that_calls_own_and_a_restored_work_system_keeps_the_tool():
    text = """G0 X0 Y0 Z1
o<inner> sub
M70
G55
G1 X1 F100
M72
o<inner> endsub
o<inner> call
M72
M2
"""
    with pytest.raises(GcodeError, match="line 9: M72: no state saved with M70 here"):  # saved in the call
        translate(text, Context("m7x", "mill3", work_offsets={"G55": {"origin": [10.0, 0.0, 0.0]}}))
    ops = translate(text.replace("M72\nM2", "M2"),
                    Context("m7x", "mill3", work_offsets={"G55": {"origin": [10.0, 0.0, 0.0]}}))
    assert ops[-1].doc["setup"]["origin"][0] == 10.0  # the feed ran in G55
