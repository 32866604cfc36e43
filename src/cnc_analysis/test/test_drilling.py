"""The drilling analyser against a piecewise-linear trajectory computed by hand."""
from __future__ import annotations

import json

import numpy as np
import pytest

from cnc_analysis.drilling import analyze_drilling

R = 0.002
TOL = 1e-5
HOLES = [(0.0, 0.0), (0.01, 0.0)]
T = np.arange(10001) / 1000.0  # 0..10 s every 1 ms, exact at whole ms
# Z: rest at 4 mm, down through R to 0 (hole A), up to 4 mm, on to 6 mm (R'), down to 0
# (hole B), up to 4 mm. R = 2 mm is crossed at 1.5, 3.5, 5.6 and 7.5 s.
Z_KNOTS = ([0, 1, 2, 3, 4, 4.6, 6.1, 7, 8, 10], [0.004, 0.004, 0, 0, 0.004, 0.006, 0, 0, 0.004, 0.004])


def trajectory(x_start: float):
    """X moves 0 -> 10 mm linearly in 1.5 s from ``x_start``; Y stays at 0."""
    x = np.interp(T, [x_start, x_start + 1.5], [0.0, 0.01])
    return x, np.zeros_like(T), np.interp(T, *Z_KNOTS)


def test_hand_computed_overlap_times():
    x, y, z = trajectory(3.8)
    result = analyze_drilling(T, x, y, z, HOLES, R, TOL, surface_z=0.001)
    a, b = result["holes"]
    # X leaves A's tolerance at 3.8 + 1.5 * 1e-5 / 0.01 and enters B's 1.5 ms before 5.3 s.
    leave, arrive = 3.8015, 5.2985
    assert result["safety_violations"] == 0
    assert a["in_position_s"] == pytest.approx(0.0)
    assert a["r_down_s"] == pytest.approx(1.5) and a["r_up_s"] == pytest.approx(3.5)
    assert b["r_down_s"] == pytest.approx(5.6) and b["r_up_s"] == pytest.approx(7.5)
    assert b["in_position_s"] == pytest.approx(arrive, abs=1e-9)
    assert a["overlap_down_s"] == 0.0  # X/Y was in place before Z left its rest at t = 1
    assert a["overlap_up_s"] == pytest.approx(4.6 - leave)  # Z rose to R' after X/Y left
    assert b["overlap_down_s"] == pytest.approx(arrive - 4.6)  # Z descended from R' before X/Y arrived
    assert b["overlap_up_s"] == 0.0
    assert a["depth_mm"] == pytest.approx(1.0) and b["depth_mm"] == pytest.approx(1.0)
    assert (a["x_mm"], b["x_mm"], a["index"], b["index"]) == (0.0, 10.0, 0, 1)
    # Motion: Z leaves its start rest by more than TOL after 1.0025 s (first sample 1.003 s)
    # and is within TOL of its end rest from 7.9975 s (last sample off it: 7.997 s).
    assert result["cycle_time_s"] == pytest.approx(7.997 - 1.003)
    assert a["cycle_time_s"] == pytest.approx(3.5 - 1.003)
    assert b["cycle_time_s"] == pytest.approx(7.5 - 3.5)
    json.dumps(result)


def test_xy_leaving_before_the_tip_is_out_counts_violations():
    # X leaves at 3.2 s: off A's tolerance from the 3.202 s sample; the tip stays below R
    # up to the 3.499 s sample.
    x, y, z = trajectory(3.2)
    result = analyze_drilling(T, x, y, z, HOLES, R, TOL)
    assert result["safety_violations"] == 298
    assert "depth_mm" not in result["holes"][0]


def test_hole_never_drilled_has_no_times():
    x, y, z = trajectory(3.8)
    result = analyze_drilling(T, x, y, z, HOLES + [(0.05, 0.05)], R, TOL)
    assert result["holes"][2]["r_down_s"] is None
    assert result["holes"][2]["cycle_time_s"] is None


def test_a_million_samples_over_two_hundred_holes_find_every_hole():
    """A long recording (vectorised analysis; its speed is a benchmark's business): every
    hole is visited, once, and nothing is off its hole below R."""
    x, y, z = trajectory(3.8)
    reps = 100
    t = np.arange(len(T) * reps) / 1000.0
    offsets = np.repeat(np.arange(reps) * 0.02, len(T))
    holes = [(k * 0.02 + hx, hy) for k in range(reps) for hx, hy in HOLES]
    result = analyze_drilling(t, np.tile(x, reps) + offsets, np.tile(y, reps), np.tile(z, reps), holes, R, TOL)
    assert len(t) >= 1_000_000 and len(result["holes"]) == len(holes)
    assert result["safety_violations"] == 0
    assert all(hole["r_down_s"] is not None for hole in result["holes"])


def test_a_gap_in_the_recording_does_not_merge_two_holes_into_one_visit():
    """Samples lost from 3.0 to 6.0 s hide the rise out of A and the descent into B: the
    samples before the gap are A's, those after it B's, and none is off its hole."""
    x, y, z = trajectory(3.8)
    kept = (T < 3.0) | (T > 6.0)
    result = analyze_drilling(T[kept], x[kept], y[kept], z[kept], HOLES, R, TOL)
    a, b = result["holes"]
    assert result["safety_violations"] == 0
    assert a["r_down_s"] == pytest.approx(1.5) and b["r_up_s"] == pytest.approx(7.5)


def test_a_start_below_r_climbs_to_it_without_a_hole_visit():
    # hole-circle.ngc's start: the tip at Z0 on B's X/Y (R 2 mm above), climbing to 4 mm by
    # 0.6 s (R at 0.3 s), then on to A and B as in the hand-computed trajectory. Without the
    # climb the tip is below R at B first: B's visits would span the whole run.
    x, y, z = trajectory(3.8)
    x = np.where(T < 0.7, 0.01, np.interp(T, [0.7, 0.9], [0.01, 0.0])) * (T < 3.8) + x * (T >= 3.8)
    z = np.where(T < 0.6, T / 0.6 * 0.004, z)
    result = analyze_drilling(T, x, y, z, HOLES, R, TOL)
    a, b = result["holes"]
    assert result["safety_violations"] == 0
    assert a["r_down_s"] == pytest.approx(1.5) and b["r_down_s"] == pytest.approx(5.6)
    assert a["in_position_s"] == pytest.approx(0.9, abs=1e-3)
    # X/Y leaving while the tip still climbs to R is X/Y moving below R: from 0.2 s on
    early = analyze_drilling(T, np.where(T < 3.8, np.interp(T, [0.2, 0.4], [0.01, 0.0]), x), y, z, HOLES, R, TOL)
    assert early["safety_violations"] == 99  # the 0.201..0.299 s samples: below R, off where it began
    # A start below R that goes down first is a visit of the hole it stands in (A: its
    # first visit begins with the run, its last ends at 3.5 s)
    z_down = np.where(T < 0.6, 0.001 - T / 0.6 * 0.001, np.where(T < 1.0, (T - 0.6) / 0.4 * 0.004, z))
    down = analyze_drilling(T, *trajectory(3.8)[:2], z_down, HOLES, R, TOL)
    assert down["holes"][0]["r_down_s"] == 0.0 and down["holes"][0]["r_up_s"] == pytest.approx(3.5)
