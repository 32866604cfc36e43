"""A cell of three machines (two mills and a lathe) in one DDS domain: each pair under
its own namespace, its own clock and diagnostics, its own bag; nothing crosses over."""
from __future__ import annotations

import json

import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from support import JOBS, cnc

CELL = ("move_mill3.yaml", "drill_row.yaml", "lathe_feed_vibration.yaml")


def messages(bag):
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn, _, raw in reader.messages():
            yield conn.topic, reader.deserialize(raw, conn.msgtype)


def test_three_machines_run_at_once_and_no_message_crosses(tmp_path):
    result = cnc("cnc-cell", *(JOBS / job for job in CELL), "--out", tmp_path, timeout=900)
    assert result.returncode == 0, result.stdout + "".join((tmp_path / f"m{i}.log").read_text()[-2000:] for i in (1, 2, 3))
    job_ids = [yaml.safe_load((JOBS / job).read_text())["job_id"] for job in CELL]
    for i, (job_id, joints) in enumerate(zip(job_ids, (("x", "y", "z", "spindle"),) * 2 + (("x", "z", "spindle"),)), 1):
        out = tmp_path / f"m{i}"
        report = json.loads((out / "report.json").read_text())
        assert report["job_id"] == job_id and report["state"] == "succeeded"
        prefix = f"/cell/m{i}/cnc/"
        seen_ids = set()
        for topic, msg in messages(out / "bag"):
            assert topic.startswith(prefix), f"m{i} recorded {topic}"
            if topic.endswith("/joint_states"):
                assert tuple(msg.name) == joints
            elif topic.endswith("/job_status"):
                seen_ids.add(json.loads(msg.data)["job_id"])
            elif topic.endswith("/diagnostics"):
                assert all(s.hardware_id == prefix.rstrip("/") for s in msg.status)
        assert seen_ids == {job_id}
