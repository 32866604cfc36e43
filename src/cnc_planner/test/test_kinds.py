"""The registry of job kinds: every kind the schema knows is planned, and what each says of itself."""
from __future__ import annotations

from pathlib import Path

import pytest

from cnc_msgs_py.job import KINDS as SCHEMA_KINDS, load_job_file, parse_job
from cnc_msgs_py.schema import JobError
from cnc_planner.kinds import KINDS, kind_of, progress_count

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"


def test_every_kind_the_schema_accepts_is_registered_under_its_name():
    assert set(KINDS) == set(SCHEMA_KINDS)
    assert all(kind.name == name for name, kind in KINDS.items())


def test_an_unknown_kind_is_refused_by_name():
    with pytest.raises(JobError, match="^kind: 'mill' jobs are not implemented"):
        kind_of("mill")


@pytest.mark.parametrize("job, count", [
    ("drill_row.yaml", {"event": "S1", "unit": "hole", "total": 5}),
    ("turn_stepped.yaml", {"event": "pass", "unit": "pass", "total": 8}),
    ("thread_m12.yaml", {"event": "thread_pass", "unit": "thread pass", "total": 7}),
    ("lathe_feed_vibration.yaml", {}),  # a move program counts nothing
    ("path_mill3.yaml", {}),
])
def test_statuses_count_what_a_machinist_counts(job, count):
    assert progress_count(parse_job(load_job_file(JOBS / job))) == count
