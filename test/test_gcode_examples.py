"""Real programs against LinuxCNC 2.9.

- Our must-show programs (test/programs/: a bolt circle from a while loop, a hole pattern
  from a subroutine called with arguments, two drills from the machine's tool table with
  G43): every feed move's end point that LinuxCNC's interpreter makes of them (rs274 -g with
  the machine's tool table, recorded by bench/peer/examples.py in
  bench/results/rs274_examples.json) is our operation's tool-tip target within 1 um,
  program coordinates, in order, without LinuxCNC installed; the planned command turns at
  each of those bottoms, pre-compensated for the drive's lag.
- LinuxCNC's own machining examples (/usr/share/linuxcnc/ncfiles, GPL, never copied here):
  each one plans, its report passing on the drive model's predicted feedback, or is refused
  for a machine reason, as bench/results/linuxcnc_examples.json records it (those that never start the spindle with it started ahead, as an operator's MDI
  would: --spindle); where the files are installed the test runs them again and checks that
  they are the recorded files.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode import machine_named
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAMS = sorted((ROOT / "test" / "programs").glob("*.ngc"))
MILLING = [p for p in PROGRAMS if machine_named(p.read_text()) != "lathe"]
LATHE_PROGRAM = ROOT / "test" / "programs" / "lathe_css_g96_g76.ngc"
TIP_TOLERANCE_MM = 1e-3
PRECOMPENSATION_M = 50e-6  # the command turns at most this far above a hole's bottom
SAMPLE_S = 5e-5


def _feed_targets(operations) -> list[tuple[float, float, float]]:
    """Our feed moves' end points (mm, program coordinates, the tool tip) in program order:
    each drill hole's bottom, each straight feed's target."""
    out = []
    for _, op, doc in operations:
        if op.kind == "drill":
            d = doc["drill"]
            out += [(x, y, d["surface_z"] - d["depth"]) for x, y in d["holes"]]
        elif op.kind == "move":
            out += [(m["linear"]["x"], m["linear"]["y"], m["linear"]["z"]) for m in doc["move"] if "linear" in m]
    return out


def _turning_points(plan, lengths_by_time) -> np.ndarray:
    """The planned Z command's lowest points (m, the tool tip): where each hole turns."""
    t = np.arange(0.0, plan.duration, SAMPLE_S)
    p, _, _ = plan.sample(t, ("x", "y", "z"))
    p[:, 2] -= lengths_by_time(t)
    z = p[:, 2]
    low = np.where((z[1:-1] < z[:-2]) & (z[1:-1] <= z[2:]))[0] + 1
    return p[low]


@pytest.mark.parametrize("path", MILLING, ids=[p.stem for p in MILLING])
def test_every_linuxcnc_feed_end_is_our_tool_tip_target(path):
    """Every feed move LinuxCNC makes of the program ends where ours does (1 um, in order),
    and our planned Z command turns at each hole's bottom: a little short of it, as the
    drill method pre-compensates the drive's lag so that the feedback lands there
    (docs/drill.md: within 5 um on feedback)."""
    text = path.read_text()
    moves, error = oracle.canonical_moves(oracle.recorded(examples.RS274_RECORDED)(text))
    assert error is None, error
    theirs = np.array([m.end for m in moves if m.kind == "feed"])
    job = parse_job(job_document(path))
    ours = np.array(_feed_targets(job.program.operations))
    assert theirs.shape == ours.shape and len(ours) >= 5
    assert np.max(np.abs(theirs - ours)) <= TIP_TOLERANCE_MM
    plan = plan_job(job, load_machine("mill3"))
    starts = np.array([e.time for e in plan.events if e.name == "operation"])
    lengths = np.array([op.tool.length for _, op, _ in job.program.operations])
    turns = _turning_points(plan, lambda t: lengths[np.clip(np.searchsorted(starts, t, side="right") - 1, 0, None)])
    bottoms = ours[np.isin(ours[:, 2], [d["surface_z"] - d["depth"] for _, op, d in job.program.operations
                                        if op.kind == "drill" for d in [d["drill"]]])] * 1e-3
    for bottom in bottoms:
        gap = turns - bottom
        near = np.hypot(gap[:, 0], gap[:, 1]) < 1e-9
        assert near.any() and 0.0 <= np.min(gap[near, 2]) <= PRECOMPENSATION_M, (path.name, bottom)


