"""``vibration: auto``: the planner's choice of waveform, its record, and refusals that name
what works (cnc_planner.vibration.auto)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.job import load_job_file, parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job
from cnc_planner.report import build_report, predicted_run
from cnc_planner.vibration.auto import choose_vibration, feasible
from cnc_servo_bridge.drive import DriveModel

JOBS = Path(__file__).resolve().parents[3] / "config" / "jobs"
F = 1e-4  # 0.1 mm/rev


def rad_s(rpm: float) -> float:
    return rpm * 2 * math.pi / 60


def chosen(plan) -> list[dict]:
    return [e.data["vibration"] for e in plan.events if e.name == "vibration_feed"]


def test_auto_on_lathe_soft_breaks_every_chip_within_its_window():
    """The example vibration move with ``vibration: auto`` on lathe_soft (60 % velocity
    feed-forward, kp 25/s): on the drive model's feedback every chip of the feed, the one
    that ends resting at the stop included, is no longer than the chosen waveform's window,
    and the events record the choice and the chip it predicted."""
    machine = load_machine("lathe_soft")
    doc = {**load_job_file(JOBS / "lathe_feed_vibration.yaml"), "machine": "lathe_soft", "vibration": "auto"}
    plan = plan_job(parse_job(doc), machine, machine.home_joints)
    [choice] = chosen(plan)
    assert choice["auto"] and choice["window_revs"] >= 1
    aircut = build_report(predicted_run(doc, plan, machine), machine)["aircut"]["feedback"]
    assert aircut["revolutions"] >= 100 and aircut["revolutions_with_aircut"] == aircut["revolutions"]
    assert aircut["max_chip_revs"] <= choice["window_revs"]
    # predicted on the commanded spindle angle, judged on its feedback
    assert aircut["max_chip_revs"] == pytest.approx(choice["predicted_chip_revs"], abs=0.02)


def test_explicit_d_1_5_on_lathe_soft_breaks_every_chip_within_one_revolution():
    """The example move (D 1.5 Q 1.2) on lathe_soft: its command settles 0.13 s (1.3
    revolutions) after the tool arrives; resting there cut the ring the last revolution left
    (one 1.19-revolution chip). The feed now ends on arrival and the x retract leaves at
    once, carrying nothing: z holds with its settling (the same z command as before)."""
    machine = load_machine("lathe_soft")
    doc = {**load_job_file(JOBS / "lathe_feed_vibration.yaml"), "machine": "lathe_soft"}
    plan = plan_job(parse_job(doc), machine, machine.home_joints)
    aircut = build_report(predicted_run(doc, plan, machine), machine)["aircut"]["feedback"]
    assert aircut["revolutions"] >= 100 and aircut["revolutions_with_aircut"] == aircut["revolutions"]
    assert aircut["max_chip_revs"] <= 1.0
    end = next(e.time for e in plan.events if e.name == "vibration_end")
    retract = next(e.time for e in plan.events if e.name == "rapid" and e.time > end - 1e-9)
    assert retract == pytest.approx(end)  # the retract leaves on arrival
    t = np.arange(round(end * 1000), round((end + 0.2) * 1000)) * 1e-3
    z = plan.sample(t)[0][:, machine.joint_names.index("z")]
    assert np.ptp(z) > 1e-7  # z still settles under the retract: a hold carrying the correction


def test_auto_keeps_d_1_5_where_the_axis_follows_it_and_explicit_parameters_stay():
    machine = load_machine("lathe")
    doc = load_job_file(JOBS / "lathe_feed_vibration.yaml")
    start = machine.home_joints
    [auto] = chosen(plan_job(parse_job({**doc, "vibration": "auto"}), machine, start))
    assert (auto["D"], auto["Q"], auto["window_revs"]) == (1.5, 1.2, 1.0)
    [given] = chosen(plan_job(parse_job(doc), machine, start))
    assert given == {"auto": False, "D": 1.5, "Q": 1.2}


def test_a_fast_drill_spindle_gets_a_vibration_every_few_revolutions():
    """mill3's Z (jerk 200 m/s^3) follows D 1.5 up to ~950 rpm; at 3000 rpm auto picks one
    vibration every E revolutions, the shortest E whose predicted feedback breaks the chip."""
    z = load_machine("mill3").axes["z"]
    drive = lambda: DriveModel(load_machine("mill3"), 1e-3, ("z",))  # noqa: E731
    slow, chip = choose_vibration(F, rad_s(600), z, drive, 1e-3)
    assert slow.vibration.D == 1.5 and chip <= 1.0
    fast, chip = choose_vibration(F, rad_s(3000), z, drive, 1e-3, rests=False)
    assert fast.vibration.D is None and fast.vibration.E == fast.window == 3 and chip <= 3
    assert [c.window for c in feasible(F, rad_s(3000), z)][0] == 3  # D 1.5 and E 2 are too fast for Z


# mill3's Z plans at 200 / 1.122 = 178.3 m/s^3, so that its feedback stays within 200
# (motion/derating.py): D 1.5 up to 950 * (1 / 1.122)^(1/3) = 915 rpm, E 2 R 0.5 up to 788 rpm.
@pytest.mark.parametrize("vibration, field, names", [
    ({"D": 1.5, "Q": 1.2}, "vibration.D", ["max spindle speed 915 rpm", "works: E 3 R 1.5 Q 1.4 at 3000 rpm"]),
    ({"D": 1.5, "Q": 0.9}, "vibration.Q", ["works: D 1.5 Q 1.2 up to 915 rpm", "E 3 R 1.5 Q 1.4 at 3000 rpm"]),
    ({"D": 2, "Q": 1.2}, "vibration.D", ["D=2.5", "works: E 3 R 1.5 Q 1.4 at 3000 rpm"]),
    ({"E": 2, "R": 0.5}, "vibration.E", ["max spindle speed 788 rpm", "works: E 3 R 1.5 Q 1.4 at 3000 rpm"]),
])
def test_every_refused_vibration_names_a_parameter_set_that_works(vibration, field, names):
    doc = {**load_job_file(JOBS / "drill_deep_auto.yaml"), "vibration": vibration}
    with pytest.raises(JobError) as refused:
        plan_job(parse_job(doc), load_machine("mill3"))
    assert refused.value.field == field
    for name in names:
        assert name in refused.value.reason


@pytest.mark.parametrize("vibration, field, reason", [
    ({"auto": True}, "vibration.auto", "unknown key"),
    ("automatic", "vibration", "expected auto or a mapping"),
])
def test_auto_is_the_word_auto_and_unknown_keys_stay_refused(vibration, field, reason):
    with pytest.raises(JobError) as refused:
        parse_job({**load_job_file(JOBS / "drill_deep_auto.yaml"), "vibration": vibration})
    assert refused.value.field == field and reason in refused.value.reason


def test_a_thread_refuses_auto_by_name():
    with pytest.raises(JobError) as refused:
        parse_job({**load_job_file(JOBS / "thread_m12.yaml"), "vibration": "auto"})
    assert refused.value.field == "vibration" and "thread" in refused.value.reason
