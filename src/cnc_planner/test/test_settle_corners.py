"""A program's drill operation starts once the drives have settled from the rapid before it:
on every drive inside the tolerance, not only the described ones. LinuxCNC's polar.ngc
moved X/Y below R on 2 of 16 corners while only the described drives were waited for: a
slower tolerated drive was still settling when the cycle climbed to its R plane."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.plant import Plant
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.compensation import corner_plants
from cnc_planner.motion.settle import settle_time
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "bench" / "peer"))
from oracle import canonical_moves, recorded  # noqa: E402  bench/peer/oracle.py: rs274's recorded moves

MILL = load_machine("mill3")
PERIOD = 1e-3
TOL = 2e-6  # m


def _rapid(x: float) -> PlanBuilder:
    builder = PlanBuilder(MILL, MILL.home_joints)
    builder.rapid({"x": x, "y": 0.4 * x})
    return builder


@pytest.mark.parametrize("x", [0.002, 0.08])
def test_after_the_settle_every_tolerated_drive_holds_the_tip_within_tol(x):
    """Each corner simulated on its own, over the whole plan from the start (the settle
    simulates only LEAD_S before the rest): within ``tol`` from then on, and not a period
    sooner for every one of them."""
    builder = _rapid(x)
    t0 = builder.end_time()
    settle = settle_time(builder, Kinematics(MILL), t0, TOL, PERIOD)
    joints = ["x", "y", "z"]
    t = np.arange(int(np.ceil((t0 + 2.0) / PERIOD)) + 1) * PERIOD
    p, v, a = (np.stack(q, axis=1) for q in zip(*[builder.timelines[j].sample(t) for j in joints]))
    last = []
    for plant in corner_plants(MILL, joints):
        feedback, _ = DriveModel(MILL, PERIOD, tuple(joints), drives={**MILL.drives, **plant}).simulate(p, v, a)
        far = np.flatnonzero((np.linalg.norm(feedback - p, axis=1) > TOL) & (t >= t0))
        last.append(t[far[-1]] + PERIOD - t0 if len(far) else 0.0)
    assert len(last) == 17 and settle == pytest.approx(max(last), abs=1e-9)
    assert settle > last[0]  # the described drives alone settle sooner


PROGRAM = Path(__file__).resolve().parents[3] / "test" / "gcode_oracle" / "drill_after_rapids.ngc"
RS274 = Path(__file__).resolve().parents[3] / "bench" / "results" / "rs274_examples.json"


def test_a_program_drills_after_a_rapid_on_every_tolerance_corner():
    """Rapids at Z0, below the R plane: each cycle climbs to R as X/Y settle (as polar.ngc's).
    Its holes are where LinuxCNC drills them (rs274 -g, recorded by bench/peer/examples.py)."""
    doc = job_document(PROGRAM)
    job = parse_job(doc)
    lc_bottoms = [m.end for m in canonical_moves(recorded(RS274)(PROGRAM.read_text()))[0] if m.kind == "feed"]
    bottoms = [(x, y, d["surface_z"] - d["depth"]) for _, op, part in job.program.operations if op.kind == "drill"
               for d in [part["drill"]] for x, y in d["holes"]]  # mm, as the program's document gives them
    assert len(bottoms) == 3 and np.allclose(bottoms, lc_bottoms, atol=1e-3)
    plan = plan_job(job, MILL, MILL.home_joints)
    failed = []
    for k, plant in enumerate(corner_plants(MILL, ["x", "y", "z"])):
        report = build_report(predicted_run(doc, plan, MILL, plant=Plant(f"corner {k}", {**MILL.drives, **plant})), MILL)
        verdicts = [op["drill"]["verdict"] for op in report["program"]["operations"] if "drill" in op]
        assert len(verdicts) == 3
        failed += [f"corner {k}: {v['says']}" for v in verdicts if not v["passed"]]
    assert failed == []
