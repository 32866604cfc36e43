"""Program pauses (M0, M1): the translation's hold points, the plan's zero-length hold mark,
and over real topics a program held at its M0 until resumed on job_resume (judged on the
feedback), canceled while held, and resumes that name no held job, which move nothing."""
from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest

from cnc_msgs_py.gcode import GcodeError
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.units import NS

from cnc_planner.planning import plan_job

PROGRAM = """(CNC,MACHINE mill3)
G21 G90 G17 G94
M3 S2000
G0 X-10 Y0 Z10
G99 G81 X-10 Y0 Z-3 R2 F300
G80
M0 (check the first hole)
G99 G81 X10 Y0 Z-3 R2 F300
G80
M1
G0 Z20
M5
M2
"""
M0_LINE, M1_LINE = 7, 10


def program_job(gcode: str = PROGRAM, job_id: str = "pause", **block) -> dict:
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "program", "machine": "mill3",
            "program": {"gcode": gcode, **block}}


def test_m0_and_m1_are_hold_points_between_operations():
    ops = parse_job(program_job()).program.operations
    assert [(op.kind, line) for line, op, _ in ops] == [("move", 4), ("drill", 5), ("drill", 8), ("move", 11)]
    assert [(h.before, h.line, h.code) for h in ops.holds] == [(2, M0_LINE, "M0"), (3, M1_LINE, "M1")]


def test_m1_is_skipped_when_the_optional_stop_is_off():
    ops = parse_job(program_job(optional_stop=False)).program.operations
    assert [(h.line, h.code) for h in ops.holds] == [(M0_LINE, "M0")]
    assert len(ops) == 4  # M1 ends no operation when it does not hold


def test_a_pause_under_cutter_compensation_is_refused_by_line():
    gcode = "G21 G90 G17\nT1 M6\nG0 X0 Y0 Z5\nG41 D1\nG1 X10 F300\nM0\nG1 Y10\nG40\nM2\n"
    with pytest.raises(GcodeError, match="line 6: M0: a pause with cutter compensation on"):
        parse_job(program_job(gcode, tool_table=[{"tool": 1, "diameter": 6}]))


def test_the_plan_marks_each_hold_at_rest_with_zero_length():
    plan = plan_job(parse_job(program_job()), load_machine("mill3"))
    holds = [e for e in plan.events if e.name == "hold"]
    assert [(e.data["line"], e.data["code"], e.data["before"]) for e in holds] == [(M0_LINE, "M0", 2),
                                                                                    (M1_LINE, "M1", 3)]
    starts = {e.data["index"]: e.time for e in plan.events if e.name == "operation"}
    for e in holds:
        assert starts[e.data["before"]] == pytest.approx(e.time)  # zero-length: the next operation starts there
        _, v, _ = plan.sample(np.array([e.time]))
        axes = [k for k, j in enumerate(plan.joints) if j != "spindle"]
        assert np.abs(v[0, axes]).max() < 1e-9  # the motion before it ended at rest


def _held(session, job_id: str, after: int = 0) -> dict:
    def latest() -> dict | None:
        return next((s for s in reversed(session.recorder.statuses) if s["job_id"] == job_id), None)
    session.spin_until(lambda: (s := latest()) is not None and s["state"] == "held" and
                       s["detail"].get("hold", 0) > after, 60, f"{job_id} never held")
    return latest()


