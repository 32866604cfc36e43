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


def test_every_report_section_and_figure_module_a_kind_names_is_found():
    """The registry names them as "module:function" (found only to report): a typo would
    only show when a job of that kind is reported, so each is resolved here."""
    sections = [kind.report for kind in KINDS.values() if kind.report is not None]
    assert {s.key for s in sections} == {"drill", "turn", "thread", "kinematics", "program", "surface_speed",
                                        "spindle_sync"}
    for section in sections:
        assert callable(section.judge), section.judge_at
        assert section.cards is None or callable(section.cards), section.cards_at
        assert section.tables is None or callable(section.tables), section.tables_at
    for kind in KINDS.values():
        if kind.figures is not None:
            assert callable(kind.figures.draw) and isinstance(kind.figures.captions, dict), kind.name
            assert kind.figures.aircut is None or callable(kind.figures.aircut), kind.name
