"""Every example job kind on the shipped machine, a stiff high-jerk one and a soft-drive
one, through both nodes over topics: it succeeds, the bridge refuses no chunk and raises
no alarm, and the properties hold on the recorded feedback, hole bottoms within 5 um.

The shipped mill3 and lathe run these jobs in test_methods.py and test_path_run.py; here
their stiff and soft siblings (config/machines/*_stiff.yaml, *_soft.yaml) do.
"""
from __future__ import annotations

import json

import pytest

from cnc_msgs_py.job import load_job_file
from support import EXAMPLES, JOBS, check_verified_properties, cnc, load_report


@pytest.mark.parametrize("variant", ["stiff", "soft"])
@pytest.mark.parametrize("kind", EXAMPLES)
def test_example_job_runs_on_a_stiff_and_a_soft_machine(kind, variant, tmp_path):
    doc = load_job_file(JOBS / EXAMPLES[kind])
    doc = {**doc, "machine": f"{doc['machine']}_{variant}", "job_id": f"{doc['job_id']}-{variant}"}
    job = tmp_path / "job.json"
    job.write_text(json.dumps(doc))
    result = cnc("cnc-run", job, "--out", tmp_path / "run")
    assert result.returncode == 0, result.stderr[-3000:]
    report = load_report(tmp_path / "run")
    assert report["state"] == "succeeded", report["reason"]
    assert report["alarms"] == [] and report["chunks_lost"] == 0
    check_verified_properties(kind, report, depth_tol_mm=0.005)
