"""The executive's program pauses without ROS: a held program streams its hold contiguously
on the grid (axes standing, the spindle turning on) until resumed, and the rest follows
from the hold's state; a resume that names no held job changes nothing."""
from __future__ import annotations

import json

import numpy as np
import pytest

from cnc_msgs_py.machine import load_machine

from cnc_planner.executive import Executive, Output

MILL = load_machine("mill3")
TICK_NS = 100_000_000
MILL_PERIOD_NS = 1_000_000  # the interpolation period (Settings' default)
SPINDLE_RAD_S = 1000 * 2 * np.pi / 60


def submit(gcode: str) -> Executive:
    executive = Executive(MILL)
    executive.feedback({j: 0.0 for j in MILL.joint_names})
    executive.bridge_report("")
    doc = {"schema": "cnc_job/1", "job_id": "p", "kind": "program", "machine": "mill3", "program": {"gcode": gcode}}
    assert executive.submit(json.dumps(doc)).state == "accepted"
    return executive


def run(executive: Executive, hold_s: float = 1.0, cancel: bool = False) -> tuple[list, list, list]:
    """Tick until the job ends, resuming (or canceling) each hold ``hold_s`` after the feedback
    reached it: (chunks, statuses, events)."""
    chunks, statuses, events, now = [], [], [], 0
    while not any(s.final for s in statuses):
        out = executive.tick(now)
        chunks += out.chunks
        statuses += out.statuses
        events += out.events
        job = executive.active
        if job is not None and job.held is not None and now >= job.stream.start_ns + hold_s * 1e9 and not job.final:
            if cancel:
                executive.cancel("p", now)
            else:
                resumed, error = executive.resume("p", now)
                assert error == ""
                chunks += resumed.chunks
        now += TICK_NS
        assert now < 60e9
    return chunks, statuses, events


def samples(chunks: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.concatenate([c.stamp_ns + np.arange(len(c.positions)) * c.period_ns for c in chunks])
    return t, np.vstack([c.positions for c in chunks]), np.vstack([c.velocities for c in chunks])


PROGRAM = "G21 G90\nG0 X0 Y0 Z5\nS1000 M3\nG1 X5 F600\nM0\nG0 X10\nM5\nM2\n"


def test_a_hold_streams_on_the_grid_axes_standing_and_the_spindle_turning_until_resumed():
    chunks, statuses, events = run(submit(PROGRAM))
    t, p, v = samples(chunks)
    assert (np.diff(t) == MILL_PERIOD_NS).all()  # one stream, hold and resume included
    hold = next(e for e in events if e["name"] == "hold")
    resume = next(e for e in events if e["name"] == "resume")
    assert (hold["line"], hold["code"], resume["line"]) == (5, "M0", 5)
    during = (t > hold["stamp_ns"] + MILL_PERIOD_NS) & (t < resume["stamp_ns"])  # the hold's own setpoints
    x, s = MILL.joint_names.index("x"), MILL.joint_names.index("spindle")
    assert during.sum() >= 1000 and np.ptp(p[during, x]) == 0.0 and (v[during, x] == 0.0).all()
    assert v[during, s] == pytest.approx(SPINDLE_RAD_S)  # M0 leaves the spindle on, as LinuxCNC's
    # the spindle's angle runs on without a jump through the hold and the resume
    steps = np.diff(p[:, s]) - 0.5 * (v[1:, s] + v[:-1, s]) * 1e-3
    assert np.abs(steps).max() < 1e-3
    assert p[-1, x] == pytest.approx(0.010, abs=1e-6) and v[-1, s] == 0.0
    held = [st for st in statuses if st.state == "held"]
    assert held and all(st.reason.startswith("held at line 5 (M0): resume by publishing 'p' on job_resume")
                        for st in held)
    assert len({st.progress for st in held}) == 1  # progress stands while held
    final = statuses[-1]
    assert final.state == "succeeded" and final.cycle_time_s > final.duration_s + 1.0  # the hold counts


def test_a_resume_names_no_held_job_and_changes_nothing():
    executive = submit(PROGRAM)
    out, error = executive.resume("p", 0)
    assert error == "cannot resume 'p': it is queued, not held" and out.chunks == []
    assert executive.resume("q", 0)[1] == "cannot resume 'q': no such job in this planner"
    assert executive.tick(0).chunks  # running now, streaming up to its M0
    out, error = executive.resume("p", 0)
    assert error == "cannot resume 'p': it is running, not held" and out.chunks == []
    assert executive.active.held is None and not executive.active.stream.stopping
    now = 0
    while executive.active.held is None:  # streamed up to its M0
        now += TICK_NS
        executive.tick(now)
    out, error = executive.resume("p", now)
    assert error == "" and out.chunks[-1].end_ns == now + 2_000_000_000 - MILL_PERIOD_NS  # planning_lookahead
    assert executive.resume("p", now) == (Output(), "cannot resume 'p': it is resuming")


def test_a_cancel_while_held_stops_the_spindle():
    chunks, statuses, _ = run(submit(PROGRAM), cancel=True)
    _, p, v = samples(chunks)
    assert statuses[-1].state == "canceled"
    assert (v[-1] == 0.0).all() and p[-1, MILL.joint_names.index("x")] == pytest.approx(0.005, abs=1e-6)


def test_a_pause_before_any_motion_and_two_in_a_row_each_hold():
    gcode = "G21 G90\nM0\nG0 X0 Y0 Z5\nM0\nM1\nG0 X10\nM0\nM2\n"
    chunks, statuses, events = run(submit(gcode), hold_s=0.3)
    assert [(e["name"], e.get("line")) for e in events if e["name"] in ("hold", "resume")] == [
        ("hold", 2), ("resume", 2), ("hold", 4), ("resume", 4), ("hold", 5), ("resume", 5), ("hold", 7), ("resume", 7)]
    assert [e["index"] for e in events if e["name"] == "operation"] == [0, 1]
    assert statuses[-1].state == "succeeded"
    t, _, _ = samples(chunks)
    assert (np.diff(t) == MILL_PERIOD_NS).all()



def test_the_duration_stands_through_holds_and_progress_never_goes_back():
    _, statuses, _ = run(submit(PROGRAM))
    durations = [s.duration_s for s in statuses]
    assert max(durations) - min(durations) < 1e-6  # the motion's, held or not, planned again or not
    progress = [s.progress for s in statuses]
    assert progress == sorted(progress) and progress[-1] == 1.0
