"""G33, moves locked to the spindle, and G33.1, rigid tapping (cnc_msgs_py.gcode.spindle_sync,
the sync kind).

- By hand: G33 K2 at S600 feeds 2 mm x 10 rev/s = 20 mm/s along Z; every pass leaves its
  start at the spindle's index (angle a whole number of turns) and its moves run locked:
  z + K * theta / 2pi is the same on both passes once at speed, the second shifted only by
  its programmed start; the 45 degree exit at K = sqrt(2) * 2 keeps 2 mm of Z per revolution.
- The oracle program (test/gcode_oracle/lathe_g33.ngc): every feed end and rapid that rs274 -g
  makes of it (recorded by bench/peer/examples.py in bench/results/rs274_examples.json) is ours
  in order within 1 um, its synchronised feeds our sync moves with their K.
- LinuxCNC's threading.ngc plans on the shipped lathe (bench/results/linuxcnc_examples.json).
- Refusals: K missing, the spindle off, G96, compensation on, a lead faster than an axis.
- G33.1 by hand on mill3 (S500 K1.25: 10.42 mm/s): Z + K * turns is constant from the index
  to the return, through the spindle's reversal; the bottom exact, where the spindle stands;
  the spindle at -500 rpm coming out and forward again after; test/gcode_oracle/mill_g33_1.ngc
  against rs274's RIGID_TAP calls.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_msgs_py.gcode import Context, GcodeError, translate
from cnc_msgs_py.gcode.document import job_document
from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, load_machine
from cnc_msgs_py.schema import JobError
from cnc_planner.planning import plan_job

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "bench" / "peer")]
import examples  # noqa: E402  bench/peer/examples.py
import oracle  # noqa: E402  bench/peer/oracle.py

PROGRAM = ROOT / "test" / "gcode_oracle" / "lathe_g33.ngc"
TIP_TOLERANCE_MM = 1e-3
TWO_PI = 2.0 * math.pi


def _job(moves: list[dict], rpm: float = 600.0, machine: str = "lathe"):
    return parse_job({"schema": "cnc_job/1", "job_id": "g33", "kind": "sync", "machine": machine,
                      "spindle_rpm": rpm, "tool": {}, "sync": moves})


TWO_PASSES = [
    {"rapid": {"x": 12, "z": 5}},
    {"sync": {"z": -20}, "lead": 2.0},
    {"rapid": {"x": 14}}, {"rapid": {"z": 5.17}}, {"rapid": {"x": 11.7}},
    {"sync": {"z": -20}, "lead": 2.0},
    {"sync": {"x": 13.7, "z": -22}, "lead": 2.0 * math.sqrt(2.0)},
    {"rapid": {"x": 14}},
]


def test_k2_at_600_rpm_feeds_20_mm_per_s_and_both_passes_start_at_the_index_in_one_groove():
    plan = plan_job(_job(TWO_PASSES), load_machine("lathe"))
    starts = [e.time for e in plan.events if e.name == "sync_pass"]
    assert len(starts) == 2
    x, z, spindle = (plan.joints.index(j) for j in ("x", "z", SPINDLE))
    for t in starts:  # at rest at the pass's start, the spindle at its index, at 600 rpm
        p, v, _ = plan.sample(np.array([t]))
        assert p[0, spindle] / TWO_PI == pytest.approx(round(p[0, spindle] / TWO_PI), abs=1e-9)
        assert v[0, spindle] == pytest.approx(600.0 * TWO_PI / 60.0) and v[0, z] == 0.0
    grooves = []
    for t, z0 in zip(starts, (5e-3, 5.17e-3)):
        ts = t + np.linspace(0.2, 1.0, 81)  # well inside the first move of each (12.5 revolutions of 2 mm)
        p, v, _ = plan.sample(ts)
        assert np.allclose(v[:, z], -0.020, rtol=0, atol=1e-12)  # 2 mm/rev x 600 rpm = 20 mm/s
        assert np.all(v[:, x] == 0.0)
        groove = p[:, z] + 2e-3 * p[:, spindle] / TWO_PI - z0  # constant once locked, less the start
        assert np.ptp(groove) < 1e-12
        grooves.append(groove[0])
    assert (grooves[1] - grooves[0]) / 2e-3 == pytest.approx(round((grooves[1] - grooves[0]) / 2e-3), abs=1e-9)
    # the ideal start is half the ramp after the index: a symmetric ramp to 20 mm/s leaves the
    # tool v * T / 2 behind it, T the ramp's time (the jerk its limit, as the plan derates it,
    # stretched so that every drive inside the tolerance holds the lock: kinds.sync.margin)
    ts = starts[0] + np.arange(0.0, 0.2, 1e-5)
    _, v, a = plan.sample(ts)
    ramp = ts[np.argmax(np.abs(v[:, z] + 0.020) < 1e-12)] - starts[0]
    assert 0.0126 <= ramp < 0.15  # at least 2 sqrt(0.02 / 500) s: the ramp is jerk-limited
    assert grooves[0] % 2e-3 == pytest.approx(0.020 * ramp / 2.0, abs=0.020 * 1e-5)
    ts = starts[1] + ramp / 2.0 + (25.0 / 20.0) + np.linspace(0.0, 0.1, 1001)  # the exit, its ramps included
    _, v, _ = plan.sample(ts)
    top = np.abs(v[:, x] - 0.020) < 1e-12  # x at its 20 mm/s between the ramps: z goes on at 20
    assert top.any() and np.allclose(v[top, z], -0.020, atol=1e-12)


def test_translation_of_g33_lines():
    ops = translate("G20 G18 G8 G90\nS400 M3\nG0 X0.2 Z0.8\nG33 Z0.1 K0.05\nG33 X0.3 Z0 K[SQRT[2]*0.05]\nG0 X0.5\nM2",
                    Context("t", "lathe"))
    (op,) = ops
    assert op.doc["kind"] == "sync" and op.doc["spindle_rpm"] == 400.0
    assert op.doc["sync"][1] == {"sync": {"x": 0.2 * 25.4, "z": 0.1 * 25.4}, "lead": pytest.approx(0.05 * 25.4)}
    assert op.doc["sync"][2]["lead"] == pytest.approx(math.sqrt(2) * 0.05 * 25.4)
    # a program without G33 stays a move operation
    assert translate("G21 G18\nS400 M3\nG0 X2 Z1\nG1 Z0 F100\nM2", Context("t", "lathe"))[0].doc["kind"] == "move"


@pytest.mark.parametrize("text,reason", [
    ("S600 M3\nG0 X10 Z2\nG33 Z-5", "line 4: G33: needs K, the distance per spindle revolution"),
    ("G0 X10 Z2\nG33 Z-5 K1", "line 3: G33: the spindle is off"),
    ("G96 D2000 S100 M3\nG0 X10 Z2\nG33 Z-5 K1", "line 4: G33: a move locked to the spindle turns at one rpm"),
    ("S600 M3\nG0 X10 Z2\nG33 X10 Z2 K1", "line 4: G33: moves nowhere"),
    ("S600 M3\n(CNC,VIBRATION D=1.5 Q=1.2)\nG0 X10 Z2\nG33 Z-5 K1", "line 5: G33: a move locked to the spindle is "
                                                                 "not vibrated"),
])
def test_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        translate("G21 G18 G8 G90\n" + text + "\nM2", Context("t", "lathe"))
    assert str(err.value).startswith(reason), str(err.value)


def test_a_lead_faster_than_an_axis_and_a_move_too_short_for_its_ramps_are_refused():
    machine = load_machine("lathe")
    with pytest.raises(JobError) as err:  # 60 mm x 600 rpm = 600 mm/s: z goes 500 at most
        plan_job(_job([{"rapid": {"x": 12, "z": 5}}, {"sync": {"z": -20}, "lead": 60.0}]), machine)
    assert str(err.value).startswith("sync[1].sync: 36000 mm/min (lead x rpm) drives z faster than its 30000 mm/min")
    with pytest.raises(JobError) as err:
        plan_job(_job([{"rapid": {"x": 12, "z": 5}}, {"sync": {"z": 4.9}, "lead": 10.0}]), machine)
    assert str(err.value).startswith("sync[1].sync: too short to be locked to the spindle")
    with pytest.raises(JobError) as err:
        _job([{"rapid": {"x": 12, "z": 5}}, {"sync": {"z": 4.9}}])
    assert str(err.value).startswith("sync[1].lead: required for a sync or tap move")


def test_every_feed_end_and_rapid_is_linuxcncs_its_synchronised_feeds_our_sync_moves():
    moves, error = oracle.canonical_moves(oracle.recorded(examples.RS274_RECORDED)(PROGRAM.read_text()))
    assert error is None, error
    theirs = [("sync" if m.synced else "linear" if m.kind == "feed" else "rapid", m.end, m.pitch if m.synced else None)
              for m in moves]
    job = parse_job(job_document(PROGRAM))
    (_, _, doc), = job.program.operations
    ours = [(k, tuple(m[k].get(a, 0.0) for a in "xyz"), m.get("lead")) for m in doc["sync"] for k in m
            if k in ("rapid", "linear", "sync")]
    assert len(ours) == len(theirs) == 10 and [k for k, _, _ in ours].count("sync") == 4
    for (kind, end, lead), (their_kind, their_end, pitch) in zip(ours, theirs):
        assert kind == their_kind and np.allclose(end, their_end, atol=TIP_TOLERANCE_MM)
        assert lead == pitch or lead == pytest.approx(pitch, abs=1e-6)
    plan_job(job, load_machine("lathe"))


def test_linuxcncs_threading_ngc_plans_on_the_lathe():
    recorded = json.loads(examples.RESULTS.read_text())["threading.ngc"]
    assert recorded["machine"] == "lathe" and recorded["outcome"] == "plans", recorded
    path = examples.NCFILES / "threading.ngc"
    if path.is_file():  # LinuxCNC installed: plan it again
        assert examples.ours(path, "lathe")[0] == "plans"


TAPS = [{"rapid": {"x": 10, "y": 5, "z": 2}}, {"tap": {"z": -10}, "lead": 1.25}, {"rapid": {"x": 30}},
        {"tap": {"z": -6}, "lead": 1.25}, {"rapid": {"z": 10}}]


def test_a_rigid_tap_follows_the_spindle_down_through_its_reversal_and_out():
    job = parse_job({"schema": "cnc_job/1", "job_id": "tap", "kind": "sync", "machine": "mill3", "spindle_rpm": 500,
                     "tool": {"diameter": 8}, "sync": TAPS})
    plan = plan_job(job, load_machine("mill3"))
    starts = [e.time for e in plan.events if e.name == "sync_pass"]
    t = np.arange(0.0, plan.duration, 1e-4)
    p, v, a = plan.sample(t)
    x, z, spindle = (plan.joints.index(j) for j in ("x", "z", SPINDLE))
    omega = 500.0 * TWO_PI / 60.0
    for start, hole, bottom in zip(starts, (10e-3, 30e-3), (-10e-3, -6e-3)):
        sp = plan.sample(np.array([start]))[0][0, spindle]
        assert sp / TWO_PI == pytest.approx(round(sp / TWO_PI), abs=1e-9)  # at the index
        tap = (t > start) & (p[:, x] == hole) & (p[:, z] < 1.5e-3)  # past the ramps on and off (0.4 mm)
        assert np.min(p[tap, z]) == pytest.approx(bottom, abs=1e-12)  # exactly the bottom
        groove = p[tap, z] + 1.25e-3 * p[tap, spindle] / TWO_PI
        assert np.ptp(groove) < 1e-12  # locked all the way, the reversal included
        assert np.max(-v[tap, z]) == pytest.approx(1.25e-3 * omega / TWO_PI, abs=1e-12)  # 10.42 mm/s in
        assert np.max(v[tap, z]) == pytest.approx(1.25e-3 * omega / TWO_PI, abs=1e-12)  # and out
        assert np.min(v[tap, spindle]) == pytest.approx(-omega, abs=1e-9)  # the spindle backwards out
        assert abs(v[tap, spindle][np.argmin(p[tap, z])]) < 0.01 * omega  # standing at the bottom
        # the spindle's limits through the lead: |a_z| = K / 2pi * 500 rad/s^2 at most
        assert np.max(np.abs(a[tap & (p[:, z] < 1e-3), z])) <= 1.25e-3 / TWO_PI * 500.0 + 1e-9
    after = t > starts[0] + 1.5
    assert np.max(v[after, spindle]) == pytest.approx(omega)  # forward again for the next hole


def test_g33_1_against_rs274s_rigid_taps():
    output = oracle.recorded(examples.RS274_RECORDED)((ROOT / "test" / "gcode_oracle" / "mill_g33_1.ngc").read_text())
    theirs = [tuple(float(v) for v in line.split("RIGID_TAP(")[1].rstrip(")").split(","))
              for line in output.splitlines() if "RIGID_TAP(" in line]
    moves, error = oracle.canonical_moves(output)
    assert error is None and len(theirs) == 2
    job = parse_job(job_document(ROOT / "test" / "gcode_oracle" / "mill_g33_1.ngc"))
    (_, _, doc), = job.program.operations
    rapids = [tuple(m["rapid"][a] for a in "xyz") for m in doc["sync"] if "rapid" in m]
    taps = [(m["tap"]["z"], m["lead"]) for m in doc["sync"] if "tap" in m]
    assert [(z, 1.25) for _, _, z in theirs] == taps
    assert rapids == [m.end for m in moves]  # the rapid after a tap leaves from where it started
    plan_job(job, load_machine("mill3"))


@pytest.mark.parametrize("text,reason", [
    ("S500 M3\nG0 X10 Y5 Z2\nG33.1 X11 Z-5 K1", "line 4: G33.1: a rigid tap runs along Z: move X before it"),
    ("S500 M3\nG0 X10 Y5 Z2\nG33.1 Z-5 K1 I2", "line 4: I2: a faster retract is not supported"),
    ("G0 X10 Y5 Z2\nG33.1 Z-5 K1", "line 3: G33.1: the spindle is off"),
    ("S500 M3\nG0 X10 Y5 Z2\nG84 Z-5 R2", "line 4: G84: tapping is not a cycle of ours: G33.1 taps rigidly"),
])
def test_tap_refusals(text, reason):
    with pytest.raises(GcodeError) as err:
        translate("G21 G17 G90\n" + text + "\nM2", Context("t", "mill3"))
    assert str(err.value).startswith(reason), str(err.value)


def test_a_tap_too_shallow_for_the_spindles_reversal_is_refused():
    with pytest.raises(JobError) as err:  # 1.25 mm/rev at 500 rpm reverses over ~0.09 mm
        plan_job(_job([{"rapid": {"x": 10, "y": 5, "z": 2}}, {"tap": {"z": 1.95}, "lead": 1.25}], 500.0, "mill3"),
                 load_machine("mill3"))
    assert str(err.value).startswith("sync[1].tap: too shallow to tap at this lead and speed")

