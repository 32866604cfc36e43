"""Faults on real processes in simulation mode: each ends in a controlled stop or hold,
a final status with the reason, and the next job running normally afterwards."""
from __future__ import annotations

import numpy as np

from cnc_planner.runner import Session
from cnc_analysis.recording import read_run

from support import LONG, SHORT, move_job, running_past

ACCEL_X = 9.8  # mill3 x max_acceleration, m/s^2


def comes_to_rest(run, after_s: float) -> bool:
    """Feedback after a fault: x stands still (within an encoder count) at the end."""
    x = run.column("x")
    later = run.feedback[run.feedback_t > after_s, x]
    return len(later) > 200 and np.ptp(later[-100:]) <= 2e-7


def test_following_error_trip_stops_and_the_next_job_runs(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(move_job("crash", LONG))
        running_past(session, "crash", 0.2)
        session.inject("x", 0.008)  # 8 mm: beyond the 5 mm following error limit
        final = session.wait("crash", 60)
        assert final["state"] == "aborted" and final["reason"].startswith("following error on x")
        session.submit(move_job("after-crash", SHORT))
        done = session.wait("after-crash", 60)
        assert done["state"] == "succeeded"
        session.settle(done)
    run = read_run(tmp_path / "bag")
    assert any(a.startswith("following error on x") for a in run.alarms)
    assert comes_to_rest(run, final["stamp_ns"] / 1e9)


def test_soft_limit_violation_at_run_time_stops_the_job(tmp_path):
    near_limit = [{"rapid": {"x": 499.0}}, {"dwell": 5.0}, {"rapid": {"x": 0.0}}]  # x travel ends at 500 mm
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(move_job("edge", near_limit))
        session.spin_until(lambda: any(s["job_id"] == "edge" and s.get("phase") == "dwell"
                                       for s in session.recorder.statuses), 60, "never reached the dwell")
        session.inject("x", 0.0015)  # pushed 1.5 mm outward: inside the error limit, beyond travel
        final = session.wait("edge", 60)
        assert final["state"] == "aborted" and final["reason"].startswith("soft limit: x")
        session.submit(move_job("back", [{"rapid": {"x": 0.0}}]))
        assert session.wait("back", 60)["state"] == "succeeded"


def test_bridge_killed_mid_job_aborts_and_a_restarted_bridge_serves_the_next_job(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(move_job("orphan", LONG))
        running_past(session, "orphan", 0.2)
        session.kill("bridge")
        final = session.wait("orphan", 60)
        assert final["state"] == "aborted" and "no joint_states from the bridge" in final["reason"]
        session.restart("bridge")
        session.submit(move_job("after-restart", SHORT))
        assert session.wait("after-restart", 60)["state"] == "succeeded"


def test_planner_killed_mid_job_the_bridge_holds_and_a_new_planner_resumes(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        session.submit(move_job("abandoned", LONG))
        running_past(session, "abandoned", 0.2)
        session.kill("planner")
        session.restart("planner")
        session.submit(move_job("resumed", SHORT))
        done = session.wait("resumed", 60)
        assert done["state"] == "succeeded"
        session.settle(done)
    run = read_run(tmp_path / "bag")
    assert any("ran dry" in a for a in run.alarms)
    x = run.column("x")
    assert abs(run.feedback[-1, x]) < 1e-6  # the resumed job brought x home


def test_cancel_at_random_instants_always_stops_within_limits(tmp_path):
    rng = np.random.default_rng(7)
    instants = sorted(rng.uniform(0.05, 0.9, size=3))  # fractions of LONG's moves
    tail_s = 60.0  # a dwell after the moves, so the cancel comes while the job runs even at 0.9
    # of the moves (without it, 0.44 s of machine time before the job ends: 28 ms at 16x real time)
    with Session("mill3", tmp_path / "bag") as session:
        def first_status(job_id: str) -> dict | None:
            return next((s for s in session.recorder.statuses if s["job_id"] == job_id), None)

        for k, fraction in enumerate(instants):
            session.submit(move_job(f"c{k}", LONG + [{"dwell": tail_s}]))
            session.spin_until(lambda: first_status(f"c{k}") is not None, 60, f"c{k} was not answered")
            duration = first_status(f"c{k}")["duration_s"]
            running_past(session, f"c{k}", fraction * (duration - tail_s) / duration)
            session.cancel(f"c{k}")
            assert session.wait(f"c{k}", 60)["state"] == "canceled"
        session.submit(move_job("home", [{"rapid": {"x": 0.0}}]))
        done = session.wait("home", 60)
        assert done["state"] == "succeeded"
        session.settle(done)
    run = read_run(tmp_path / "bag")
    x = run.column("x")
    accel = np.diff(run.command_velocity[:, x]) / np.diff(run.command_t)
    assert np.abs(accel).max() <= ACCEL_X * 1.01
    assert not run.alarms
    assert abs(run.feedback[-1, x]) < 1e-6
