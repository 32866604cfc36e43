"""Every example job in config/jobs (the README points to them) validates and plans."""
from __future__ import annotations

import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_planner.planning import plan_job

from support import JOBS


@pytest.mark.parametrize("path", sorted(JOBS.glob("*.yaml")), ids=lambda p: p.stem)
def test_example_job_plans_within_travel(path):
    job = parse_job(load_job_file(path))
    machine = load_machine(job.machine)
    plan = plan_job(job, machine)
    assert plan.duration > 0
    final = plan.final_position()
    for name in machine.linear_axes:
        assert machine.axes[name].within_travel(final[name])
