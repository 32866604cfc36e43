"""The must-show G-code programs over topics (cnc-run: planner and bridge nodes, DDS on this
host), each one goal, judged on the recorded feedback: a bolt circle from a while loop, a hole
pattern from a subroutine called with arguments, two drills from the machine's tool table
with G43 (test/programs/, checked against LinuxCNC's interpreter in test_gcode_examples.py)."""
from __future__ import annotations

import math
from pathlib import Path

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
