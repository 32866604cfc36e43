"""Lossless recording: every 1 kHz joint_states sample and every chunk is in the bag, and
a slow recorder holds the simulated clock back (backpressure) instead of losing samples."""
from __future__ import annotations

import json
import time

import numpy as np

from cnc_msgs_py.job import job_id_of, load_job_file
from cnc_planner.runner import Session
from cnc_analysis.summary import chunks_lost
from cnc_servo_bridge.lockstep import RECORDER_WINDOW_NS
from cnc_analysis.recording import read_run

from support import ROOT

SLOW_WRITE_S = 0.001  # a slow disk: 1 ms per feedback sample, so the recorder manages ~1x real time


def test_a_slow_recorder_holds_the_clock_and_the_bag_has_every_sample(tmp_path):
    doc = load_job_file(ROOT / "config" / "jobs" / "drill_row.yaml")
    lag = []
    with Session("mill3", tmp_path / "bag") as session:
        recorder, write = session.recorder, session.bag.write

        def slow_write(topic: str, t_ns: int, data: bytes) -> None:
            write(topic, t_ns, data)
            if topic.endswith("joint_states"):
                lag.append(recorder.sim_ns - recorder.feedback_ns)  # /clock heard - sample written
                time.sleep(SLOW_WRITE_S)  # the slow disk (fault injection, not a wait)

        session.bag.write = slow_write
        session.submit(json.dumps(doc))
        final = session.wait(job_id_of(doc), 120)
        session.settle(final)
    assert final["state"] == "succeeded"
    # The bridge's clock never ran more than the window (plus one block) ahead of the disk.
    assert max(lag) <= RECORDER_WINDOW_NS + 200_000_000
    run = read_run(tmp_path / "bag")
    steps = np.diff(np.round(run.feedback_t * 1e3).astype(np.int64))
    assert len(run.feedback_t) > 4000 and np.all(steps == 1)  # 0 missing, longest gap one period
    assert chunks_lost(run) == 0 and len(run.chunks) >= 40
