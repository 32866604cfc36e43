"""The 5-axis path job over real topics: the tip deviation from the programmed line by
forward kinematics of the bridge's feedback, and the report reproduced from the bag."""
from __future__ import annotations

import json

from support import JOBS, cnc, load_report


def test_5_axis_tilt_stays_on_the_line_on_feedback_and_the_bag_reproduces_the_report(tmp_path):
    out = tmp_path / "path"
    result = cnc("cnc-run", JOBS / "path_5ax_tilt.yaml", "--out", out)
    assert result.returncode == 0, result.stderr[-3000:]
    report = load_report(out)
    assert report["state"] == "succeeded" and report["chunks_lost"] == 0 and not report["alarms"]
    kin = report["kinematics"]
    assert kin["completed"] and 6.0 < kin["path_time_s"] < 6.1  # 60 mm at 600 mm/min, one profile
    assert kin["chord_tolerance_mm"] == 0.01
    assert kin["commanded_max_tip_deviation_mm"] <= kin["chord_tolerance_mm"]
    assert 0.0 < kin["servo_lag_mm"] < 0.05
    assert kin["max_tip_deviation_mm"] <= kin["chord_tolerance_mm"] + kin["servo_lag_mm"]
    assert kin["feedback_samples"] > 6000
    again = cnc("cnc-analyze", out / "bag", "--out", out / "again.json")
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "again.json").read_text()) == report
