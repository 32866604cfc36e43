"""The long path goals that the starvation test and `make stream-lead` plan beside a
running real-time job: a 0.5 mm zigzag on mill3. Planning one takes longer the more points
it has (one segment, however long; faster than in proportion: the zigzag retraces its
50 mm strip every 1000 points, its commanded path checked against every layer near it);
it lasts about 52 s per 1000 points at 900 mm/min."""
from __future__ import annotations

MOST_POINTS = 8000  # a path's points at most: 8000 take about 420 s, under the 600 s a path may last


def zigzag_path(job_id: str, k: int, points: int) -> dict:
    """A path goal of ``points`` points, shifted by k so that no two are alike."""
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "path", "machine": "mill3",
            "spindle_rpm": 3000, "tool": {"length": 0.0, "diameter": 6.0},
            "path": {"points": [[0.5 * (i % 2) + 0.01 * k, 0.05 * (i % 1000), -1.0] for i in range(points)],
                     "feed": 900, "chord_tolerance": 0.01}}
