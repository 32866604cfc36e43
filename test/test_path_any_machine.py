"""5-axis paths on any 5-axis machine a user describes: refused up front with a reason,
or planned so that the tool tip on the drive model's predicted feedback stays within the
job's chord tolerance (judged by the report code that judges recordings).

Machine descriptions are drawn over the ranges users write (as test_any_machine draws
them): for every positioning axis, linear and rotary, max_jerk 50 to 1e6, kp 10-150 /s,
velocity and acceleration feed-forward 0-1, velocity lag 0.2-10 ms, encoder resolution
1e-8 to 1e-5 (m or rad), following error limit 1-20 mm (or mrad); the pivot off centre by up
to 50 mm; the job's feed 200-3000 mm/min. Both shipped 5-axis path jobs, one per layout. Each drawn
machine is trusted as described (its tolerance closed): what holds on the corners of a
tolerance is test_path_tolerance_corners' and bench/program_corners.py's to show, and
planning every corner of six drawn machines per layout took 58 s of the suite.
"""
from __future__ import annotations

import dataclasses

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import KinematicParams, Machine, exactly_as_described, load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import INTERNAL, plan_job
from cnc_planner.report import build_report, predicted_run
from support import JOBS, machines

PATHS = {"5ax_table_table": "path_5ax_table_table.yaml", "5ax_head_table": "path_5ax_head_table.yaml"}


@st.composite
def five_axis_machines(draw, base: Machine) -> Machine:
    """The base 5-axis machine with every positioning axis's jerk and drive, and the
    pivot, drawn anew."""
    machine = draw(machines(base))
    offset = draw(st.tuples(*[st.floats(-0.05, 0.05)] * 3))
    pivot = tuple(p + o for p, o in zip(base.kinematics.pivot, offset))
    kinematics = KinematicParams(pivot=pivot, pivot_length=base.kinematics.pivot_length)
    return exactly_as_described(dataclasses.replace(machine, kinematics=kinematics))


@pytest.mark.parametrize("layout", PATHS)
def test_5_axis_paths_are_refused_up_front_or_within_tolerance_on_predicted_feedback(layout):
    base = load_machine(layout)
    outcomes = []

    @settings(max_examples=6, deadline=None, derandomize=True, database=None, phases=(Phase.generate,),
              suppress_health_check=[HealthCheck.too_slow])
    @given(five_axis_machines(base), st.floats(200.0, 3000.0))
    def run(machine: Machine, feed: float) -> None:
        doc = load_job_file(JOBS / PATHS[layout])
        doc = {**doc, "machine": machine.name, "path": {**doc["path"], "feed": feed}}
        job = parse_job(doc)
        try:
            plan = plan_job(job, machine, machine.home_joints)
        except JobError as err:
            assert err.field and err.reason and INTERNAL not in err.reason, str(err)
            outcomes.append(f"refused: {err}")
            return
        kin = build_report(predicted_run(doc, plan, machine), machine)["kinematics"]
        assert kin["completed"]
        assert kin["max_tip_deviation_mm"] <= kin["chord_tolerance_mm"], kin
        assert kin["within_tolerance"] and kin["verdict"]["passed"]
        outcomes.append("within tolerance")

    run()
    assert "within tolerance" in outcomes, outcomes  # never vacuous
