"""Air-cut analyser against hand-computed cases.

The synthetic paths are piecewise linear in the spindle angle (triangle vibrations), so
where revolution n+1 re-enters the path of revolution n can be worked out on paper:
with feed F per rev and amplitude Q*F, the depth below the previous revolution changes
linearly between the return and turning points.
"""
import json
import math

import numpy as np
import pytest

from cnc_analysis.aircut import analyze_aircut

F = 1e-4
Q = 1.2
PI = math.pi


def triangle(u: np.ndarray) -> np.ndarray:
    """0 at the return point (u integer), 1 at the turning point (u + 1/2), linear between."""
    x = np.mod(u, 1.0)
    return np.where(x < 0.5, 2 * x, 2 * (1 - x))


def path(d: float, revs: int, start: float = 0.0, step_deg: float = 0.5):
    theta = np.append(np.arange(start, 2 * PI * revs, math.radians(step_deg)), 2 * PI * revs)
    return theta, F * theta / (2 * PI) + Q * F * triangle(d * theta / (2 * PI))


def assert_intervals(actual, expected_deg):
    assert len(actual) == len(expected_deg)
    for (a, b), (ea, eb) in zip(actual, expected_deg):
        assert a == pytest.approx(math.radians(ea), abs=1e-9)
        assert b == pytest.approx(math.radians(eb), abs=1e-9)


def test_half_vibration_per_rev_breaks_at_every_return_point():
    # D = 0.5: forward for one rev, back for one. Rev 2k-1 (returning) meets rev 2k-2 (at the
    # turning point) where F + Q*F*(1 - x/pi) <= 0, i.e. x >= pi*(1 + 1/Q) = 330 deg; rev 2k
    # (forward from the return point) is behind rev 2k-1 while F + Q*F*(x/pi - 1) <= 0, i.e.
    # x <= pi*(1 - 1/Q) = 30 deg.
    theta, s = path(0.5, 8)
    report = analyze_aircut(theta, s)
    assert report.revolutions == 7
    assert report.revolutions_with_aircut == 7
    for n, rev in enumerate(report.intervals, start=1):
        assert_intervals(rev, [(330.0, 360.0)] if n % 2 else [(0.0, 30.0)])
    assert report.aircut_fraction == pytest.approx(30 / 360)
    # cutting from 30 deg of an even rev to 330 deg of the next odd rev: 1 + 300/360 revs
    assert report.max_chip_revs == pytest.approx(1 + 300 / 360)


def test_one_and_a_half_vibrations_per_rev():
    # D = 1.5: the previous rev is half a vibration off, so rev n - rev n-1 = F + Q*F*(2w - 1)
    # <= 0 where w <= (1 - 1/Q)/2 = 1/12: 1/24 of a vibration (10 deg) either side of every
    # return point, which lie at 0, 240, 480, ... deg.
    theta, s = path(1.5, 8)
    report = analyze_aircut(theta, s)
    assert report.revolutions == 7
    assert report.revolutions_with_aircut == 7
    for n, rev in enumerate(report.intervals, start=1):
        expected = [(110.0, 130.0), (350.0, 360.0)] if n % 2 else [(0.0, 10.0), (230.0, 250.0)]
        assert_intervals(rev, expected)
    assert report.aircut_fraction == pytest.approx(1 / 12)
    assert report.max_chip_revs == pytest.approx(220 / 360)


def test_tolerance_widens_the_air_cut():
    # depth <= F/2 counts as air: x <= pi*(1 - 0.5/Q) = 105 deg, x >= pi*(1 + 0.5/Q) = 255 deg
    theta, s = path(0.5, 8)
    report = analyze_aircut(theta, s, tolerance=0.5 * F)
    for n, rev in enumerate(report.intervals, start=1):
        assert_intervals(rev, [(255.0, 360.0)] if n % 2 else [(0.0, 105.0)])


def test_feed_direction_and_position_offset_do_not_matter():
    theta, s = path(1.5, 6)
    forward = analyze_aircut(theta, s)
    backward = analyze_aircut(theta, 0.02 - s, direction=-1.0)
    assert backward.revolutions_with_aircut == forward.revolutions_with_aircut == 5
    assert backward.max_chip_revs == pytest.approx(forward.max_chip_revs)
    for b, f in zip(backward.intervals, forward.intervals):
        assert np.allclose(b, f, atol=1e-9)


def test_recording_starting_mid_revolution():
    # from 1 rad: revolution 1 is complete but its phases below 1 rad have no earlier
    # surface, so the analysis starts with revolution 2
    theta, s = path(0.5, 8, start=1.0)
    report = analyze_aircut(theta, s)
    assert report.revolutions == 6
    assert_intervals(report.intervals[0], [(0.0, 30.0)])
    assert_intervals(report.intervals[1], [(330.0, 360.0)])


def test_plain_feed_never_cuts_air():
    theta = np.linspace(0, 2 * PI * 5, 3601)
    report = analyze_aircut(theta, F * theta / (2 * PI))
    assert (report.revolutions, report.revolutions_with_aircut) == (4, 0)
    assert report.aircut_fraction == 0.0
    assert report.max_chip_revs == pytest.approx(4.0)
    assert report.intervals == [[], [], [], []]


def test_dwell_cuts_air_once_the_tool_has_been_round():
    # feed for 3 revs, then stand still: rev 3 still cuts what revs 0-2 left (its end only
    # touches the surface, which is no air-cut); revs 4 and 5 cut nothing at all
    theta = np.linspace(0, 2 * PI * 6, 4321)
    report = analyze_aircut(theta, np.minimum(F * theta / (2 * PI), 3 * F))
    assert report.revolutions == 5
    assert report.intervals[:3] == [[], [], []]
    assert_intervals(report.intervals[3], [(0.0, 360.0)])
    assert_intervals(report.intervals[4], [(0.0, 360.0)])
    assert report.revolutions_with_aircut == 2
    assert report.aircut_fraction == pytest.approx(2 / 5)
    assert report.max_chip_revs == pytest.approx(3.0)


def test_report_is_json_ready():
    theta, s = path(1.5, 4)
    d = analyze_aircut(theta, s).to_dict()
    assert set(d) == {
        "revolutions", "revolutions_with_aircut", "max_chip_revs", "aircut_fraction", "intervals"
    }
    assert json.loads(json.dumps(d)) == d
    assert len(d["intervals"]) == d["revolutions"]


def test_rejects_bad_samples():
    with pytest.raises(ValueError, match="spindle_angle"):
        analyze_aircut(np.array([0.0, 1.0, 0.5]), np.zeros(3))
    with pytest.raises(ValueError, match="equal-length"):
        analyze_aircut(np.zeros(3), np.zeros(4))
