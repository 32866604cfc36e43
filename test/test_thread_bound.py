"""Threads over topics against the independent Z-only lower bound (issue 25).

cnc-run runs each job through the planner and bridge nodes and records the bag; the bag
alone is judged by readers that import nothing of this project: test/z_only_bound.py (the
cycle, first to last x/z motion on feedback, and the bound from the job document and the
machine's Z limits) and test/thread_reader.py (chips and helix on feedback).

Both M12x1.75 and M16x2 met the issue's 1.10 (bench/thread_bound.py: 1.08x and 1.07x) while
max_jerk bound the commands. Since it binds the feedback (issue 41: the lathe's axes plan at
max_jerk / 1.16, motion/derating.py), the bound, which moves Z at the full max_jerk, is
1.11x away on M12x1.75: the ratio allowed is 1.12.
"""
from __future__ import annotations

import os

import pytest

from cnc_msgs_py.discovery import dds_environment
from support import JOBS, cnc, domain_range
from z_only_bound import cycle_time, z_only_bound
from thread_reader import judge, read_bag

ISSUE_RATIO = 1.12  # 1.10 with max_jerk on the commands (issue 25); see above
JOBS_RUN = ("thread_m12.yaml", "thread_m16.yaml")
CHIP_REVS = 1.0


@pytest.fixture(scope="module", params=JOBS_RUN)
def recorded(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("thread_bound")
    domains = domain_range()  # module scope: conftest's DDS fixture does not reach here
    with pytest.MonkeyPatch.context() as env:
        for key, value in dds_environment(os.environ, domains[(os.getpid() + JOBS_RUN.index(request.param)) % len(domains)]).items():
            env.setenv(key, value)
        result = cnc("cnc-run", JOBS / request.param, "--out", out)
    assert result.returncode == 0, result.stderr[-3000:]
    return request.param, read_bag(out / "bag")


def test_thread_within_its_ratio_of_the_z_only_bound_with_chips_broken(recorded):
    name, (job, t, x, z, spindle) = recorded
    bound = z_only_bound(job)
    cycle = cycle_time(t, x, z)
    assert cycle <= ISSUE_RATIO * bound["bound_s"], (name, cycle, bound)
    thread = judge(job, t, x, z, spindle)
    assert thread["synchronised_passes"] == bound["passes"] and thread["full_depth"]
    assert thread["helix_residual_mm"] < 0.01
    for p in thread["passes"]:
        if p["cutting"]:
            assert p["max_chip_revs"] <= CHIP_REVS, (name, p)


def test_the_bound_adds_up():
    """M16x2 at 500 rpm: 9 strokes of 24 mm at 2 mm x 500/60 s = 16.67 mm/s are 12.96 s;
    each Z-only move costs more than its rest-to-rest distance at full acceleration alone."""
    job = {"machine": "lathe", "spindle_rpm": 500,
           "thread": {"start_z": 4.0, "end_z": -24.0, "pitch": 2.0, "passes": 8, "spring_passes": 1}}
    bound = z_only_bound(job)
    assert bound["passes"] == 9
    assert bound["stroke_s"] == pytest.approx(24.0 / (2.0 * 500 / 60.0))
    assert bound["return_s"] > 2 * (24e-3 / 9.8) ** 0.5  # bang-bang at 9.8 m/s^2 over 24 mm
    assert bound["bound_s"] == pytest.approx(bound["approach_s"] + 9 * bound["stroke_s"]
                                             + 8 * bound["return_s"] + bound["final_s"])
