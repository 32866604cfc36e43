"""G33 over topics, judged on the recorded feedback: LinuxCNC's way of cutting a thread by
hand (test/gcode_oracle/lathe_g33.ngc, two passes at S600 K2, the second deeper and along
the flank, each leaving at 45 degrees locked to the spindle) run by cnc-run on the lathe. The
program's sync operation has its spindle_sync section: both passes found on feedback, every
move at its K per revolution of the measured spindle angle, both passes in one groove.
Checked from the bag as well: on feedback Z runs at 2 mm per revolution of the spindle
angle (20 mm/s at 600 rpm), and z + 2 mm * revolutions, less each pass's start, is the same
on both passes to well within the tolerance.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_analysis.recording import read_run
from support import ROOT, cnc, load_report

PROGRAM = ROOT / "test" / "gcode_oracle" / "lathe_g33.ngc"
STARTS_MM = (5.0, 5.17)


def test_g33_passes_locked_to_the_spindle_in_one_groove_on_feedback(tmp_path):
    result = cnc("cnc-run", PROGRAM, "--machine", "lathe", "--out", tmp_path / "run")
    assert result.returncode == 0, result.stderr[-3000:]
    (op,) = load_report(tmp_path / "run")["program"]["operations"]
    sync = op["spindle_sync"]
    assert op["kind"] == "sync" and sync["verdict"]["passed"], sync["verdict"]
    assert [len(p["moves"]) for p in sync["passes"]] == [2, 2]
    for p in sync["passes"]:
        thread, exit_ = p["moves"]
        assert thread["measured_lead_mm"] == pytest.approx(2.0, rel=1e-3)
        assert exit_["measured_lead_mm"] == pytest.approx(2.0 * math.sqrt(2.0), rel=5e-3)
        assert thread["locked_revs"] > 12.0 and thread["lock_error_mm"] < 0.01
    assert sync["groove_spread_mm"] < 0.002

    run = read_run(tmp_path / "run" / "bag")
    x, z, spindle = (run.feedback[:, run.column(j)] for j in ("x", "z", "spindle"))
    theta = np.unwrap(spindle)
    grooves = []
    for radius, start in zip((11.5e-3, 11.2e-3), STARTS_MM):
        on = (np.abs(x - radius) < 1e-6) & (z < start * 1e-3 - 2e-3) & (z > -18e-3)  # the thread, past the ramp
        lead = np.polyfit(theta[on], z[on], 1)[0] * 2 * math.pi
        assert lead == pytest.approx(-2e-3, rel=1e-4)  # 2 mm per revolution of the measured angle
        groove = z[on] + 2e-3 * theta[on] / (2 * math.pi) - start * 1e-3
        assert np.ptp(groove) < 10e-6
        grooves.append(float(np.median(groove)) % 2e-3)
    assert abs(grooves[1] - grooves[0]) < 2e-6


def test_g33_1_rigid_taps_follow_the_spindle_through_its_reversal_on_feedback(tmp_path):
    """test/gcode_oracle/mill_g33_1.ngc on mill3 (two M8x1.25 holes at S500): each tap found
    on feedback, 1.25 mm per revolution of the measured spindle angle in and out, locked across
    the reversal, the bottom within 0.02 mm, the spindle measured turning backwards."""
    program = ROOT / "test" / "gcode_oracle" / "mill_g33_1.ngc"
    result = cnc("cnc-run", program, "--machine", "mill3", "--out", tmp_path / "run")
    assert result.returncode == 0, result.stderr[-3000:]
    (op,) = load_report(tmp_path / "run")["program"]["operations"]
    sync = op["spindle_sync"]
    assert op["kind"] == "sync" and sync["verdict"]["passed"], sync["verdict"]
    assert [t["depth_mm"] for t in sync["taps"]] == [12.0, 8.0]
    for tap in sync["taps"]:
        assert tap["measured_lead_in_mm"] == pytest.approx(1.25, rel=1e-3)
        assert tap["measured_lead_out_mm"] == pytest.approx(1.25, rel=1e-3)
        assert tap["lock_error_mm"] < 0.01 and abs(tap["reached_mm"] - tap["depth_mm"]) < 0.01
        assert tap["reversed_rpm"] < -490.0

    run = read_run(tmp_path / "run" / "bag")
    x, z, spindle = (run.feedback[:, run.column(j)] for j in ("x", "z", "spindle"))
    theta = np.unwrap(spindle)
    first = (np.abs(x - 10e-3) < 1e-6) & (z < 1.5e-3)  # the first hole, past the ramps (0.38 mm)
    groove = z[first] + 1.25e-3 * theta[first] / (2 * math.pi)
    assert np.ptp(groove) < 10e-6  # one helix in and out
    assert z[first].min() == pytest.approx(-10e-3, abs=10e-6)
