"""Real-time mode: the bridge steps on the wall clock, no /clock, and a job still runs."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from cnc_planner.runner import Session
from cnc_servo_bridge.recording import read_run


def test_a_job_runs_in_real_time_mode(tmp_path):
    job = {"schema": "cnc_job/1", "job_id": "rt", "kind": "move", "machine": "mill3",
           "move": [{"rapid": {"x": 20.0}}, {"linear": {"x": 0.0}, "feed": 1200}]}
    with Session("mill3", tmp_path / "bag", simulation=False) as session:
        session.submit(json.dumps(job))
        final = session.wait("rt", 60)
        assert final["state"] == "succeeded"
        session.settle(final)
    run = read_run(tmp_path / "bag")
    # Stamps are wall-clock time, 1 ms apart, and the job took (about) its planned time.
    assert abs(run.feedback_t[-1] - time.time()) < 60
    assert np.median(np.diff(run.feedback_t)) == pytest.approx(0.001, abs=1e-6)
    assert final["cycle_time_s"] > 1.0  # 20 mm at 20 mm/s plus the rapid
    assert abs(run.feedback[-1, run.column("x")]) < 1e-6
    assert not run.alarms


def test_planning_the_next_job_does_not_starve_the_running_one(tmp_path):
    """A goal that takes seconds to plan (a 50-hole plate) arrives while a job runs in real
    time with 0.3 s of setpoints buffered: it is planned beside the stream, not in its way."""
    running = {"schema": "cnc_job/1", "job_id": "rt-run", "kind": "move", "machine": "mill3",
               "move": [{"rapid": {"x": 20.0}}, {"linear": {"x": 0.0}, "feed": 150}]}
    plate = {"schema": "cnc_job/1", "job_id": "rt-plate", "kind": "drill", "machine": "mill3", "spindle_rpm": 3000,
             "drill": {"holes": [[5.0 * (i % 10), 5.0 * (i // 10)] for i in range(50)],
                       "surface_z": 0.0, "depth": 5.0, "r_gap": 2.0, "feed": 1200}}
    with Session("mill3", tmp_path / "bag", simulation=False) as session:
        session.submit(json.dumps(running))
        session.spin_until(lambda: any(s["job_id"] == "rt-run" and s["state"] == "running"
                                       for s in session.recorder.statuses), 30, "the first job did not start")
        started = time.monotonic()
        session.submit(json.dumps(plate))
        session.spin_until(lambda: any(s["job_id"] == "rt-plate" for s in session.recorder.statuses), 60,
                           "the plate was not answered")
        planning = time.monotonic() - started
        session.cancel("rt-plate")  # only its planning matters here
        final = session.wait("rt-run", 60)
        session.wait("rt-plate", 60)
    order = [(s["job_id"], s["state"]) for s in session.recorder.statuses]
    # the plate was planned and canceled while the first job ran
    assert order.index(("rt-plate", "accepted")) < order.index(("rt-plate", "canceled")) < order.index(("rt-run", "succeeded"))
    assert planning > 0.3  # longer than the buffered setpoints last: planning inline would starve the stream
    assert final["state"] == "succeeded", final.get("reason")
    run = read_run(tmp_path / "bag")
    assert not run.alarms
