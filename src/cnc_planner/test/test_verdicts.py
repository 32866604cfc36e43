"""Every kind's verdict on feedback, and the feedback the description predicts beside the
recorded one (issue 41, item 4), on runs made by hand: a prediction of an example job
(report.predicted_run) whose feedback is then replaced by a plant's or altered where the
miss should show. No ROS: the same build_report that cnc-run and cnc-analyze call."""
from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest

from cnc_analysis import recording
from cnc_analysis.drilling import DEPTH_SHORT_LIMIT
from cnc_analysis.recording import Run
from cnc_analysis.verdict import OVERCUT_LIMIT
from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import Machine, load_machine
from cnc_planner.cli import VERDICT_FAILED, analyze_main, failed_verdicts, summary
from cnc_planner.planning import plan_job
from cnc_planner import replay
from cnc_planner.replay import ADVICE, predicted_feedback
from cnc_planner.report import build_report, predicted_run
from cnc_planner.report_page import render
from cnc_servo_bridge.drive import DriveModel

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
SECTION = {"drill_row": "drill", "drill_clamps": "drill", "drill_vibration": "drill", "thread_m12": "thread",
           "turn_stepped": "turn", "lathe_feed_vibration": "aircut", "path_mill3": "kinematics"}


@functools.cache
def _predicted(name: str) -> tuple[Machine, Run]:
    doc = load_job_file(JOBS / f"{name}.yaml")
    job = parse_job(doc)
    machine = load_machine(job.machine)
    plan = plan_job(job, machine, machine.home_joints)
    return machine, predicted_run(doc, plan, machine)


def predicted(name: str) -> tuple[Machine, Run]:
    """The example job's predicted run (a copy: tests replace its feedback)."""
    machine, run = _predicted(name)
    return machine, dataclasses.replace(run, feedback=run.feedback.copy())


def on_plant(run: Run, machine: Machine, **changes: dict) -> np.ndarray:
    """The run's commands through drives that differ from the description (joint -> keys)."""
    drives = {j: dataclasses.replace(d, **changes.get(j, {})) for j, d in machine.drives.items()}
    feedback, _ = DriveModel(machine, 1e-3, run.joints, drives=drives).simulate(
        run.command, run.command_velocity, run.command_acceleration)
    return feedback


@pytest.mark.parametrize("name", SECTION)
def test_a_nominal_run_passes_its_verdict_and_follows_its_description(name):
    machine, run = predicted(name)
    report = build_report(run, machine)
    verdict = report[SECTION[name]]["verdict"]
    assert verdict["passed"] is True and verdict["criterion"] and verdict["says"], verdict
    assert failed_verdicts(report) == []
    drives = report["drives"]
    assert drives["as_described"] and drives["differs"] == []
    assert set(drives["axes"]) == set(run.joints)
    for joint, axis in drives["axes"].items():
        # the prediction is the recording: nothing but the start's rounding to an encoder count
        count = machine.drives[joint].resolution * (1e3 if axis["unit"] == "mm" else np.degrees(1.0))
        assert axis["max_residual"] <= count * 1.001
        assert axis["predicted_max_following_error"] == pytest.approx(axis["max_following_error"], abs=count * 1.001)
    assert report["plant"] is None  # a prediction records no bridge


