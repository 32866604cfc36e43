"""Every example job kind on the shipped machine, a stiff high-jerk one and a soft-drive
one, through both nodes over topics: it succeeds, the bridge refuses no chunk and raises
no alarm, and the properties hold on the recorded feedback, hole bottoms within 5 um.

The shipped mill3 and lathe run the drill, vibration, turn and thread examples in
test_methods.py; here the path example runs on mill3, and every example on their stiff
and soft siblings (config/machines/*_stiff.yaml, *_soft.yaml).
"""
from __future__ import annotations

import json

import pytest

from cnc_msgs_py.job import load_job_file
from support import EXAMPLES, JOBS, check_verified_properties, cnc, load_report


RUNS = [(kind, variant) for variant in ("_stiff", "_soft") for kind in EXAMPLES] + [("path", "")]


@pytest.mark.parametrize(("kind", "variant"), RUNS, ids=[f"{k}{v}" for k, v in RUNS])
def test_example_job_runs_on_the_shipped_stiff_and_soft_machines(kind, variant, tmp_path):
    doc = load_job_file(JOBS / EXAMPLES[kind])
    doc = {**doc, "machine": f"{doc['machine']}{variant}", "job_id": f"{doc['job_id']}{variant}"}
    job = tmp_path / "job.json"
    job.write_text(json.dumps(doc))
    result = cnc("cnc-run", job, "--out", tmp_path / "run")
    assert result.returncode == 0, result.stderr[-3000:]
    report = load_report(tmp_path / "run")
    assert report["state"] == "succeeded", report["reason"]
    assert report["alarms"] == [] and report["chunks_lost"] == 0
    check_verified_properties(kind, report, depth_tol_mm=0.005)
