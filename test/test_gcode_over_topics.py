"""The must-show G-code programs over topics (cnc-run: planner and bridge nodes, DDS on this
host), each one goal, judged on the recorded feedback: a bolt circle from a while loop, a hole
pattern from a subroutine called with arguments, two drills from the machine's tool table
with G43, a lathe program roughing at constant surface speed then threading at one rpm
(test/programs/, checked against LinuxCNC's interpreter in test_gcode_examples.py)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ROOT / "test" / "programs"


def _run(tmp_path: Path, name: str) -> dict:
    from support import cnc, load_report
    out = tmp_path / "run"
    result = cnc("cnc-run", PROGRAMS / f"{name}.ngc", "--out", out)
    assert result.returncode == 0, result.stderr[-2000:]
    report = load_report(out)
    assert report["state"] == "succeeded" and report["job_id"] == name
    return report


def _drills(report: dict) -> list[dict]:
    return [op["drill"] for op in report["program"]["operations"] if op["kind"] == "drill"]


@pytest.mark.parametrize("name,depths", [
    ("bolt_circle_while", [4.0] * 8),
    ("hole_pattern_sub", [3.0] * 5 + [6.0] * 4),
    ("two_drills_g43", [3.0] * 3 + [8.0] * 2),
])
def test_a_parameterised_program_drills_every_hole_on_feedback(tmp_path, name, depths):
    """Each drill operation's own judge on its share of the feedback: no X/Y motion while the
    tip is below R, every hole at its depth (the drill's verdict: +0.005/-0.2 mm), the holes
    where the program's parameters put them."""
    report = _run(tmp_path, name)
    drills = _drills(report)
    assert all(d["safety_violations"] == 0 and d["verdict"]["passed"] for d in drills), [d["verdict"] for d in drills]
    holes = [hole for drill in drills for hole in drill["holes"]]
    assert len(holes) == len(depths)
    for hole, depth in zip(holes, depths):
        assert -0.2 <= hole["depth_mm"] - depth <= 0.005
    assert all(op.get("duration_s", 0.0) > 0.0 for op in report["program"]["operations"])  # each one ran
    if name == "bolt_circle_while":
        assert [round(math.hypot(h["x_mm"], h["y_mm"]), 6) for h in holes] == [30.0] * 8


def test_a_failed_operation_fails_the_program(tmp_path):
    """A G98 drill cycle on drives far softer than described (position gain 12/s of 50/s,
    well outside the stated tolerance that the planner's margins cover): X/Y still moves as
    the tip goes below R, which the drill's judge counts. The program's verdict fails with it
    and cnc-run exits 4: an operation's miss is never a silent success."""
    from support import cnc, load_report
    program = tmp_path / "g98.ngc"
    program.write_text("G21 G90 G17 G94\nM3 S2000\nG0 X-10 Y15 Z10\nG98 G81 X-10 Y15 Z-8 R2 F300\nX10\nG80\nM5\nM2\n")
    plant = tmp_path / "far_off.yaml"
    plant.write_text("name: mill3_far_off\ndrive:\n" + "".join(f"  {a}: {{kp: 12.0}}\n" for a in "xyz"))
    result = cnc("cnc-run", program, "--machine", "mill3", "--plant", plant, "--out", tmp_path / "run")
    assert result.returncode == 4, result.stderr[-2000:]
    report = load_report(tmp_path / "run")
    assert report["state"] == "succeeded" and report["program"]["verdict"]["passed"] is False
    assert report["program"]["verdict"]["says"].startswith("operation 1 (line 4, drill): X/Y moved")


def test_a_lathe_program_roughs_at_constant_surface_speed_then_threads_at_one_rpm(tmp_path):
    """test/programs/lathe_css_g96_g76.ngc over topics: G96 D3000 S120 then G71, G97 S600 then
    G76. Judged on the recorded feedback: wherever the tip cuts (feeding at the feed per
    revolution of the measured spindle speed) the measured surface speed is within 2 % of
    120 m/min where 3000 rpm does not cap it, the measured rpm never above 3000; the thread
    cut at one 600 rpm, at full depth along its flank."""
    from cnc_analysis.recording import read_run
    report = _run(tmp_path, "lathe_css_g96_g76")
    ops = report["program"]["operations"]
    assert [(op["line"], op["kind"]) for op in ops] == [(8, "move"), (17, "turn"), (20, "move"), (21, "thread"),
                                                      (22, "move")]
    turn, thread = ops[1]["turn"], ops[3]["thread"]
    css = turn["surface_speed"]
    assert turn["verdict"]["passed"] and thread["verdict"]["passed"], (turn["verdict"], thread["verdict"])
    assert css["max_deviation_pct"] <= 2.0 and css["max_rpm"] <= 3000.0
    assert css["held_s"] > 5.0 and css["capped_s"] > 1.0  # most of the cut held, the small radii capped
    assert 118.0 <= css["min_m_min"] and css["max_m_min"] <= 122.0
    assert css["feed_per_rev_mm"][1] == pytest.approx(0.15, rel=0.01)  # per revolution of the actual speed
    assert turn["max_gouge_part_mm"] == 0.0 and thread["full_depth"]
    run = read_run(tmp_path / "run" / "bag")
    starts = sorted(e["stamp_ns"] / 1e9 for e in run.events if e.get("name") == "operation")
    rpm = run.feedback_velocity[:, run.column("spindle")] * 60.0 / (2.0 * math.pi)
    during = lambda k: (run.feedback_t >= starts[k]) & (run.feedback_t < starts[k + 1])  # noqa: E731
    assert np.ptp(rpm[during(1)]) > 1000.0  # the roughing's spindle follows the radius
    in_thread = during(3) & (run.feedback[:, run.column("x")] < 6e-3)  # the tip below the major radius
    assert in_thread.sum() > 1000 and np.allclose(rpm[in_thread], 600.0, rtol=1e-3)  # one rpm while it cuts


def test_a_face_cut_at_constant_surface_speed_is_judged_on_feedback(tmp_path):
    """G96 D3000 S150 then G1 facing from a radius of 21 mm to 0.4 mm past the axis at 0.1 mm
    per revolution: a move operation at the surface speed, its own surface_speed section on
    the recorded feedback: within 2 % of 150 m/min down to where 3000 rpm caps it, never above
    3000 rpm, 0.1 mm per revolution of the measured speed."""
    from support import cnc, load_report
    program = tmp_path / "face_g96.ngc"
    program.write_text("G21 G18 G8 G90 G95\nG96 D3000 S150 M3\nG0 X21 Z0\nG1 X-0.4 F0.1\nG0 Z2\nM5\nM2\n")
    result = cnc("cnc-run", program, "--machine", "lathe", "--out", tmp_path / "run")
    assert result.returncode == 0, result.stderr[-2000:]
    (op,) = load_report(tmp_path / "run")["program"]["operations"]
    css = op["surface_speed"]
    assert op["kind"] == "move" and css["verdict"]["passed"], css["verdict"]
    assert css["max_deviation_pct"] <= 2.0 and css["max_rpm"] <= 3000.0
    assert css["held_s"] > 4.0 and css["capped_s"] > 1.0
    assert css["feed_per_rev_mm"][1] == pytest.approx(0.1, rel=0.01)