def test_xy_moving_below_r_fails_the_drill_verdict_and_cnc_analyze_exits_4(tmp_path, monkeypatch, capsys):
    """X/Y drives far outside their tolerance (40 % of the gain, a 5 ms loop, 6 ms delay):
    the cycle moves X while the tip is still below R on feedback."""
    machine, run = predicted("drill_row")
    slow = {"kp": 20.0, "velocity_lag": 0.005, "delay": 0.006}
    run.feedback = on_plant(run, machine, x=slow, y=slow)
    report = build_report(run, machine)
    drill = report["drill"]
    assert drill["safety_violations"] > 0
    assert drill["verdict"]["passed"] is False
    assert f"X/Y moved while the tip was below R in {drill['safety_violations']} feedback samples" \
        in drill["verdict"]["says"]
    assert failed_verdicts(report) == ["drill"]
    assert "verdict drill: FAILED: X/Y moved" in summary(report)
    # The row runs along X: X is named as the axis that is not its description, Y (at rest) is not.
    assert report["drives"]["differs"] == ["x"]
    # cnc-analyze on that recording exits 4, as cnc-run does.
    monkeypatch.setattr(recording, "read_run", lambda bag: run)
    assert analyze_main([str(tmp_path / "bag"), "--out", str(tmp_path / "again.json")]) == VERDICT_FAILED
    assert "verdict failed: drill" in capsys.readouterr().err
    assert (tmp_path / "again.json").is_file()


def test_a_hole_too_deep_or_too_shallow_fails_the_drill_verdict():
    machine, run = predicted("drill_row")
    z = run.column("z")
    nominal = run.feedback[:, z].copy()
    bottom = nominal < -4.9e-3
    run.feedback[bottom, z] = nominal[bottom] - 0.045e-3  # every hole 4.9679 + 0.045 = 5.0129 mm deep
    deep = build_report(run, machine)["drill"]["verdict"]
    assert deep["passed"] is False
    assert deep["says"] == ("5 of 5 holes deeper than programmed by more than 0.005 mm, the worst 5.0129 mm deep "
                            "for 5 mm at X 0 Y 0 mm")
    assert f"+{OVERCUT_LIMIT * 1e3:g}/-{DEPTH_SHORT_LIMIT * 1e3:g} mm" in deep["criterion"]
    run.feedback[:, z] = np.maximum(nominal, -4.5e-3)  # every hole stops 0.5 mm short
    short = build_report(run, machine)["drill"]["verdict"]
    assert short["passed"] is False and "5 of 5 holes shallower than programmed by more than 0.2 mm" in short["says"]


def test_a_thread_cut_too_deep_or_off_its_flank_fails_the_thread_verdict():
    machine, run = predicted("thread_m12")
    x, z = run.column("x"), run.column("z")
    nominal = run.feedback.copy()
    # The tool 10 um further into the external thread: within the analyser's full_depth
    # (0.02 mm either way), but an overcut, which the verdict holds to OVERCUT_LIMIT.
    run.feedback[:, x] = nominal[:, x] - 0.01e-3
    over = build_report(run, machine)
    assert over["thread"]["overcut_mm"] == pytest.approx(0.01, abs=1e-3) and over["thread"]["full_depth"]
    assert over["thread"]["verdict"]["passed"] is False
    assert over["thread"]["verdict"]["says"].startswith("cut 0.01")
    assert "deeper than the thread's depth (limit 0.005 mm)" in over["thread"]["verdict"]["says"]
    assert failed_verdicts(over) == ["thread"]
    assert "too deep" in render(over, [])
    run.feedback[:, x] = nominal[:, x] + 0.03e-3  # 30 um short: within SHORT_LIMIT
    assert build_report(run, machine)["thread"]["verdict"]["passed"] is True
    run.feedback[:, x] = nominal[:, x] + 0.06e-3  # 60 um short
    short = build_report(run, machine)["thread"]["verdict"]
    assert short["passed"] is False and short["says"].startswith("depth 0.06"), short
    # The last pass 30 um further along the axis than the others: off the flank line they cut
    # (a shift of every pass alike would only move the thread's start, and is not judged).
    last = build_report(dataclasses.replace(run, feedback=nominal), machine)["thread"]["passes"][-1]
    run.feedback[:] = nominal
    run.feedback[run.feedback_t >= last["t_start"], z] += 0.03e-3
    off = build_report(run, machine)["thread"]["verdict"]
    assert off["passed"] is False and off["says"].startswith("the tool left its flank line by 0.02"), off


