"""Constant surface speed (G96 D S / G97, issue 42): the front end's modal spindle speed mode
and its refusals, the job schema's ``surface_speed``, the planner's spindle along X and the
judge's reading of it (cnc_analysis.surface_speed). The program over topics, judged on its
feedback, is in test_gcode_over_topics.py."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from cnc_analysis.surface_speed import judge_surface_speed
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.executive import Executive
from cnc_planner.kinematics import Kinematics
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
PROGRAM = ROOT / "test" / "programs" / "lathe_css_g96_g76.ngc"
HEAD = "G21 G18 G7 G90 G95\n"


def _program(text: str, machine: str = "lathe") -> dict:
    return {"schema": "cnc_job/1", "job_id": "css", "kind": "program", "machine": machine, "program": {"gcode": text}}


def _refused(text: str, machine: str = "lathe") -> str:
    with pytest.raises(JobError) as err:
        parse_job(_program(text, machine))
    return str(err.value)


def test_g96_roughs_at_a_surface_speed_and_g97_threads_at_one_rpm():
    """The must-show program: the rapid and the G71 at 120 m/min capped at D3000, no rpm of
    their own; the G76 and the moves after G97 at S600."""
    ops = parse_job(job_document(PROGRAM)).program.operations
    assert [(line, op.kind) for line, op, _ in ops] == [(8, "move"), (17, "turn"), (20, "move"), (21, "thread"),
                                                      (22, "move")]
    for _, _, doc in ops[:2]:
        assert doc["surface_speed"] == {"m_min": 120.0, "max_rpm": 3000.0} and "spindle_rpm" not in doc
    assert ops[1][2]["turn"]["feed"] == pytest.approx(0.15)  # G95: per revolution, at the actual speed
    assert [doc.get("spindle_rpm") for _, _, doc in ops[2:]] == [600.0] * 3
    assert all("surface_speed" not in doc for _, _, doc in ops[2:])


def test_a_surface_speed_in_feet_per_minute_is_converted_once():
    """Under G20 S is ft/min: 500 ft/min = 152.4 m/min; without D the spindle's limit caps."""
    text = ("G20 G18 G7 G90 G95\nG96 S500 M3\nG0 X0.9 Z0.2\nF0.006\no100 sub\nG1 X0.4 Z0.2\nG1 Z-0.5\no100 endsub\n"
            "G71 Q100 X0.8 Z0.2 D0.004 I0.04 R0.02\nM2\n")
    ops = parse_job(_program(text)).program.operations
    turn = next(doc for _, op, doc in ops if op.kind == "turn")
    assert turn["surface_speed"] == {"m_min": pytest.approx(152.4)}


