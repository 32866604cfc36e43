"""Real-time mode: the bridge steps on the wall clock, no /clock, and a job still runs."""
from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from cnc_planner.executive import Settings
from cnc_planner.runner import Session
from cnc_analysis.recording import read_run
from zigzag_paths import MOST_POINTS, zigzag_path


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
    """Goals whose planning lasts more than twice as long as the setpoints buffered while
    goals are planned (2 s) arrive while a job runs in real time: planned in the stream's way
    they would run the stream dry (they do with the planner's intake thread taken out);
    planned beside it, they do not. That premise is built, not assumed: goals come in
    groups, planned one after the other, their planning measured on the machine's clock from
    the first's answer to the last's, and while a group plans faster than that the next one
    has longer paths, or more of them once the paths have MOST_POINTS."""
    lookahead_ns = Settings().planning_lookahead_ns
    running = {"schema": "cnc_job/1", "job_id": "rt-run", "kind": "move", "machine": "mill3",
               "move": [{"rapid": {"x": 20.0}}, {"linear": {"x": 0.0}, "feed": 10}]}  # 120 s, canceled
    # (long enough that the groups plan beside it on a loaded host: under make stress a pair
    # of 8000-point paths once took 78 s)
    ids: list[str] = []

    def answer(job_id: str) -> dict | None:
        return next((s for s in session.recorder.statuses if s["job_id"] == job_id), None)

    with Session("mill3", tmp_path / "bag", simulation=False) as session:
        session.submit(json.dumps(running))
        session.spin_until(lambda: any(s["job_id"] == "rt-run" and s["state"] == "running"
                                       for s in session.recorder.statuses), 30, "the first job did not start")
        points, goals, planning_ns = 1000, 2, 0
        while planning_ns <= 2 * lookahead_ns:
            group = [zigzag_path(f"rt-path-{len(ids) + k}", len(ids) + k, points) for k in range(goals)]
            group_ids = [goal["job_id"] for goal in group]
            ids += group_ids
            for goal in group:
                session.submit(json.dumps(goal))
            session.spin_until(lambda: all(map(answer, group_ids)), 120, "the goals were not answered")
            answers = list(map(answer, group_ids))
            assert all(a["state"] == "accepted" for a in answers), [a["reason"] for a in answers]
            planning_ns = answers[-1]["stamp_ns"] - answers[0]["stamp_ns"]
            for job_id in group_ids:
                session.cancel(job_id)  # only their planning matters here
            # the next group aimed at 3 lookaheads: at least twice, at most 8 times the work
            grow = min(8.0, max(2.0, 3 * lookahead_ns / max(planning_ns, 1)))
            if points < MOST_POINTS:
                points = min(MOST_POINTS, math.ceil(points * grow))
            else:
                goals = math.ceil((goals - 1) * grow) + 1  # the first's planning is not measured
        for job_id in ids:
            session.wait(job_id, 60)
        session.cancel("rt-run")
        final = session.wait("rt-run", 60)
    # it ran until canceled, and the goals were planned and canceled meanwhile
    assert (final["state"], final["reason"]) == ("canceled", "canceled by request")
    order = [(s["job_id"], s["state"]) for s in session.recorder.statuses]
    for job_id in ids:
        assert order.index((job_id, "accepted")) < order.index((job_id, "canceled")) < order.index(("rt-run", "canceled"))
    run = read_run(tmp_path / "bag")
    assert not run.alarms
