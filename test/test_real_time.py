"""Real-time mode: the bridge steps on the wall clock, no /clock, and a job still runs."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from cnc_planner.executive import Settings
from cnc_planner.runner import Session
from cnc_analysis.recording import read_run


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
    """Goals that take longer to plan than the buffered setpoints last (1 s while goals are
    planned; twelve 50-hole plates of different depths, each about 0.1 s when the CPU is
    free, and not sharing the retract search's cache) arrive while a job runs in real time:
    they are planned beside the stream, not in its way."""
    running = {"schema": "cnc_job/1", "job_id": "rt-run", "kind": "move", "machine": "mill3",
               "move": [{"rapid": {"x": 20.0}}, {"linear": {"x": 0.0}, "feed": 150}]}
    plates = [{"schema": "cnc_job/1", "job_id": f"rt-plate-{k}", "kind": "drill", "machine": "mill3",
               "spindle_rpm": 3000,
               "drill": {"holes": [[5.0 * (i % 10) + k, 5.0 * (i // 10)] for i in range(50)],
                         "surface_z": 0.0, "depth": 5.0 + 0.5 * k, "r_gap": 2.0, "feed": 1200}} for k in range(12)]
    ids = [p["job_id"] for p in plates]
    with Session("mill3", tmp_path / "bag", simulation=False) as session:
        session.submit(json.dumps(running))
        session.spin_until(lambda: any(s["job_id"] == "rt-run" and s["state"] == "running"
                                       for s in session.recorder.statuses), 30, "the first job did not start")
        started = time.monotonic()
        for plate in plates:
            session.submit(json.dumps(plate))
        session.spin_until(lambda: {s["job_id"] for s in session.recorder.statuses} >= set(ids), 60,
                           "the plates were not answered")
        planning = time.monotonic() - started
        for job_id in ids:
            session.cancel(job_id)  # only their planning matters here
        final = session.wait("rt-run", 60)
        for job_id in ids:
            session.wait(job_id, 60)
    order = [(s["job_id"], s["state"]) for s in session.recorder.statuses]
    # the plates were planned and canceled while the first job ran
    for job_id in ids:
        assert order.index((job_id, "accepted")) < order.index((job_id, "canceled")) < order.index(("rt-run", "succeeded"))
    # longer than the buffered setpoints last: planning inline would starve the stream
    assert planning > Settings().planning_lookahead_ns / 1e9
    assert final["state"] == "succeeded", final.get("reason")
    run = read_run(tmp_path / "bag")
    assert not run.alarms
