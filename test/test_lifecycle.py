"""The bridge as a managed node: transitions through its standard lifecycle services
(<ns>/cnc_servo_bridge/change_state, get_state), driven by the cell controller's client,
on real processes in simulation mode. Judged on the recorded joint_states."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_msgs_py.client import CncClient, CncClientError
from cnc_msgs_py.machine import load_machine
from cnc_planner.runner import Session
from cnc_servo_bridge.bridge_node import DEACTIVATED
from cnc_analysis.recording import read_run
from cnc_servo_bridge.servo import DRIVES_DISABLED

from support import LONG, SHORT, move_job, running_past

X = load_machine("mill3").axes["x"]
CRUISE = 0.05  # m/s: LONG feeds x at 3000 mm/min


def first_running_s(session: Session, job_id: str) -> float:
    return next(s["stamp_ns"] for s in session.recorder.statuses
                if s["job_id"] == job_id and s["state"] == "running") / 1e9


def test_deactivate_mid_job_is_a_jerk_limited_stop_the_job_aborts_and_after_activate_the_next_runs(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        client = CncClient(session.recorder, executor=session.executor)
        assert client.bridge_state() == "active"  # autostart: up and driving with one command
        session.submit(move_job("cut", LONG))
        running_past(session, "cut", 0.3)  # x cruising at 50 mm/s
        deactivated_s = session.recorder.sim_ns / 1e9
        assert client.bridge_transition("deactivate") == "inactive"
        cut = session.wait("cut", 60)
        assert cut["state"] == "aborted" and cut["reason"] == DEACTIVATED
        session.settle(cut, 1.0)  # a second of the inactive bridge's feedback, to judge the stop on

        # inactive: joint_states go on, setpoints are refused with the reason
        heard = session.recorder.feedback_ns
        session.submit(move_job("while-inactive", SHORT))
        refused = session.wait("while-inactive", 60)
        assert refused["state"] == "aborted" and refused["reason"] == f"refused setpoints: {DRIVES_DISABLED}"
        assert session.recorder.feedback_ns > heard
        with pytest.raises(CncClientError, match="refused 'deactivate' \\(it is inactive\\)"):
            client.bridge_transition("deactivate")

        assert client.bridge_transition("activate") == "active"
        session.submit(move_job("next", SHORT))
        done = session.wait("next", 60)
        assert done["state"] == "succeeded"
        next_start_s = first_running_s(session, "next")
        session.settle(done)
    run = read_run(tmp_path / "bag")
    assert DEACTIVATED in run.alarms
    x = run.column("x")
    t = run.feedback_t
    window = (t >= deactivated_s) & (t < next_start_s)  # from the deactivation to the next job
    p, v, tw = run.feedback[window, x], run.feedback_velocity[window, x], t[window]
    assert v[0] == pytest.approx(CRUISE, rel=0.02)  # it was cruising when deactivated
    dt = np.diff(tw)
    # no jump: positions move at most at the axis's speed, velocity changes within its acceleration
    assert np.all(np.abs(np.diff(p)) <= X.max_velocity * dt + 1e-7)
    decel = -np.diff(v) / dt
    assert np.abs(decel).max() <= X.max_acceleration
    # jerk-limited: braking from 50 mm/s at jerk J (triangular deceleration) peaks at
    # sqrt(v J) = 3.16 m/s^2, where an acceleration-limited stop would brake at 9.8, and
    # takes 2 sqrt(v / J) (1 - sqrt(0.2)) = 17.5 ms from 90 % to 10 % of the speed
    assert decel.max() == pytest.approx(np.sqrt(CRUISE * X.max_jerk), rel=0.15)
    fast = int(np.argmax(v < 0.9 * CRUISE))
    slow = int(np.argmax(v < 0.1 * CRUISE))
    assert tw[slow] - tw[fast] == pytest.approx(2 * np.sqrt(CRUISE / X.max_jerk) * (1 - np.sqrt(0.2)), rel=0.2)
    # comes to rest short of the 200 mm the job was going to, and stays there until the next job
    rest = tw > tw[slow] + 0.1
    assert np.count_nonzero(rest) >= 500
    assert np.abs(v[rest]).max() < 1e-4 and np.ptp(p[rest]) <= 1e-6
    assert p[-1] < 0.2


def test_configure_cleanup_and_shutdown_without_autostart(tmp_path):
    session = Session("mill3", tmp_path / "bag", bridge_params={"autostart": False})
    try:
        client = CncClient(session.recorder, executor=session.executor)
        assert client.bridge_state() == "unconfigured"  # no drive model yet: no joint_states
        assert session.recorder.feedback_ns == 0
        assert client.bridge_transition("configure") == "inactive"  # machine loaded, drives off
        session.spin_until(lambda: session.recorder.feedback_ns > 0, 30, "no joint_states while inactive")
        assert client.bridge_transition("activate") == "active"
        session.spin_until(session.ready, 30, "the planner did not come up")
        session.submit(move_job("first", SHORT))
        assert session.wait("first", 60)["state"] == "succeeded"
        assert client.bridge_transition("deactivate") == "inactive"
        assert client.bridge_transition("cleanup") == "unconfigured"
        before = session.recorder.feedback_ns
        assert client.bridge_transition("configure") == "inactive"
        assert client.bridge_transition("activate") == "active"
        session.submit(move_job("after-reconfigure", SHORT))
        done = session.wait("after-reconfigure", 60)
        assert done["state"] == "succeeded"
        assert done["stamp_ns"] > before  # sim time ran on across cleanup and configure
        assert client.bridge_transition("shutdown") == "finalized"
    finally:
        session.close()