def test_linuxcnc_reads_the_constant_surface_speed_program_as_we_do():
    """lathe_css_g96_g76.ngc through rs274 (recorded): G96 D3000 S120 sets LinuxCNC's spindle mode
    to constant surface speed capped at 3000 rpm before the roughing and G97 S600 back to rpm
    before the thread, as ours reads them; its G71 levels and contour (D from our profile) and
    its G76 passes are ours within rs274's printed resolution (bench/peer/oracle.py). Its feed
    moves are not ours one by one: our roughing starts each pass at the stock (docs/turn.md)."""
    text = LATHE_PROGRAM.read_text()
    interpret = oracle.recorded(examples.RS274_RECORDED)
    calls = [ln.split("N..... ")[1] for ln in interpret(text).splitlines() if "SPINDLE_MODE" in ln or "SPINDLE_SPEED" in ln]
    assert calls[:4] == ["SET_SPINDLE_MODE(0 3000.0000)", "SET_SPINDLE_SPEED(0, 120.0000)",
                         "SET_SPINDLE_MODE(0 0.0000)", "SET_SPINDLE_SPEED(0, 600.0000)"]
    ops = parse_job(job_document(LATHE_PROGRAM)).program.operations
    assert [(op.kind, doc.get("surface_speed"), doc.get("spindle_rpm")) for _, op, doc in ops if op.kind != "move"] == [
        ("turn", {"m_min": 120.0, "max_rpm": 3000.0}, None), ("thread", None, 600.0)]
    lines = oracle.check_program(LATHE_PROGRAM.stem, text, [(line, op.kind, doc) for line, op, doc in ops], interpret)
    assert len(lines) == 2 and all(" same within " in line for line in lines), lines


def test_the_must_show_programs_make_what_they_say():
    ops = {p.stem: parse_job(job_document(p)).program.operations for p in PROGRAMS}
    circle = [op.drill.holes for _, op, _ in ops["bolt_circle_while"] if op.kind == "drill"]
    assert len(circle) == 1 and len(circle[0]) == 8
    radii = np.hypot(*np.asarray(circle[0]).T)
    assert np.allclose(radii, 0.03, atol=1e-12)
    rows = [(len(op.drill.holes), op.drill.depth) for _, op, _ in ops["hole_pattern_sub"] if op.kind == "drill"]
    assert [(n, round(d * 1e3, 9)) for n, d in rows] == [(5, 3.0), (4, 6.0)]
    drills = [(round(op.tool.length * 1e3, 9), round(op.tool.diameter * 1e3, 9), len(op.drill.holes))
              for _, op, _ in ops["two_drills_g43"] if op.kind == "drill"]
    assert drills == [(15.0, 3.0, 3), (25.0, 10.0, 2)]  # T3 and T2 of config/machines/mill3.tbl


def test_linuxcncs_example_programs_plan_or_are_refused_with_their_reason():
    recorded = json.loads(examples.RESULTS.read_text())
    machining = {name: r for name, r in recorded.items() if "outcome" in r}
    assert sorted(name for name, r in machining.items() if r["outcome"] == "plans") == [
        "3D_Chips.ngc", "3dtest.ngc", "arcspiral.ngc", "cds.ngc", "comp-g1.ngc", "comp.ngc", "comp311.ngc",
        "comp311_2.ngc", "flowsnake.ngc", "g76.ngc", "gmoccapy_2_tools_with_cutter_radius_compensation.ngc",
        "hole-circle.ngc", "lathe-g76.ngc", "lathe_g70_71_demo.ngc", "lathe_g7x_face_boring.ngc", "lathe_pawn.ngc",
        "lathecomp.ngc", "offsets.ngc", "polar.ngc", "skeleton.ngc", "spiral.ngc", "threading.ngc", "toplevel.ngc",
        "tort.ngc"]
    assert all(r["rs274"] == "reads" for r in machining.values() if r["outcome"] == "plans")
    for name, r in machining.items():
        assert r["outcome"] in ("plans", "machine"), (name, r["detail"])  # each plans, or the machine refuses it
        assert r["outcome"] == "plans" or r["detail"].startswith("line "), (name, r["detail"])
        if "spindle_ahead_rpm" in r:  # it never starts the spindle: run as after the operator's S1000 M3
            assert "the spindle is off" in r["without_spindle"], (name, r["without_spindle"])
        if r["outcome"] == "plans":  # and its report passes on the predicted run from the machine's home
            assert r["judged"] == "passes", (name, r["judged"])
    assert sorted(name for name, r in machining.items() if "spindle_ahead_rpm" in r) == [
        "hole-circle.ngc", "lathe_g70_71_demo.ngc", "lathe_g7x_face_boring.ngc", "lathe_g7x_quadrants.ngc",
        "polar.ngc"]
    assert set(recorded) - set(machining) == set(examples.LEFT_OUT)
    if not examples.NCFILES.is_dir():
        return  # LinuxCNC is not installed: the recorded outcomes are what there is to check
    for name, r in machining.items():
        path = examples.NCFILES / name
        assert hashlib.sha256(path.read_bytes()).hexdigest() == r["sha256"], f"{name} is not the recorded file"
        if "spindle_ahead_rpm" in r:
            assert examples.ours(path, r["machine"]) == ("program", r["without_spindle"]), name
        if r["outcome"] != "plans":  # refusals are quick; planning them all takes minutes
            assert examples.ours(path, r["machine"], r.get("spindle_ahead_rpm")) == (r["outcome"], r["detail"]), name
