"""Taper threads over topics, judged on the recorded feedback: NPT 1/2"-14 (taper 1:16 on
the diameter, 14 threads per inch) cut external and internal with the chip-breaking
vibration along the flank. X follows the cone and Z the lead, both locked to the spindle
angle: every cutting pass breaks its chips within one revolution and the last passes reach
full depth below the cone everywhere from the face to end_z. Judged as a cylinder the same
feedback is 0.37 mm off at end_z (1:16 over 14 mm on the diameter is 0.44 mm on it, half
on the radius and ~0.06 mm of that taken by the flank offset), so the depth is really
measured along the taper. The same bore cut straight (taper 0) is the internal straight
thread, judged the same way.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cnc_analysis.recording import read_run
from cnc_analysis.threads import analyze_thread
from support import cnc, load_report

NPT_HALF = {"start_z": 4.0, "end_z": -14.0, "pitch": 25.4 / 14, "depth": 1.45, "passes": 6,
            "infeed_angle": 29.5, "spring_passes": 1, "taper": 1 / 16}


def cut(tmp_path, name: str, **thread) -> tuple[dict, dict, object]:
    doc = {"schema": "cnc_job/1", "job_id": name, "kind": "thread", "machine": "lathe", "spindle_rpm": 600,
           "thread": {**NPT_HALF, **thread}, "vibration": {"D": 1.5, "Q": 1.2, "phase_shift": 180}}
    (tmp_path / f"{name}.json").write_text(json.dumps(doc))
    result = cnc("cnc-run", tmp_path / f"{name}.json", "--out", tmp_path / name)
    assert result.returncode == 0, result.stderr[-3000:]
    return doc["thread"], load_report(tmp_path / name)["thread"], read_run(tmp_path / name / "bag")


def check_thread(thread: dict) -> None:
    """Chips broken in every cutting pass, full depth without overcut, one helix."""
    assert thread["synchronised_passes"] == 7 and thread["cutting_passes"] == 6
    for p in thread["passes"]:
        if p["doc_mm"] > 0.05:
            assert p["max_chip_revs"] <= 1.0, p
    assert thread["full_depth"] and thread["depth_error_mm"] <= 0.02 and thread["overcut_mm"] <= 0.02
    assert thread["helix_residual_mm"] < 0.01
    assert thread["infeed_angle_deg"] == pytest.approx(29.5, abs=0.5)


def check_taper_thread(block: dict, thread: dict, run) -> None:
    check_thread(thread)
    columns = [run.column(j) for j in ("x", "z", "spindle")]
    x, z, spindle = (run.feedback[:, c] for c in columns)
    as_cylinder = analyze_thread(run.feedback_t, x, z, spindle, {**block, "taper": 0.0})
    assert not as_cylinder["full_depth"] and as_cylinder["depth_error_mm"] > 0.3


def test_external_npt_half_inch_taper_thread(tmp_path):
    check_taper_thread(*cut(tmp_path, "npt-half-external", major_radius=10.3))


def test_internal_npt_half_inch_taper_thread(tmp_path):
    block, thread, run = cut(tmp_path, "npt-half-internal", major_radius=9.2, internal=True)
    check_taper_thread(block, thread, run)
    # inside the part the tool stays within the bore's full-depth cone, widest at the face:
    # radius 9.2 + 1.45 + g/32 at the groove's z, g = z + depth*tan(29.5 deg) behind the tip
    x, z = (run.feedback[:, run.column(j)] * 1e3 for j in ("x", "z"))
    inside = z < 0.0
    assert inside.sum() > 1000
    g = z[inside] + 1.45 * math.tan(math.radians(29.5))
    assert np.all(x[inside] <= 9.2 + 1.45 + g / 32 + 0.002)


def test_internal_straight_thread(tmp_path):
    _, thread, _ = cut(tmp_path, "straight-internal", major_radius=9.2, internal=True, taper=0.0)
    check_thread(thread)