@pytest.mark.parametrize("text,reason", [
    (HEAD + "G96 D2000 S150 M3\nG0 X14 Z4\nG76 P1.75 Z-14 I-2 J0.8738 R2 K2.14 Q29.5 H1 E0 L0\nM2",
     "line 4: G76: a thread turns at one rpm (its lead is locked to the spindle angle): G97 S.. before it"),
    (HEAD + "G96 D2000 S150 M3\nG0 X22 Z7\nF0.15\n(CNC,VIBRATION D=1.5 Q=1.2)\n"
            "G71 Q100 X20 Z5 D0.2 I1.5 R0.5\nM2\no100 sub\nG1 X10 Z5\nG1 Z-10\no100 endsub",
     "line 6: G71: (CNC,VIBRATION) is locked to one spindle speed"),
    ("G21 G18 G7 G90 G94\nG96 D2000 S150 M3\nG0 X22 Z7\nF200\nG71 Q100 X20 Z5 D0.2 I1.5 R0.5\nM2\n"
     "o100 sub\nG1 X10 Z5\nG1 Z-10\no100 endsub",
     "line 5: G71: at constant surface speed the feed is per revolution (G95)"),
    (HEAD + "G96 D2000 S150 M3\nG0 X22 Z7\n(CNC,VIBRATION D=1.5 Q=1.2)\nG1 X18 F0.1\nM2",
     "line 5: G1: (CNC,VIBRATION) is locked to one spindle speed"),
    (HEAD + "G96 D-5 S150 M3\nM2", "line 2: D-5: the maximum rpm must be >= 0"),
    (HEAD + "G96 D2000 M3\nM2", "line 2: G96: needs S, the surface speed"),
    (HEAD + "M3 S500\nG0 X22 Z7\nF0.15\nG96 G71 Q100 X20 Z5 D0.2 I1.5 R0.5\nM2\no100 sub\nG1 X10 Z5\no100 endsub",
     "line 5: G96: give G96 D.. S.. on a line of its own: D is also G71's word here"),
    # G95 with the spindle standing, at a surface speed and at an rpm (S0): one message
    (HEAD + "G96 D2000 S150\nG0 X21 Z0\nG1 X10 F0.1\nM2", "line 4: G1: G95 feeds per revolution need the spindle "
                                                           "on: give S and M3 before it"),
    (HEAD + "S0 M3\nG0 X21 Z0\nG1 X10 F0.1\nM2", "line 4: G1: G95 feeds per revolution need the spindle on: "
                                                 "give S and M3 before it"),
    (HEAD + "G96 D2000 S150 M3\nG0 X21 Z0\nG1 X10\nM2", "line 4: G1: no feed given (F)"),
])
def test_what_cannot_turn_at_a_surface_speed_is_refused_at_its_word(text, reason):
    assert _refused(text).startswith(reason)


def test_a_face_cut_under_g96_feeds_per_revolution_of_the_changing_speed():
    """G96 then G1 facing past the axis, in G95 and in G94: one move operation at the surface
    speed, its feed per revolution (G95) or per minute (G94) as written; it plans."""
    for mode, key in (("G95", "feed_per_rev"), ("G94", "feed")):
        text = (f"G21 G18 G8 G90 {mode}\nG96 D3000 S150 M3\nG0 X21 Z0\nG1 X-0.4 F{0.1 if mode == 'G95' else 200}\n"
                "G0 Z2\nM5\nM2\n")
        ops = parse_job(_program(text)).program.operations
        (_, op, doc), = ops
        assert doc["surface_speed"] == {"m_min": 150.0, "max_rpm": 3000.0}
        assert doc["move"][1] == {"linear": {"x": -0.4, "z": 0.0}, key: 0.1 if key == "feed_per_rev" else 200.0}
        assert plan_job(parse_job(_program(text)), load_machine("lathe"), {"x": 0.03, "z": 0.01}).duration > 5.0


def test_a_nose_radius_compensated_contour_turns_at_the_surface_speed():
    """G42.1 under G96: the compensated moves keep their feed per revolution (G95) and the
    operation its surface speed; it plans."""
    text = (HEAD + "G96 D3000 S150 M3\nG0 X26 Z5\nG42.1 D0.8\nG1 X20 Z2 F0.1\nG1 Z-10\nG1 X30\nG40\nG0 X40 Z5\n"
            "M5\nM2\n")
    job = parse_job(_program(text))
    (_, op, doc), = job.program.operations
    assert doc["surface_speed"] == {"m_min": 150.0, "max_rpm": 3000.0}
    feeds = [m for m in doc["move"] if "linear" in m]
    assert len(feeds) >= 3 and all(m.get("feed_per_rev") == 0.1 and "feed" not in m for m in feeds)
    assert plan_job(job, load_machine("lathe"), {"x": 0.03, "z": 0.01}).duration > 1.0


def test_g96_on_a_mill_names_the_machine():
    assert _refused("G21 G90\nG96 S100 M3\nG0 X1\nM2", "mill3").startswith(
        "line 2: G96: constant surface speed needs a lathe (the speed follows the tool's radius, x): mill3 is a mill3")


def _turn_doc(**spindle) -> dict:
    doc = yaml.safe_load((ROOT / "config" / "jobs" / "turn_cone.yaml").read_text())
    doc.pop("spindle_rpm", None)
    return {**doc, **spindle}


