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
