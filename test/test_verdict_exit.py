"""A run whose feedback misses is never a silent success, end to end: overlapped drilling on
a plant whose X/Y drives lie far outside the description's tolerance moves X while the tip
is below R; cnc-run ends `succeeded` on the planner's side but exits 4 with the failed
verdict, names the plant and the axis that follows differently, and cnc-analyze on the bag
exits 4 too."""
from __future__ import annotations

import json

from support import JOBS, cnc, load_report

# X and Y at 40 % of the described gain, a 5 ms velocity loop and 6 ms of fieldbus delay.
FAR = """name: far_xy
drive:
  x: {kp: 20.0, velocity_lag: 0.005, delay: 0.006}
  y: {kp: 20.0, velocity_lag: 0.005, delay: 0.006}
"""


def test_x_moving_below_r_on_a_far_plant_exits_4_from_cnc_run_and_cnc_analyze(tmp_path):
    plant = tmp_path / "far.yaml"
    plant.write_text(FAR)
    out = tmp_path / "far"
    result = cnc("cnc-run", JOBS / "drill_row.yaml", "--plant", plant, "--out", out)
    assert result.returncode == 4, result.stdout[-2000:] + result.stderr[-2000:]
    report = load_report(out)
    assert report["state"] == "succeeded" and report["plant"] == "far_xy"
    assert report["drill"]["safety_violations"] > 0 and report["drill"]["verdict"]["passed"] is False
    assert "verdict drill: FAILED: X/Y moved while the tip was below R" in result.stdout
    # The row runs along X: X is the axis named, with what to do; Y never moved.
    assert report["drives"]["differs"] == ["x"]
    assert "drives (plant far_xy): DIFFER: x follows differently from its description" in result.stdout
    assert "run cnc-identify on this bag" in result.stdout
    again = cnc("cnc-analyze", out / "bag", "--out", out / "again.json")
    assert again.returncode == 4 and "verdict failed: drill" in again.stderr
    assert json.loads((out / "again.json").read_text()) == report