@pytest.mark.parametrize("change,reason", [
    ({"surface_speed": {"m_min": 150}, "spindle_rpm": 1000}, "spindle_rpm: give spindle_rpm or surface_speed"),
    ({"surface_speed": {"m_min": 0}}, "surface_speed.m_min: must be > 0 m/min"),
    ({"surface_speed": {"m_min": 150, "max_rpm": 0.5}}, "surface_speed.max_rpm: must be >= 1 rpm"),
    ({"surface_speed": {"m_min": 150, "rpm": 5}}, "surface_speed.rpm: unknown key"),
    ({"surface_speed": {"m_min": 150}, "vibration": {"D": 1.5, "Q": 1.2}}, "vibration: a vibration is locked to one"),
    ({}, "spindle_rpm: must be > 0 for a turn job"),
])
def test_bad_surface_speeds_are_refused_by_field(change, reason):
    with pytest.raises(JobError) as err:
        parse_job(_turn_doc(**change))
    assert str(err.value).startswith(reason)


def test_a_thread_job_and_a_mill_refuse_a_surface_speed_and_move_nothing():
    doc = yaml.safe_load((ROOT / "config" / "jobs" / "thread_m12.yaml").read_text())
    doc.pop("spindle_rpm")
    with pytest.raises(JobError, match=r"^surface_speed: not used by a thread job: a thread turns at one rpm"):
        parse_job({**doc, "surface_speed": {"m_min": 100}})
    executive = Executive(load_machine("mill3"))
    move = {"schema": "cnc_job/1", "job_id": "css-mill", "kind": "move", "machine": "mill3",
            "surface_speed": {"m_min": 100}, "move": [{"rapid": {"x": 10}}]}
    status = executive.submit(json.dumps(move))  # refused before any setpoint
    assert status.state == "rejected" and status.reason.startswith("surface_speed: needs a lathe"), status.reason


FACE = {"schema": "cnc_job/1", "job_id": "face", "kind": "move", "machine": "lathe",
        "surface_speed": {"m_min": 150, "max_rpm": 3000},
        "move": [{"rapid": {"x": 21, "z": 0}}, {"linear": {"x": -0.4}, "feed_per_rev": 0.1}, {"rapid": {"z": 2}}]}


def test_a_face_cut_past_the_axis_follows_the_radius_down_to_the_cap():
    """A move job facing from a radius of 21 mm to 0.4 mm past the axis at 0.1 mm/rev: the
    planned spindle holds 150 m/min within 1 % until 3000 rpm caps it (below 8 mm), the feed
    per revolution of the speed it has throughout (else the judge finds no cut)."""
    machine = load_machine("lathe")
    job = parse_job(FACE)
    plan = plan_job(job, machine, {"x": 0.03, "z": 0.01})
    t = np.arange(0.0, plan.duration, 1e-3)
    p, v, _ = plan.sample(t)
    x, z, s = (plan.joints.index(j) for j in ("x", "z", "spindle"))
    figures = judge_surface_speed(t, p[:, x], np.hypot(v[:, x], v[:, z]), v[:, s], job.surface_speed.m_min,
                                  job.surface_speed.max_rpm, (0.1e-3,))
    assert figures["failures"] == [] and figures["max_deviation_pct"] <= 1.0 + 1e-6
    assert figures["held_s"] > 4.0 and figures["capped_s"] > 1.5 and figures["max_rpm"] <= 2970.0 + 1e-6


@pytest.mark.parametrize("move,field,reason", [
    ({"linear": {"x": 1}, "feed": 60, "feed_per_rev": 0.1}, "move[0].feed", "give feed or feed_per_rev, not both"),
    ({"rapid": {"x": 1}, "feed_per_rev": 0.1}, "move[0].feed_per_rev", "only a linear move takes a feed"),
    ({"linear": {"x": 1}, "feed_per_rev": 0.0001}, "move[0].feed_per_rev", "must be >= 0.001 mm/rev"),
])
def test_bad_move_feeds_are_refused_by_field(move, field, reason):
    with pytest.raises(JobError) as err:
        parse_job({**FACE, "move": [move]})
    assert err.value.field == field and reason in err.value.reason
    with pytest.raises(JobError, match=r"^move\[0\]\.feed_per_rev: a feed per revolution needs the spindle turning"):
        parse_job({**FACE, "surface_speed": None, "move": [{"linear": {"x": 1}, "feed_per_rev": 0.1}]})


