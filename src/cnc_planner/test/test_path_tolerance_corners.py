"""A G64 P path on drives that are not their description: planned once on the described mill,
its tip judged (build_report on predicted_run, the report's own judge) on the predicted
feedback of every corner of the drives' tolerance stays within P, as bench/program_corners.py
judges the oracle programs. The planner softens the stops' jerk for it (kinds.path.corners),
not the feed, and at a small price in time."""
from __future__ import annotations

import functools
from dataclasses import dataclass
import tempfile
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import exactly_as_described, load_machine
from cnc_msgs_py.plant import Plant, tolerance_corners
from cnc_planner.kinds.path.corners import JERK_SLOPE, MIN_JERK_SHARE, TOLERANCE_SHARE, next_jerk_share, soften
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run

MILL = load_machine("mill3")
JOINTS = ("x", "y", "z")
P = 0.02  # mm
# A pocket corner, an arc and a short line at 1200 mm/min: on the described drives the tip
# holds P; at 3 ms velocity loop and 0.7x gain the stops overshoot it unless softened.
PROGRAM = f"""(CNC,MACHINE mill3)
G21 G90 G17 G94
T1 M6 G43
S3000 M3
G0 X0 Y0 Z5
G1 Z-1 F300
G64 P{P}
G1 X12 F1200
G1 Y6
G3 X6 Y12 R6
G1 X0
G0 Z5
M5
M2
"""


@functools.cache
def planned(described_only: bool):
    """(doc, machine planned on, plan) of PROGRAM; ``described_only`` closes the tolerance."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "path_tolerance_corners.ngc"
        path.write_text(PROGRAM)
        doc = job_document(path)
    machine = exactly_as_described(MILL) if described_only else MILL
    return doc, machine, plan_job(parse_job(doc), machine)


def corner_plants() -> list[Plant]:
    """The described drives with the k-th tolerance corner of every axis together."""
    each = [tolerance_corners(MILL.drives[j]) for j in JOINTS]
    return [Plant(f"corner {k}", {**MILL.drives, **{j: c[k] for j, c in zip(JOINTS, each)}})
            for k in range(len(each[0]))]


def judged(described_only: bool, plant: Plant) -> dict:
    """The path operation's kinematics section, judged on the plant's predicted feedback."""
    doc, machine, plan = planned(described_only)
    report = build_report(predicted_run(doc, plan, machine, plant=plant), machine)
    (path,) = [op["kinematics"] for op in report["program"]["operations"] if "kinematics" in op]
    return path


def test_every_tolerance_corner_holds_p_on_its_predicted_feedback():
    tips = []
    for plant in corner_plants():
        path = judged(False, plant)
        assert path["verdict"]["passed"], (plant.name, path["verdict"])
        tips.append(path["max_tip_deviation_mm"])
    assert max(tips) <= TOLERANCE_SHARE * P + 1e-4  # the margin kept, within a count of the encoders
    _, _, plan = planned(False)
    (start,) = [e for e in plan.events if e.name == "path_start"]
    assert start.data["corner_tip_deviation"] * 1e3 == pytest.approx(max(tips), abs=2e-4)  # the plan predicted it


def test_the_plan_that_trusts_the_description_misses_p_on_a_corner():
    """Without the corners' check (tolerance closed) the same path leaves P on a slow corner:
    the test above tests the planner's margin, not an easy path."""
    misses = [judged(True, plant)["max_tip_deviation_mm"] for plant in corner_plants()]
    assert max(misses) > P, misses


def test_the_price_is_softer_stops_not_a_lower_feed():
    _, _, tolerant = planned(False)
    _, _, trusting = planned(True)
    start, = [e for e in tolerant.events if e.name == "path_start"]
    assert start.data["planned_feed"] == pytest.approx(start.data["feed"])
    assert MIN_JERK_SHARE <= start.data["jerk_share"] < 1.0
    (trusting_start,) = [e for e in trusting.events if e.name == "path_start"]
    assert trusting_start.data["jerk_share"] == 1.0
    assert tolerant.duration < 1.1 * trusting.duration, (tolerant.duration, trusting.duration)


def test_the_jerk_share_steps_towards_the_target_by_secant():
    assert next_jerk_share([(1.0, 0.032)], 0.018) == pytest.approx(np.exp(np.log(0.018 / 0.032) / JERK_SLOPE))
    # two tries measure the slope: halving the share took 0.03 to 0.02, so 0.0133 needs another half
    assert next_jerk_share([(1.0, 0.03), (0.5, 0.02)], 0.02 / 1.5) == pytest.approx(0.25)
    assert next_jerk_share([(0.02, 0.05)], 0.001) == MIN_JERK_SHARE  # never below the floor


@dataclass
class Synthetic:
    """A plan whose stretches' worst tips follow a law of their jerk and speed shares each."""

    jerk_shares: np.ndarray
    speed_shares: np.ndarray
    stretch_deviations: np.ndarray


def test_each_stretch_is_softened_on_its_own_and_only_where_it_helps():
    """Stop overshoots falling with the jerk share (as on mill3: 0.032 mm at 1, 0.021 at 0.1,
    0.011 at 0.03), a stretch that holds as it is, and an arc at speed whose miss the jerk
    does not change but the square of the speed does: the stops hold near the target at
    full speed, the third stretch keeps its shares, the arc is back at its full jerk and
    runs slower, alone."""
    laws = [lambda j, v: 0.0323 * j ** 0.27, lambda j, v: 0.025 * j ** 0.4, lambda j, v: 0.01 + 0 * j,
            lambda j, v: 0.0346 * v ** 2]
    target = 0.018

    def attempt(jerks: np.ndarray, speeds: np.ndarray) -> Synthetic:
        return Synthetic(jerks, speeds, np.array([law(j, v) for law, j, v in zip(laws, jerks, speeds)]))

    done = soften(attempt, attempt(np.ones(4), np.ones(4)), target)
    tips = done.stretch_deviations
    assert np.all(tips <= target) and np.all(tips[:2] >= 0.8 * target), tips
    assert done.jerk_shares[2] == done.jerk_shares[3] == 1.0
    assert MIN_JERK_SHARE < done.jerk_shares[0] < done.jerk_shares[1] < 1.0
    assert list(done.speed_shares[:3]) == [1.0, 1.0, 1.0] and 0.5 < done.speed_shares[3] <= np.sqrt(target / 0.0346)

