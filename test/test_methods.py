"""The machining methods over real topics, judged on the bridge's feedback, and the
report figures reproduced by cnc-analyze from the recording alone."""
from __future__ import annotations

import json

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file
from cnc_analysis.recording import read_run
from support import JOBS, assert_hole_depth, cnc, load_report


def run_and_reanalyse(job: str, out) -> dict:
    result = cnc("cnc-run", JOBS / job, "--out", out)
    assert result.returncode == 0, result.stderr[-3000:]
    report = load_report(out)
    again = cnc("cnc-analyze", out / "bag", "--out", out / "again.json")
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "again.json").read_text()) == report
    return report


def test_overlapped_drilling_is_safe_on_feedback_and_beats_conventional(tmp_path):
    report = run_and_reanalyse("drill_row.yaml", tmp_path / "drill")
    drill = report["drill"]
    assert drill["safety_violations"] == 0
    assert len(drill["holes"]) == 5
    assert all(h["mode"] in (1, 2, 3) for h in drill["holes"])
    assert drill["lower_bound_s"] < drill["cycle_time_s"] < drill["conventional_cycle_time_s"]
    # Every hole: X/Y in position no later than the tip passes R on the way down.
    for hole in drill["holes"]:
        assert hole["in_position_s"] <= hole["r_down_s"] + 1e-3
        assert_hole_depth(hole["depth_mm"], 5.0)  # the Z bottom is compensated too, leaving material


def test_vibration_breaks_the_chip_every_revolution_on_feedback(tmp_path):
    report = run_and_reanalyse("lathe_feed_vibration.yaml", tmp_path / "vib")
    aircut = report["aircut"]
    for side in ("commanded", "feedback"):
        assert aircut[side]["revolutions"] >= 100  # 12 mm at 0.1 mm/rev
        assert aircut[side]["revolutions_with_aircut"] == aircut[side]["revolutions"]
        assert aircut[side]["max_chip_revs"] <= 1.0


def test_roughing_starts_passes_on_the_stock_without_gouging(tmp_path):
    report = run_and_reanalyse("turn_stepped.yaml", tmp_path / "turn")
    turn = report["turn"]
    assert turn["passes"] >= 5
    # Setpoints never enter the profile offset by the radial and axial allowances; passes end
    # W = 0.1 mm before shoulder faces, so the servo's overshoot of a few um in Z on feedback
    # stays in the allowance and never reaches the final profile.
    assert turn["max_gouge_commanded_mm"] == pytest.approx(0.0, abs=1e-9)
    assert turn["max_gouge_part_mm"] == 0
    assert turn["max_gouge_mm"] < 0.02
    assert turn["air_feed_mm"] < 0.1 * turn["naive_air_feed_mm"]
    assert turn["path_mm"] < turn["naive_path_mm"]


def test_thread_with_vibration_breaks_chips_on_every_pass_on_feedback(tmp_path):
    report = run_and_reanalyse("thread_m12.yaml", tmp_path / "thread")
    thread = report["thread"]
    assert thread["synchronised_passes"] == 7  # 6 cutting passes + 1 spring pass
    for p in thread["passes"]:
        if p["doc_mm"] > 0.05:
            assert p["max_chip_revs"] <= 1.0
    assert thread["full_depth"] and abs(thread["depth_error_mm"]) <= 0.02
    assert thread["overcut_mm"] <= 0.02
    assert thread["helix_residual_mm"] < 0.01
    assert thread["doc_never_grows"]


def test_thread_honours_setup_and_tool_length_on_the_axes(tmp_path):
    """thread_m12 with the part's face 100 mm down z and a 20 mm tool: the report, judged
    in program coordinates, is as good as without; the axes really ran 100 mm down z."""
    doc = {**load_job_file(JOBS / "thread_m12.yaml"), "job_id": "thread-m12-placed",
           "setup": {"origin": [0, 0, -100], "rotation_deg": [0, 0, 0]}, "tool": {"length": 20}}
    (tmp_path / "placed.json").write_text(json.dumps(doc))
    report = run_and_reanalyse(tmp_path / "placed.json", tmp_path / "placed")
    thread = report["thread"]
    assert thread["synchronised_passes"] == 7
    for p in thread["passes"]:
        if p["doc_mm"] > 0.05:
            assert p["max_chip_revs"] <= 1.0
    assert thread["full_depth"] and abs(thread["depth_error_mm"]) <= 0.02
    assert thread["helix_residual_mm"] < 0.01
    run = read_run(tmp_path / "placed" / "bag")
    t, x, z = run.feedback_t, run.feedback[:, run.column("x")] * 1e3, run.feedback[:, run.column("z")] * 1e3
    syncs = [e["stamp_ns"] / 1e9 for e in run.events if e.get("name") == "sync"]
    starts = [e["stamp_ns"] / 1e9 for e in run.events if e.get("name") == "thread_pass"]
    assert len(syncs) == 7
    for sync, following in zip(syncs, starts[1:] + [np.inf]):
        on_pass = (t >= sync) & (t < following)  # on the helix, out past end_z and back
        assert -118.0 <= z[on_pass].min() and z[on_pass].max() <= -95.0
        # until it reaches end_z (the first pass's run-out ends within microns of it)
        on_helix = on_pass & (t < t[on_pass & (z <= -116.0 + 0.01)].min())
        assert on_helix.sum() > 900  # on the helix from before the face: 16 mm of thread at 17.5 mm/s
        assert 20.0 + 4.9 <= x[on_helix].min() and x[on_helix].max() <= 20.0 + 6.1


def test_conventional_thread_is_correct_but_its_chips_are_long(tmp_path):
    report = run_and_reanalyse("thread_m12_conventional.yaml", tmp_path / "g76")
    thread = report["thread"]
    assert thread["full_depth"] and thread["helix_residual_mm"] < 0.01
    assert thread["max_chip_revs"] > 5.0


def test_tilted_holes_on_a_five_axis_machine_are_safe_on_feedback(tmp_path):
    report = run_and_reanalyse("drill_5ax_tilted.yaml", tmp_path / "tilted")
    drill = report["drill"]
    assert drill["safety_violations"] == 0 and len(drill["holes"]) == 5
    assert drill["cycle_time_s"] < drill["conventional_cycle_time_s"]
