"""Cancel and queueing over real topics: a jerk-limited stop, then the next job runs."""
from __future__ import annotations

import json

import numpy as np

from cnc_planner.runner import Session
from cnc_analysis.recording import read_run

from support import running_past


def job_text(job_id: str, x: float) -> str:
    doc = {"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3",
           "move": [{"linear": {"x": x}, "feed": 3000}, {"rapid": {"x": 0}}]}
    return json.dumps(doc)


def test_cancel_mid_move_stops_smoothly_and_next_job_runs(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(job_text("long", 200.0))  # 200 mm at 50 mm/s: 4 s
        running_past(session, "long", 0.2)
        session.cancel("long")
        assert session.wait("long", 60)["state"] == "canceled"
        session.submit(job_text("after", 20.0))
        final = session.wait("after", 60)
        assert final["state"] == "succeeded"
        session.settle(final)
    run = read_run(tmp_path / "bag")
    x = run.column("x")
    v = run.command_velocity[:, x]
    # The commanded speed falls from feed to zero without a step (jerk-limited stop).
    accel = np.diff(v) / np.diff(run.command_t)
    assert np.abs(accel).max() <= 9.8 * 1.01
    peak = run.command[:, x].max()
    assert 0.01 < peak < 0.2  # stopped well before the 200 mm target
    # After the stop the axis came back (second job) and the feedback ended at x = 0.
    assert abs(run.feedback[-1, x]) < 1e-6
    states = [s["state"] for s in run.statuses if s["job_id"] == "after"]
    assert states[0] == "accepted" and states[-1] == "succeeded"


def test_jobs_queue_and_run_in_order(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        for k in range(3):
            session.submit(job_text(f"q{k}", 10.0 + k))
        for k in range(3):
            assert session.wait(f"q{k}", 60)["state"] == "succeeded"
    finals = [s["job_id"] for s in read_run(tmp_path / "bag").statuses if s["state"] == "succeeded"]
    assert finals == ["q0", "q1", "q2"]