def planned_surface_speed(job, op, feeds_per_rev: tuple[float, ...]) -> tuple[np.ndarray, dict]:
    """The job planned on the lathe from X30 Z10 and sampled every ms: the spindle's
    acceleration and the surface speed judged on the command where operation ``op`` (the
    job itself, or one of its program's) feeds."""
    machine = load_machine("lathe")
    plan = plan_job(job, machine, {"x": 0.03, "z": 0.01})
    t = np.arange(0.0, plan.duration, 1e-3)
    p, v, a = plan.sample(t)
    x, z, s = (plan.joints.index(j) for j in ("x", "z", "spindle"))
    radius, _ = Kinematics(machine, op.setup, op.tool).tip_radius_z(p[:, x], p[:, z])
    return a[:, s], judge_surface_speed(t, radius, np.hypot(v[:, x], v[:, z]), v[:, s], op.surface_speed.m_min,
                                  op.surface_speed.max_rpm, feeds_per_rev)


def test_g70_finishes_at_the_surface_speed():
    """G70 under G96 (G95): its finishing passes are feed moves of one operation at the surface
    speed, each at the feed per revolution written; planned, the spindle holds 150 m/min within
    1 % wherever the tip feeds and the cap does not bind."""
    text = (HEAD + "G96 D3000 S150 M3\nG0 X30 Z4\nF0.1\nG70 Q100 X30 Z4 P2 D0.3\nM5\nM2\n"
            "o100 sub\nG1 X20 Z2\nG1 Z-20\nG1 X28 Z-24\no100 endsub\n")
    job = parse_job(_program(text))
    (_, op, doc), = job.program.operations
    assert doc["surface_speed"] == {"m_min": 150.0, "max_rpm": 3000.0} and "spindle_rpm" not in doc
    feeds = [m for m in doc["move"] if "linear" in m]
    # two passes of the contour after its first point (the approach, as LinuxCNC has it)
    assert len(feeds) == 2 * 2 and all(m == {"linear": m["linear"], "feed_per_rev": 0.1} for m in feeds)
    _, figures = planned_surface_speed(job, op, (next(m.feed_per_rev for m in op.move if m.linear),))
    assert figures["failures"] == [] and figures["max_deviation_pct"] <= 1.0 + 1e-6 and figures["held_s"] > 5.0


def test_the_planned_spindle_holds_the_surface_speed_along_x():
    """turn_cone at 150 m/min capped at 3000 rpm: wherever the tip feeds (at the feed per
    revolution of the planned spindle speed) the surface speed is within 1 % of 150 m/min
    where the cap does not bind, the rpm never above the cap, the spindle's acceleration
    within its limit; the cone's tapered cuts ramp it along the cut."""
    job = parse_job(_turn_doc(surface_speed={"m_min": 150, "max_rpm": 3000}))
    spindle_acceleration, figures = planned_surface_speed(job, job, (job.turn.feed,))
    assert figures["failures"] == [] and figures["max_deviation_pct"] <= 1.0 + 1e-6
    assert figures["held_s"] > 30.0 and figures["capped_s"] > 1.0 and figures["max_rpm"] <= 3000.0
    assert figures["min_m_min"] < 149.0  # a taper's pieces: not one rpm per cut
    assert np.max(np.abs(spindle_acceleration)) <= load_machine("lathe").axes["spindle"].max_acceleration * (1 + 1e-9)


