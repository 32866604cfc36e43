"""Load over real topics: 100 small jobs queued back to back in one session.

All must end `succeeded`, in submission order, and the recording must show an unbroken
setpoint stream: no chunk lost, duplicated or overlapping, each job's chunks contiguous
on the interpolation grid from its job_start to its job_end.
"""
from __future__ import annotations

import json

from cnc_planner.runner import Session
from cnc_analysis.summary import chunks_lost
from cnc_analysis.recording import read_run

JOBS = 100
PERIOD_NS = 1_000_000  # the executive's interpolation period
IN_FLIGHT = 5  # goals submitted but not yet acknowledged ('accepted'): job_goal is
# reliable with depth 10 (docs/interfaces.md), so a burst of more goals than that while the planner is
# busy planning loses the oldest ones; a cell controller keeps fewer in flight.


def job_text(job_id: str, x: float) -> str:
    doc = {"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3",
           "move": [{"rapid": {"x": x}}, {"rapid": {"x": 0}}]}
    return json.dumps(doc)


def test_hundred_jobs_back_to_back_finish_in_order_without_gaps(tmp_path):
    ids = [f"load{k:03d}" for k in range(JOBS)]
    with Session("mill3", tmp_path / "bag") as session:
        def acknowledged() -> int:
            return sum(s["state"] == "accepted" for s in session.recorder.statuses)

        for k, job_id in enumerate(ids):
            session.spin_until(lambda: k - acknowledged() < IN_FLIGHT, 30, f"{job_id} not accepted")
            session.submit(job_text(job_id, 1.0 + (k % 5)))  # 1..5 mm out and back
        # All submitted long before the first jobs have run: they wait in the planner's queue.
        assert session.final_status(ids[JOBS // 2]) is None
        for job_id in ids:
            assert session.wait(job_id, 60)["state"] == "succeeded", job_id
        session.settle(session.final_status(ids[-1]))
    run = read_run(tmp_path / "bag")

    finals = [s for s in run.statuses if s["state"] in ("succeeded", "canceled", "aborted", "rejected")]
    assert [s["job_id"] for s in finals] == ids
    assert all(s["state"] == "succeeded" for s in finals)
    assert [s["job_id"] for s in run.statuses if s["state"] == "accepted"] == ids

    assert chunks_lost(run) == 0
    # Globally: stamps strictly increasing, no chunk overlapping the one before (a
    # duplicate would repeat a stamp, an overlap start before the previous end).
    for prev, nxt in zip(run.chunks, run.chunks[1:]):
        assert nxt.stamp_ns > prev.end_ns, (prev, nxt)

    # Per job: the chunks between its job_start and job_end events tile it exactly.
    marks = {(e["job_id"], e["name"]): e["stamp_ns"] for e in run.events if e["name"] in ("job_start", "job_end")}
    assigned = 0
    for job_id in ids:
        start, end = marks[(job_id, "job_start")], marks[(job_id, "job_end")]
        mine = [c for c in run.chunks if start <= c.stamp_ns <= end]
        assert mine, job_id
        assert mine[0].stamp_ns == start, job_id
        for prev, nxt in zip(mine, mine[1:]):
            assert nxt.stamp_ns == prev.end_ns + PERIOD_NS, (job_id, prev, nxt)
        assert mine[-1].end_ns >= end - PERIOD_NS and not mine[-1].moving_at_end, job_id
        assigned += len(mine)
    assert assigned == len(run.chunks)  # no chunk outside a job (none sent twice or stray)