def test_a_gouge_into_the_part_fails_the_turn_verdict():
    machine, run = predicted("turn_stepped")
    run.feedback[:, run.column("z")] -= 0.3e-3  # 0.3 mm towards the chuck: into the shoulders' faces
    report = build_report(run, machine)
    turn = report["turn"]
    assert turn["max_gouge_part_mm"] == pytest.approx(0.205, abs=1e-3)
    assert turn["verdict"]["passed"] is False
    assert turn["verdict"]["says"] == "gouge: the tip went 0.2050 mm into the final profile"
    assert failed_verdicts(report) == ["turn"]
    assert "failed: turn" in render(report, [])


def test_a_long_chip_fails_the_aircut_verdict():
    """X/Z drives far too slow for the 1.5 vibrations per revolution: the feedback barely
    vibrates and the chip never breaks."""
    machine, run = predicted("lathe_feed_vibration")
    slow = {"kp": 20.0, "velocity_lag": 0.01}
    run.feedback = on_plant(run, machine, x=slow, z=slow)
    report = build_report(run, machine)
    aircut = report["aircut"]
    assert aircut["max_chip_revs"] > 100
    assert aircut["verdict"]["passed"] is False
    assert aircut["verdict"]["says"].startswith("1 of 1 vibrated feeds left chips longer than their window")
    assert failed_verdicts(report) == ["aircut"]


@pytest.mark.parametrize("axis, alter", [
    ("z", lambda column: np.concatenate([np.repeat(column[:1], 3), column[:-3]])),  # 3 ms late
    ("x", lambda column: column + 0.01e-3),  # 10 um off
])
def test_the_drives_section_names_the_axis_that_follows_differently(axis, alter):
    machine, run = predicted("drill_row")
    run.feedback[:, run.column(axis)] = alter(run.feedback[:, run.column(axis)])
    report = build_report(run, machine)
    drives = report["drives"]
    assert drives["differs"] == [axis] and drives["as_described"] is False
    residual = drives["axes"][axis]["max_residual"]
    assert residual > drives["residual_limit_mm"]
    assert drives["says"] == f"{axis} follows differently from its description (residual {residual:.4f} mm): {ADVICE}"
    assert "cnc-identify" in drives["says"] and "CNC_MACHINE_PATH" in drives["says"]
    assert all(a["max_residual"] <= 1e-4 for j, a in drives["axes"].items() if j != axis)
    # Advice, not a verdict: it never fails the run by itself; it is printed and on the page.
    assert "drives" not in failed_verdicts(report)
    assert f"drives: DIFFER: {axis} follows differently" in summary(report)
    page = render(report, [])
    assert "Drives vs description" in page and f"{axis} differs" in page
    run.alarms = ["following error on z: 0.003000 exceeds 0.002000"]
    assert build_report(run, machine)["drives"]["says"].endswith("which the replay does not predict")


def test_the_recorded_lag_is_set_beside_the_predicted_one():
    """A softer X gain (35/s where 50/s is described) lags more than predicted: the section
    shows both following errors, the recorded one the larger."""
    machine, run = predicted("drill_row")
    run.feedback = on_plant(run, machine, x={"kp": 35.0})
    x = build_report(run, machine)["drives"]["axes"]["x"]
    assert x["max_following_error"] > x["predicted_max_following_error"] + 0.01
    assert x["max_residual"] > 0.02 and x["rms_residual"] < x["max_residual"] and x["unit"] == "mm"


def test_a_long_recording_is_replayed_in_blocks_to_the_same_feedback(monkeypatch):
    """The replay steps the drives block by block (bounded memory on an hours-long bag), the
    drives' state carried across: the same prediction as in one go, to the bit."""
    machine, run = predicted("thread_m12")
    compared, whole = predicted_feedback(run, machine)
    monkeypatch.setattr(replay, "BLOCK", 777)
    again = predicted_feedback(run, machine)
    assert np.array_equal(again[0], compared) and np.array_equal(again[1], whole)
