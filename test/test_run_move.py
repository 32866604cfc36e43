"""The spine end to end: a job over the topic, setpoints to the emulated drives, feedback
recorded, and a report that the recording alone reproduces."""
from __future__ import annotations

import json
import os
import zipfile

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from cnc_planner.runner import Session
from support import JOBS, cnc, load_report

JOB = JOBS / "move_mill3.yaml"


@pytest.fixture(scope="module")
def move_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("move") / "run"
    result = cnc("cnc-run", JOB, "--out", out)
    assert result.returncode == 0, result.stderr[-2000:]
    return out


def read_bag(bag):
    """An independent reading of the bag with rosbags only (no project code)."""
    topics = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn, _, raw in reader.messages():
            topics.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    return topics


def test_recording_holds_every_topic_in_standard_types(move_run):
    topics = read_bag(move_run / "bag")
    for name in ("/cnc/job_goal", "/cnc/job_status", "/cnc/joint_trajectory", "/cnc/joint_states",
                 "/cnc/job_events", "/diagnostics", "/clock"):
        assert topics.get(name), f"{name} missing from the recording"
    assert (move_run / "bag" / "metadata.yaml").exists()
    assert list((move_run / "bag").glob("*.mcap"))
    goal = json.loads(topics["/cnc/job_goal"][0].data)
    assert goal["job_id"] == "move-mill3-demo"


def test_the_goal_was_sent_once_the_planner_had_heard_the_bridge(move_run):
    """cnc-run submits once the planner's heartbeat says it has heard the bridge (where the
    axes stand, and its report): a goal sent before that waited for the bridge's next
    report, 100 steps of idle sim time at the wall's pace, and was planned from a guessed
    start, to be planned again when it started."""
    said_ready, goal_at = [], None
    with AnyReader([move_run / "bag"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn, stamp, raw in reader.messages():
            if conn.topic == "/cnc/job_goal":
                goal_at = stamp
                break
            if conn.topic == "/diagnostics":
                for status in reader.deserialize(raw, conn.msgtype).status:
                    values = {kv.key: kv.value for kv in status.values}
                    if status.name.startswith("cnc_planner") and values.get("ready") == "yes":
                        said_ready.append(stamp)
    assert goal_at is not None and said_ready, "no planner heartbeat said ready before the goal"


def test_chunks_are_contiguous_and_follow_jtc_rules(move_run):
    chunks = read_bag(move_run / "bag")["/cnc/joint_trajectory"]
    period = 1_000_000
    prev_end = None
    for chunk in chunks:
        stamp = chunk.header.stamp.sec * 10**9 + chunk.header.stamp.nanosec
        offsets = np.array([p.time_from_start.sec * 10**9 + p.time_from_start.nanosec for p in chunk.points])
        assert offsets[0] == 0 and np.all(np.diff(offsets) == period)
        assert list(chunk.joint_names) == ["x", "y", "z", "spindle"]
        if prev_end is not None:
            assert stamp == prev_end + period
        prev_end = stamp + offsets[-1]
    last = chunks[-1].points[-1]
    assert np.allclose(last.velocities, 0.0) and np.allclose(last.accelerations, 0.0)


def test_feedback_follows_setpoints_and_ends_on_target(move_run):
    topics = read_bag(move_run / "bag")
    states = topics["/cnc/joint_states"]
    t = np.array([s.header.stamp.sec + s.header.stamp.nanosec * 1e-9 for s in states])
    pos = np.array([s.position for s in states])
    assert np.allclose(np.diff(t), 1e-3), "a feedback sample is missing from the recording"
    points = [(c.header.stamp.sec + c.header.stamp.nanosec * 1e-9 + p.time_from_start.nanosec * 1e-9, p.positions)
              for c in topics["/cnc/joint_trajectory"] for p in c.points]
    ct = np.array([p[0] for p in points])
    cmd = np.array([p[1] for p in points])
    inside = (t >= ct[0]) & (t <= ct[-1])
    for j in range(3):  # linear axes: following error well inside the 2 mm alarm limit
        error = np.abs(np.interp(t[inside], ct, cmd[:, j]) - pos[inside, j])
        assert error.max() < 0.5e-3
    job = yaml.safe_load(JOB.read_text())
    final = job["move"][-1]["rapid"]
    assert pos[-1, 0] == pytest.approx(final["x"] * 1e-3, abs=1e-6)
    assert pos[-1, 1] == pytest.approx(final["y"] * 1e-3, abs=1e-6)
    assert pos[-1, 2] == pytest.approx(final["z"] * 1e-3, abs=1e-6)


def test_report_figures_and_cnc_analyze_reproduces_them(move_run, tmp_path):
    report = load_report(move_run)
    assert report["state"] == "succeeded" and report["job_id"] == "move-mill3-demo"
    assert report["chunks_lost"] == 0
    assert report["setpoints"] > 5000
    # Planned duration 6.15 s includes the spindle ramp-down after the last rapid.
    assert 5.0 < report["cycle_time_s"] < report["planned_time_s"]
    assert set(report["max_following_error"]) == {"x", "y", "z", "spindle"}
    again = cnc("cnc-analyze", move_run / "bag", "--out", tmp_path / "again.json")
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "again.json").read_text()) == report


