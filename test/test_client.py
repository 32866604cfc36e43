"""The cell controller's client (cnc_msgs_py.client) and cnc-submit, against running nodes.

runner.Session starts planner and bridge under /cnc and records every topic; the client
talks to them over the topics only. A bad job must fail in the client, before anything
is published on job_goal (the recording shows what was).
"""
from __future__ import annotations

import json
import subprocess
import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from cnc_msgs_py import qos
from cnc_msgs_py.client import RESEND_S, CncClient
from cnc_msgs_py.qos import PLANNER_LEASE_S
from cnc_msgs_py.status import Status
from cnc_msgs_py.job import load_job
from cnc_msgs_py.schema import JobError
from cnc_planner.runner import Session
from cnc_analysis.recording import read_run

from support import BIN, JOBS, cnc


def move_job(job_id: str, x: float, feed: float = 3000.0) -> dict:
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3",
            "move": [{"linear": {"x": x}, "feed": feed}, {"rapid": {"x": 0}}]}


def yaml_text(doc: dict) -> str:
    moves = "\n".join(f"  - {json.dumps(m)}" for m in doc["move"])
    return (f"schema: cnc_job/1\njob_id: {doc['job_id']}\nkind: move\nmachine: mill3\n"
            f"move:\n{moves}\n")