def test_a_program_holds_at_m0_until_resumed_and_each_operation_is_judged(tmp_path):
    from support import BIN
    from cnc_analysis.recording import read_run
    from cnc_planner.report import build_report
    from cnc_planner.runner import Session

    with Session("mill3", tmp_path / "bag") as session:
        session.submit(json.dumps(program_job()))
        held = _held(session, "pause")
        assert held["reason"].startswith(f"held at line {M0_LINE} (M0): resume") and "job_resume" in held["reason"]
        stay = held["stamp_ns"] + NS // 2  # held for 0.5 s of machine time
        session.spin_until(lambda: session.recorder.feedback_ns >= stay, 60, "the clock stopped")
        session.resume("pause")
        held = _held(session, "pause", after=1)  # on to the M1 (the optional stop is on by default)
        assert held["reason"].startswith(f"held at line {M1_LINE} (M1)")
        # as an operator would, from a shell: the recorder spins meanwhile (the clock waits for it)
        resume = subprocess.Popen([str(BIN / "cnc-submit"), "--resume", "pause"], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, env=dict(os.environ))
        final = session.wait("pause", 60)
        assert final["state"] == "succeeded"
        session.settle(final)
        out, err = resume.communicate(timeout=60)
        assert resume.returncode == 0, err
        assert "cnc-submit: resumed pause on /cnc/job_resume" in err and json.loads(out)["state"] == "succeeded"
    run = read_run(tmp_path / "bag")
    events = {name: [e for e in run.events if e["name"] == name] for name in ("hold", "resume")}
    assert [e["line"] for e in events["hold"]] == [M0_LINE, M1_LINE] == [e["line"] for e in events["resume"]]
    hold_s, resume_s = events["hold"][0]["stamp_ns"] / NS, events["resume"][0]["stamp_ns"] / NS
    assert resume_s - hold_s >= 0.5
    # The feedback stays at rest during the hold (after the drives settle), the spindle turning on.
    during = (run.feedback_t > hold_s + 0.1) & (run.feedback_t < resume_s)
    axes = [run.column(a) for a in ("x", "y", "z")]
    assert during.sum() > 300
    assert np.abs(run.feedback_velocity[during][:, axes]).max() < 1e-3
    assert np.ptp(run.feedback[during][:, axes], axis=0).max() < 2e-6
    spindle = run.feedback_velocity[during][:, run.column("spindle")]
    assert np.abs(spindle - 2000 * 2 * np.pi / 60).max() < 1.0  # M0 leaves the spindle on, as LinuxCNC's
    report = build_report(run)
    operations = report["program"]["operations"]
    drills = [op["drill"] for op in operations if op["kind"] == "drill"]
    assert len(drills) == 2 and all(d["verdict"]["passed"] and len(d["holes"]) == 1 for d in drills)
    assert [round(d["holes"][0]["x_mm"]) for d in drills] == [-10, 10]
    assert operations[1]["duration_s"] < resume_s - hold_s  # its share ends at the hold, not at the resume
    assert report["program"]["verdict"]["passed"]


def test_a_held_program_cancels_cleanly_and_a_resume_for_no_held_job_moves_nothing(tmp_path):
    from support import BIN
    from cnc_analysis.recording import read_run
    from cnc_planner.runner import Session

    with Session("mill3", tmp_path / "bag") as session:
        session.resume("nobody")  # idle: nothing to resume
        session.submit(json.dumps(program_job(job_id="held")))
        held = _held(session, "held")
        session.resume("nobody")
        # The recorder spins while cnc-submit runs: a recorder that stops reading for 1 s of
        # wall time counts as gone, and the simulated clock then runs on unrecorded.
        resume = subprocess.Popen([str(BIN / "cnc-submit"), "--resume", "nobody", "--namespace", "/cnc"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
        session.spin_until(lambda: resume.poll() is not None, 60, "cnc-submit --resume never returned")
        _, err = resume.communicate()
        assert resume.returncode == 2
        assert err.strip().splitlines() == [
            "cnc-submit: job 'nobody' is not held (no status heard for it); only a program held at M0/M1 resumes"]
        later = held["stamp_ns"] + NS // 2
        session.spin_until(lambda: session.recorder.feedback_ns >= later, 60, "the clock stopped")
        assert _held(session, "held")["state"] == "held"  # still held
        canceled_ns = session.recorder.feedback_ns
        session.cancel("held")
        final = session.wait("held", 60)
        assert final["state"] == "canceled"
        session.settle(final)
    run = read_run(tmp_path / "bag")
    assert not [e for e in run.events if e["name"] == "resume"]
    hold_s = next(e["stamp_ns"] for e in run.events if e["name"] == "hold") / NS
    after = run.feedback_t > hold_s + 0.1
    axes = [run.column(a) for a in ("x", "y", "z")]
    assert np.ptp(run.feedback[after][:, axes], axis=0).max() < 2e-6  # never moved again
    s = run.column("spindle")
    assert abs(run.feedback_velocity[-1, s]) < 1e-3 and abs(run.command_velocity[-1, s]) == 0.0  # stopped
    turning = 2000 * 2 * np.pi / 60
    stop_s = run.command_t[(run.command_t > hold_s) & (run.command_velocity[:, s] < 0.99 * turning)][0]
    assert stop_s - canceled_ns / NS < 1.0  # the stop begins a lookahead after the cancel, not later
    accel = np.diff(run.command_velocity[:, s]) / np.diff(run.command_t)
    limit = load_machine("mill3").axes["spindle"].max_acceleration
    assert np.abs(accel[run.command_t[1:] > hold_s]).max() <= limit * 1.01  # a controlled stop
