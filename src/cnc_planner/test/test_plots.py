"""Run figures: each job kind gets its figures, each a real picture (not a blank canvas).

The runs are synthetic: the planner's commands for a small job and the drive model's
feedback for them, put into a Run as the recording would give them, without ROS or bags.
"""
import dataclasses
import functools
import json

import numpy as np
import pytest
from matplotlib.image import imread

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job
from cnc_planner.plots import write_plots
from cnc_planner.report import build_report
from cnc_planner.prediction import simulated_feedback
from cnc_analysis.recording import Run

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
T0 = 2.0  # s of ROS time at which the synthetic job starts

DRILL = {
    "schema": "cnc_job/1", "job_id": "drill-test", "kind": "drill", "machine": "mill3",
    "tool": {"diameter": 4.0}, "spindle_rpm": 3000,
    "drill": {"holes": [[0, 0], [8, 0], [16, 0]], "depth": 3.0, "r_gap": 2.0, "feed": 1200},
}
TURN = {
    "schema": "cnc_job/1", "job_id": "turn-test", "kind": "turn", "machine": "lathe", "spindle_rpm": 1500,
    "turn": {"stock": [[0, 10], [-8, 10]], "profile": [[0, 7], [-8, 7]], "depth_of_cut": 1.5,
             "feed": 0.3, "origin": [3, 14], "finish_allowance": 0.2},
}
FACING = {  # passes along X inwards, stepping along Z (G72): the figure draws the material left of the face
    "schema": "cnc_job/1", "job_id": "facing-test", "kind": "turn", "machine": "lathe", "spindle_rpm": 1500,
    "turn": {"stock": [[0, 10], [0, 0]], "profile": [[-3, 10], [-3, 5], [-1, 5], [-1, 0]], "depth_of_cut": 1.0,
             "feed": 0.3, "origin": [3, 12], "finish_allowance": 0.2, "finish_allowance_z": 0.2,
             "passes": "-x", "infeed": "-z"},
}
VIBRATION = {
    "schema": "cnc_job/1", "job_id": "vibration-test", "kind": "move", "machine": "lathe", "spindle_rpm": 600,
    "move": [{"rapid": {"x": 10, "z": 1}}, {"linear": {"z": -1}, "feed": 60}, {"rapid": {"x": 12}}],
    "vibration": {"D": 1.5, "Q": 1.2},
}

THREAD = {
    "schema": "cnc_job/1", "job_id": "thread-test", "kind": "thread", "machine": "lathe", "spindle_rpm": 600,
    "thread": {"start_z": 3.0, "end_z": -6.0, "major_radius": 6.0, "pitch": 1.5, "depth": 0.9, "passes": 3},
    "vibration": {"D": 1.5, "Q": 1.3, "phase_shift": 180},
}

PLATE = {**DRILL, "job_id": "plate-test",  # more holes than the timing figure shows in detail
         "drill": {**DRILL["drill"], "holes": [[8 * i, 8 * j] for j in range(2) for i in range(4)]}}

JOBS = {"drill": DRILL, "turn": TURN, "facing": FACING, "vibration": VIBRATION, "thread": THREAD, "plate": PLATE}


@functools.cache
def synthetic_run(name: str) -> Run:
    """The job's commands and the drive model's feedback, stamped as a recording would be."""
    doc = JOBS[name]
    job = parse_job(doc)
    machine = load_machine(job.machine)
    plan = plan_job(job, machine)
    t, feedback = simulated_feedback(plan, machine)
    command, command_velocity, _ = plan.sample(t)
    events = [{"job_id": job.job_id, "name": e.name, "stamp_ns": int(round((T0 + e.time) * 1e9)),
               "plan_time_s": e.time, **e.data} for e in plan.events]
    return Run(joints=tuple(plan.joints), feedback_t=T0 + t, feedback=feedback,
               feedback_velocity=np.gradient(feedback, t, axis=0), command_t=T0 + t, command=command,
               command_velocity=command_velocity, goals=[json.dumps(doc)], events=events,
               statuses=[{"job_id": job.job_id, "state": "succeeded"}])


def assert_pictures(paths: list, expected: list[str]) -> None:
    assert [p.name for p in paths] == expected
    for path in paths:
        assert path.stat().st_size > 0
        assert path.read_bytes()[:8] == PNG_SIGNATURE
        assert float(np.std(imread(path))) > 0.0, f"{path.name} is blank"


@pytest.mark.parametrize("name, expected", [
    ("drill", ["following_error.png", "drill_xz.png", "drill_timing.png"]),
    ("turn", ["following_error.png", "turn_passes.png"]),
    ("facing", ["following_error.png", "turn_passes.png"]),
    ("vibration", ["following_error.png", "aircut.png", "aircut_map.png"]),
    ("thread", ["following_error.png", "thread_passes.png", "thread_section.png"]),
])
def test_each_job_kind_gets_its_figures(name, expected, tmp_path):
    run = synthetic_run(name)
    report = build_report(run)
    assert_pictures(write_plots(run, report, tmp_path / "plots"), expected)


def test_figures_of_a_recording_that_lost_its_tail_are_still_drawn(tmp_path):
    # the feedback of the last holes was not recorded: the figures show what there is
    full = synthetic_run("drill")
    kept = full.feedback_t <= full.feedback_t[0] + 0.7 * (full.feedback_t[-1] - full.feedback_t[0])
    run = dataclasses.replace(full, feedback_t=full.feedback_t[kept], feedback=full.feedback[kept],
                              feedback_velocity=full.feedback_velocity[kept])
    report = build_report(run)
    assert_pictures(write_plots(run, report, tmp_path), ["following_error.png", "drill_xz.png", "drill_timing.png"])


def test_a_run_without_feedback_draws_nothing(tmp_path):
    run = Run(joints=("x", "z", "spindle"), goals=[json.dumps(TURN)])
    assert write_plots(run, {"job_id": "turn-test"}, tmp_path) == []


def test_a_plate_shows_its_first_holes_in_detail_and_every_hole_on_a_map(tmp_path):
    from cnc_planner.kinds.drill import figures
    from cnc_planner.report import job_window, last_job

    run = synthetic_run("plate")
    report = build_report(run)
    assert len(report["drill"]["holes"]) > figures.DETAIL_HOLES
    assert_pictures(write_plots(run, report, tmp_path),
                    ["following_error.png", "drill_xz.png", "drill_timing.png", "drill_map.png"])
    _, job = last_job(run)
    window = job_window(run, report["job_id"])
    cycle = figures._cycle(run, job, load_machine(job.machine), window)
    lowest = figures._lowest_above_r(run, cycle, window, report["drill"]["holes"])
    # the map's margins say what the judge says: no X/Y motion off a hole below R, on every approach
    assert report["drill"]["safety_violations"] == 0
    assert np.all(np.isfinite(lowest[1:])) and np.nanmin(lowest) > 0.0