def test_the_judge_fails_one_rpm_along_x_and_a_spindle_above_its_cap():
    """Synthetic feedback: a face cut from 20 to 10 mm at one rpm is 50 % off at its end;
    a spindle 1 % above the cap fails however well it holds the speed."""
    t = np.arange(0.0, 2.0, 1e-3)
    radius = np.linspace(0.020, 0.010, len(t))
    w = np.full_like(t, 2.5 / 0.020)  # 150 m/min at 20 mm
    feed = 0.15e-3 * w / (2.0 * math.pi)
    one_rpm = judge_surface_speed(t, radius, feed, w, 2.5, 1000.0, (0.15e-3,))
    assert one_rpm["max_deviation_pct"] == pytest.approx(50.0, abs=0.1)
    assert one_rpm["failures"][0].startswith("surface speed -50.00 % off 150 m/min at radius 10.000 mm")
    held = 2.5 / radius
    above = judge_surface_speed(t, radius, 0.15e-3 * held / (2.0 * math.pi), held, 2.5, held.max() / 1.01, (0.15e-3,))
    assert any(f.startswith("spindle at 2387.3 rpm, above the cap of 2363.7 rpm") for f in above["failures"])
    rapid = judge_surface_speed(t, radius, np.full_like(t, 0.2), held, 2.5, 1000.0, (0.15e-3,))
    assert rapid["cutting_s"] == 0.0 and rapid["failures"] == [
        "no cut found at the job's feeds (per revolution of the measured spindle speed)"]
    per_minute = judge_surface_speed(t, radius, np.full_like(t, 0.2), held, 2.5, 1000.0, feeds=(0.2,))
    assert per_minute["held_s"] > 1.9 and per_minute["failures"] == [] and "feed_per_rev_mm" not in per_minute


def test_the_report_page_shows_the_surface_speed_apart_from_the_gouge():
    """The turn section's cards: a surface speed 3 % off is its own bad card, the gouge card
    stays ok (it judges the gouge alone)."""
    from cnc_planner.kinds.turn.page import cards
    turn = {"max_gouge_part_mm": 0.0, "verdict": {"passed": False}, "air_feed_mm": 1.0, "naive_air_feed_mm": 2.0,
            "surface_speed": {"requested_m_min": 120.0, "cap_rpm": 3000.0, "cutting_s": 10.0, "held_s": 8.0,
                              "capped_s": 2.0, "max_rpm": 2990.0, "max_deviation_pct": 3.0}}
    shown = {title: (value, status) for title, value, _, status in cards(turn)}
    assert shown["Stock left / gouge"] == ("no gouge", "ok") and shown["Surface speed"] == ("3.00 % off", "bad")


def test_every_corner_of_the_drives_tolerance_holds_the_surface_speed_and_the_cap():
    """turn_cone at 150 m/min (cap 3000 rpm) planned on the described lathe, its setpoints run
    through the drives at every corner of their tolerance (spindle, x and z together): the
    judge passes on each one's feedback, the spindle's overshoot inside the cap's headroom
    (measured: at most 1.13 % off, 2984 rpm)."""
    from cnc_msgs_py.plant import tolerance_corners
    from cnc_servo_bridge.drive import DriveModel
    machine = load_machine("lathe")
    job = parse_job(_turn_doc(surface_speed={"m_min": 150, "max_rpm": 3000}))
    plan = plan_job(job, machine)
    t = np.arange(0.0, plan.duration, 1e-3)
    command = plan.sample(t)
    x, z, s = (machine.joint_names.index(j) for j in ("x", "z", "spindle"))
    kin = Kinematics(machine, job.setup, job.tool)
    corners = zip(*(tolerance_corners(machine.drives[j]) for j in ("spindle", "x", "z")))
    for spindle, dx, dz in corners:
        p, v = DriveModel(machine, 1e-3, drives={**machine.drives, "spindle": spindle, "x": dx, "z": dz}).simulate(*command)
        radius, _ = kin.tip_radius_z(p[:, x], p[:, z])
        figures = judge_surface_speed(t, radius, np.hypot(v[:, x], v[:, z]), v[:, s], job.surface_speed.m_min,
                                      job.surface_speed.max_rpm, (job.turn.feed,))
        assert figures["failures"] == [] and figures["max_rpm"] < 3000.0 and figures["held_s"] > 40.0, spindle