def test_rejected_job_gets_a_report_and_moves_nothing(tmp_path):
    job = yaml.safe_load(JOB.read_text())
    job["job_id"] = "bad-feed"
    job["move"][1]["feed"] = -300
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(job))
    result = cnc("cnc-run", path, "--out", tmp_path / "run")
    assert result.returncode != 0
    report = load_report(tmp_path / "run")
    assert report["state"] == "rejected"
    assert report["reason"].startswith("move[1].feed:")
    assert report["setpoints"] == 0
    topics = read_bag(tmp_path / "run" / "bag")
    assert "/cnc/joint_trajectory" not in topics
    assert "Traceback" not in result.stderr


def test_a_second_run_in_the_same_domain_is_refused_before_it_sends_a_goal(tmp_path):
    """Two runs in one domain and namespace would take each other's goals: a mill3 job went
    to another run's lathe planner once, and was rejected there for the wrong machine; and
    while the DDS graph had not yet shown the other run (1 in 5 tries), it went to both and
    the mill's planner took the lathe's feedback. This host's claim refuses it at once."""
    with Session("lathe", tmp_path / "first") as first:
        result = cnc("cnc-run", JOB, "--out", tmp_path / "second")
        assert result.returncode == 3
        assert result.stderr == (f"cnc-run: another run (pid {os.getpid()}) already runs nodes at /cnc in "
                                 f"ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']} on this host: "
                                 "set ROS_DOMAIN_ID to a free domain\n")  # nothing started, nothing logged
        heard = first.recorder.heard.planner_heartbeats
        first.spin_until(lambda: first.recorder.heard.planner_heartbeats >= heard + 2, 30, "the planner went quiet")
        assert first.final_status("move-mill3-demo") is None  # the goal was never sent


def test_missing_job_file_is_one_line(tmp_path):
    result = cnc("cnc-run", tmp_path / "nope.yaml", "--out", tmp_path / "run")
    assert result.returncode != 0
    assert result.stderr.strip().count("\n") == 0 and "nope.yaml" in result.stderr
    assert load_report(tmp_path / "run")["state"] == "rejected"


def test_cnc_plan_offline_writes_setpoints_planned_as_cnc_run_plans_them(move_run, tmp_path):
    """From the machine's home (mill3: Z 50 mm), where cnc-run's drives start: the same plan."""
    result = cnc("cnc-plan", JOB, "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    data = np.load(tmp_path / "setpoints.npz")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["joints"] == ["x", "y", "z", "spindle"]
    assert len(data["t"]) == summary["setpoints"]
    assert (data["x"][0], data["y"][0], data["z"][0]) == (0.0, 0.0, 0.05)
    assert data["x"][-1] == pytest.approx(0.0) and data["z"][-1] == pytest.approx(0.010)
    assert summary["duration_s"] == pytest.approx(load_report(move_run)["planned_time_s"], abs=1e-3)


def test_cnc_plan_stores_setpoints_unless_asked_to_compress(tmp_path):
    """Stored by default (the fastest write); --compress deflates the very same arrays."""
    for option, out in (((), tmp_path / "stored"), (("--compress",), tmp_path / "deflated")):
        assert cnc("cnc-plan", JOB, "--out", out, *option).returncode == 0
    with zipfile.ZipFile(tmp_path / "stored" / "setpoints.npz") as stored, \
            zipfile.ZipFile(tmp_path / "deflated" / "setpoints.npz") as deflated:
        assert {i.compress_type for i in stored.infolist()} == {zipfile.ZIP_STORED}
        assert {i.compress_type for i in deflated.infolist()} == {zipfile.ZIP_DEFLATED}
    with np.load(tmp_path / "stored" / "setpoints.npz") as a, np.load(tmp_path / "deflated" / "setpoints.npz") as b:
        assert sorted(a.files) == sorted(b.files) and all(np.array_equal(a[k], b[k]) for k in a.files)