def submit_process(*args: str) -> subprocess.Popen:
    return subprocess.Popen([str(BIN / "cnc-submit"), *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def finish(session: Session, proc: subprocess.Popen, timeout: float = 45) -> tuple[str, str]:
    """Keep the session recording while cnc-submit works; its output once it exits."""
    session.spin_until(lambda: proc.poll() is not None, timeout, "cnc-submit did not end")
    return proc.communicate()


def test_cnc_submit_runs_and_cancels_jobs_on_running_nodes(tmp_path):
    job = tmp_path / "short.yaml"
    job.write_text(yaml_text(move_job("sub-1", 20.0)))
    queued = tmp_path / "queued.yaml"
    queued.write_text(yaml_text(move_job("sub-2", 20.0)))
    with Session("mill3", tmp_path / "bag") as session:
        proc = submit_process(job, "--namespace", "/cnc", "--timeout", "30")
        out, err = finish(session, proc)
        assert proc.returncode == 0, err
        final = json.loads(out.strip().splitlines()[-1])
        assert final["job_id"] == "sub-1" and final["state"] == "succeeded" and final["cycle_time_s"] > 0
        assert "Traceback" not in err

        # sub-2 waits behind 600 s (machine time) of feed, and --cancel-after cancels it 3 s
        # (wall) after sending: planned in milliseconds, it is accepted long before that, and
        # still waiting then unless the simulation ran 200x real time (it runs up to 16x)
        session.submit(json.dumps(move_job("ahead", 200.0, feed=20.0)))
        session.spin_until(lambda: any(s["job_id"] == "ahead" and s["state"] == "running"
                                       for s in session.recorder.statuses), 30, "the job ahead did not start")
        proc = submit_process(queued, "--cancel-after", "3", "--timeout", "30")
        out, err = finish(session, proc)
        assert proc.returncode == 0, err  # canceled, as asked
        assert json.loads(out.strip().splitlines()[-1])["state"] == "canceled"
        session.cancel("ahead")
        assert session.wait("ahead", 60)["state"] == "canceled"
    # The planner got both (job_goal keeps no history, so a recorder discovered by the
    # cnc-submit process after it sent may miss a goal; the statuses are latched).
    finals = [(s["job_id"], s["state"]) for s in read_run(tmp_path / "bag").statuses
              if s["state"] != "running" and s["job_id"] != "ahead"]
    assert finals == [("sub-1", "accepted"), ("sub-1", "succeeded"), ("sub-2", "accepted"), ("sub-2", "canceled")]


def test_client_submits_follows_waits_and_cancels_in_process(tmp_path):
    with Session("mill3", tmp_path / "bag") as session:
        node = rclpy.create_node("cell_controller")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.add_node(session.recorder)  # keeps recording while the client spins
        try:
            client = CncClient(node, namespace="/cnc", executor=executor)
            seen: list[dict] = []
            client.on_progress(seen.append)

            # A bad job fails in the client, naming the field; nothing is sent.
            bad = move_job("bad-1", 10.0, feed=-300)
            with pytest.raises(JobError, match=r"move\[0\]\.feed"):
                client.submit(bad)
            with pytest.raises(JobError, match="cannot read job file"):
                client.submit(str(tmp_path / "missing.yaml"))

            # A dict, waited for.
            job_id = client.submit(move_job("cli-1", 15.0))
            final = client.wait(job_id, timeout=30)
            assert final["state"] == "succeeded" and final["job_id"] == "cli-1"
            assert client.status("cli-1") == final
            states = [s["state"] for s in seen if s["job_id"] == "cli-1"]
            assert states[0] == "accepted" and "running" in states and states[-1] == "succeeded"
            running = [s for s in seen if s["state"] == "running"]
            assert all(0.0 <= s["progress"] <= 1.0 and s["duration_s"] > 0 for s in running)

            # The same goal again (a client's resend): answered with the job's latest status,
            # not run again.
            session.submit(json.dumps(load_job(move_job("cli-1", 15.0))))
            deadline = time.monotonic() + 30
            while [s["state"] for s in session.recorder.statuses if s["job_id"] == "cli-1"].count("succeeded") < 2:
                assert time.monotonic() < deadline, "the repeated goal was not answered"
                executor.spin_once(timeout_sec=0.05)
            assert [s["state"] for s in session.recorder.statuses if s["job_id"] == "cli-1"].count("accepted") == 1

            # YAML text, canceled once it runs; a timeout is an exception, not a hang. 120 s of
            # feed, so that it is still running 0.3 s on and when the cancel comes unless the
            # simulation ran 100x real time (while this client spins, the recorder holds the
            # bridge back for 1 s only; then it ran 7x)
            job_id = client.submit(yaml_text(move_job("cli-2", 200.0, feed=100.0)))
            with pytest.raises(TimeoutError, match="cli-2"):
                client.wait(job_id, timeout=0.3)
            deadline = time.monotonic() + 20
            while (client.status(job_id) or {}).get("state") != "running" and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
            assert client.status(job_id)["state"] == "running"
            client.cancel(job_id)
            assert client.wait(job_id, timeout=30)["state"] == "canceled"

            # The planner's own rejection comes back as a final status (duplicate job_id).
            job_id = client.submit(move_job("cli-1", 5.0))
            assert client.wait(job_id, timeout=30)["state"] == "rejected"
            # The client may hear the rejection before the recorder (on the same executor)
            # has taken the goal: record until the recorder has the rejection too, which the
            # planner sent after the goal reached it.
            deadline = time.monotonic() + 30
            while not any(s["job_id"] == "cli-1" and s["state"] == "rejected" for s in session.recorder.statuses):
                assert time.monotonic() < deadline, "the recorder never heard the rejection"
                executor.spin_once(timeout_sec=0.05)
        finally:
            executor.remove_node(session.recorder)
            executor.remove_node(node)
            node.destroy_node()
    goals = [json.loads(g)["job_id"] for g in dict.fromkeys(read_run(tmp_path / "bag").goals)]  # resends once
    assert goals == ["cli-1", "cli-2", "cli-1"]  # never bad-1


def test_a_goal_the_planner_missed_is_sent_again_until_a_status_answers_it():
    """A planner whose side of the DDS match came after the goal never sees it (a volatile
    topic): the client sends the same goal again while it hears nothing of it. Here a
    stand-in planner drops the first copy and answers the second."""
    from std_msgs.msg import String

    rclpy.init()
    try:
        planner, cell = rclpy.create_node("cnc_planner", namespace="/cnc"), rclpy.create_node("cell_controller")
        executor = SingleThreadedExecutor()
        executor.add_node(planner)
        executor.add_node(cell)
        heard: list[tuple[str, float]] = []
        status_pub = planner.create_publisher(String, "job_status", qos.JOB_STATUS)

        def on_goal(msg: String) -> None:
            heard.append((msg.data, time.monotonic()))
            if len(heard) == 2:
                job_id = json.loads(msg.data)["job_id"]
                for state in ("accepted", "succeeded"):
                    status_pub.publish(String(data=Status(job_id, state).encode()))
        planner.create_subscription(String, "job_goal", on_goal, qos.JOB_GOAL)
        client = CncClient(cell, namespace="/cnc", executor=executor)
        job_id = client.submit(move_job("resent-1", 5.0))
        assert client.wait(job_id, timeout=30)["state"] == "succeeded"
        assert len(heard) == 2 and heard[0][0] == heard[1][0]  # the same goal, byte for byte
        assert heard[1][1] - heard[0][1] >= RESEND_S - 0.05
        end = time.monotonic() + 2 * RESEND_S  # answered: sent no more
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        assert len(heard) == 2
    finally:
        rclpy.try_shutdown()


def test_client_follows_another_controllers_job_and_says_when_the_planner_is_lost(tmp_path):
    """DDS liveliness of job_status: a planner that dies (SIGKILL, as a host that goes
    away) is reported unreachable within its lease and reachable once it is back."""
    with Session("mill3", tmp_path / "bag") as session:
        node = rclpy.create_node("cell_controller")
        executor = SingleThreadedExecutor()  # the client's own; the session spins the recorder
        executor.add_node(node)

        def spin_until(done, timeout: float) -> None:
            deadline = time.monotonic() + timeout
            while not done() and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
            assert done()
        try:
            client = CncClient(node, namespace="/cnc", executor=executor)
            changes: list[tuple[bool, float]] = []
            client.on_reachability(lambda up: changes.append((up, time.monotonic())))
            session.submit(json.dumps(move_job("other-1", 10.0)))  # sent by the session, not the client
            client.follow("other-1")
            assert client.wait("other-1", timeout=30)["state"] == "succeeded"
            spin_until(lambda: client.reachable is True, 10)

            killed = time.monotonic()
            session.kill("planner")
            spin_until(lambda: client.reachable is False, 10)
            assert changes[-1][1] - killed <= PLANNER_LEASE_S + 1.0
            session.restart("planner")
            spin_until(lambda: client.reachable is True, 30)
            assert [up for up, _ in changes] == [True, False, True]
        finally:
            executor.remove_node(node)
            node.destroy_node()


def test_cnc_submit_refuses_a_bad_job_in_one_line_before_any_ros(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml_text(move_job("bad-2", 10.0, feed=-300)))
    for args, expected in (([bad], "move[0].feed: must be > 0 mm/min"),
                           ([tmp_path / "missing.yaml"], "cannot read job file"),
                           ([JOBS / "drill_row.yaml", "--timeout", "0"], "--timeout: must be > 0")):
        result = cnc("cnc-submit", *args, timeout=30)
        assert result.returncode == 2, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0] and lines[0].startswith("cnc-submit: "), result.stderr
        assert result.stdout == ""


def test_load_job_takes_dicts_text_and_files():
    doc = load_job(JOBS / "drill_row.yaml")
    assert load_job(str(JOBS / "drill_row.yaml")) == doc
    assert load_job(json.dumps(doc)) == doc
    assert load_job(doc) is doc
    with pytest.raises(JobError, match="drill.depth"):
        load_job({**doc, "drill": {**doc["drill"], "depth": -1}})
    with pytest.raises(JobError, match="mapping"):
        load_job("- just\n- a list\n")
