"""analyze_thread on hand-made samples: passes laid exactly on a helix (or deliberately off
it), sampled every millisecond as a bag would hold them, with rests and returns between.

Thread: start_z 4, end_z -16, major_radius 6, pitch 1.75 (mm), infeed 29.5 deg, 600 rpm.
The thread between the face and end_z is 16 / 1.75 = 9.14 revolutions long.
"""
import math

import numpy as np
import pytest

from cnc_analysis.threads import POINTS_PER_REV, analyze_thread

T = 1e-3
OMEGA = 20 * math.pi  # 600 rpm
LEAD = 1.75e-3
TAN = math.tan(math.radians(29.5))
THREAD = {"start_z": 4.0, "end_z": -16.0, "major_radius": 6.0, "pitch": 1.75, "depth": 1.07,
          "passes": 3, "infeed_angle": 29.5, "spring_passes": 0}
REVS = 16 / 1.75
RESOLUTION = 2.0 / POINTS_PER_REV  # chip lengths: a grid point at either end


def wave(u):
    """The vibration waveform: 0 at the return point, 1 at the turning point."""
    return (1 - np.cos(2 * np.pi * u)) / 2


def constant(depth_mm):
    return lambda psi: np.full_like(psi, depth_mm * 1e-3)


def vibrating(depth_mm, amplitude_mm, per_rev, phase):
    return lambda psi: (depth_mm - amplitude_mm * (1 - wave(per_rev * psi + phase))) * 1e-3


def samples(passes, lead=LEAD, tan=TAN, start_z=4e-3, end_z=-16e-3, radius=6e-3):
    """t, x, z, spindle angle for passes given as (depth(psi), groove phase in revolutions):
    each idles at the clearance, meets the helix at start_z at its groove phase (psi = 0),
    runs half a revolution past end_z, then jumps out and returns in 0.2 s."""
    t_all, x_all, z_all = [], [], []
    t = 0.0
    for depth_of, phase in passes:
        theta_ref = 2 * math.pi * (phase + math.ceil((OMEGA * (t + 0.1)) / (2 * math.pi) - phase))
        idle = np.arange(t, theta_ref / OMEGA, T)
        t_all.append(idle)
        x_all.append(np.full_like(idle, radius + 1e-3))
        z_all.append(np.full_like(idle, start_z))
        t_last = (theta_ref + 2 * math.pi * ((start_z - end_z) / lead + 0.5)) / OMEGA
        t_sync = np.arange(idle[-1] + T if idle.size else t, t_last, T)
        psi = (OMEGA * t_sync - theta_ref) / (2 * math.pi)
        depth = depth_of(psi)
        t_all.append(t_sync)
        x_all.append(radius - depth)
        z_all.append(start_z - lead * psi - depth * tan)
        back = np.arange(t_sync[-1] + T, t_sync[-1] + 0.2, T)
        t_all.append(back)
        x_all.append(np.full_like(back, radius + 1e-3))
        z_all.append(np.linspace(z_all[-1][-1], start_z, back.size))
        t = back[-1] + T
    t = np.concatenate(t_all)
    return t, np.concatenate(x_all), np.concatenate(z_all), OMEGA * t


def analyze(passes, thread=THREAD, **kwargs):
    return analyze_thread(*samples(passes, **kwargs), thread)


THREE = [(constant(0.5), 0.0), (constant(0.9), 0.0), (constant(1.07), 0.0)]


def test_hand_computed_vibrating_pass_against_the_previous_one():
    """Pass 2 runs 0.6 - 0.36*(1 - w(1.5*psi + 1/2)) mm over pass 1's flat 0.3 mm: it is in
    air where 0.36*(1 - w) >= 0.3, i.e. cos(2pi*u) >= 2/3, a share acos(2/3)/pi = 0.2677 of
    each vibration; a chip lasts (1 - 0.2677)/1.5 = 0.4882 revolutions."""
    report = analyze([(constant(0.3), 0.0), (vibrating(0.6, 0.36, 1.5, 0.5), 0.0)])
    first, second = report["passes"]
    assert first["depth_mm"] == pytest.approx(0.3) and first["doc_mm"] == pytest.approx(0.3)
    assert first["max_chip_revs"] == pytest.approx(REVS, abs=RESOLUTION)
    assert first["aircut_share"] == 0.0 and first["vibration_per_rev"] is None
    air = math.acos(2 / 3) / math.pi
    assert second["depth_mm"] == pytest.approx(0.6, abs=1e-4)
    assert second["doc_mm"] == pytest.approx(0.3, abs=1e-4)
    assert second["max_cut_mm"] == pytest.approx(0.3, abs=1e-4)
    assert second["aircut_share"] == pytest.approx(air, abs=0.003)
    assert second["max_chip_revs"] == pytest.approx((1 - air) / 1.5, abs=RESOLUTION)
    assert second["vibration_per_rev"] == pytest.approx(1.5, abs=1e-3)
    assert second["vibration_phase_deg"] == pytest.approx(180.0, abs=0.5)
    assert second["vibration_amplitude_mm"] == pytest.approx(0.36, abs=1e-3)
    assert report["max_chip_revs"] == pytest.approx(REVS, abs=RESOLUTION)  # pass 1 is one chip
    assert not report["chips_broken"]
    assert not report["full_depth"] and report["depth_error_mm"] == pytest.approx(1.07 - 0.3, abs=1e-4)


def test_clean_thread_on_the_helix():
    report = analyze(THREE)
    assert report["synchronised_passes"] == report["cutting_passes"] == 3
    assert [p["doc_mm"] for p in report["passes"]] == pytest.approx([0.5, 0.4, 0.17])
    assert [p["coverage"] for p in report["passes"]] == [1.0] * 3
    assert report["full_depth"] and report["depth_error_mm"] < 1e-9 and report["overcut_mm"] < 1e-9
    assert report["doc_never_grows"]
    assert report["helix_residual_mm"] < 1e-6
    assert report["infeed_angle_deg"] == pytest.approx(29.5, abs=1e-6)
    assert abs((report["helix_phase_deg"] + 180) % 360 - 180) < 1e-6  # the spindle index


def test_spindle_angle_read_wrapped_gives_the_same_report():
    t, x, z, theta = samples(THREE)
    unwrapped = analyze_thread(t, x, z, theta, THREAD)
    wrapped = analyze_thread(t, x, z, np.mod(theta, 2 * math.pi), THREAD)
    for a, b in zip(wrapped["passes"], unwrapped["passes"], strict=True):
        assert a.keys() == b.keys()
        for key in a:
            assert a[key] == (pytest.approx(b[key], abs=1e-9) if isinstance(b[key], float) else b[key])


def test_overcut_and_growing_depth_of_cut_are_reported():
    deep = analyze([(constant(0.5), 0.0), (constant(0.9), 0.0), (constant(1.10), 0.0)])
    assert deep["overcut_mm"] == pytest.approx(0.03) and not deep["full_depth"]
    growing = analyze([(constant(0.3), 0.0), (constant(0.8), 0.0), (constant(1.07), 0.0)])
    assert growing["full_depth"] and not growing["doc_never_grows"]


def test_lead_error_and_phase_drift_show_in_the_helix_residual():
    lead_error = analyze(THREE, lead=1.76e-3)  # 0.01 mm/rev over 9 revolutions
    assert lead_error["synchronised_passes"] == 3 and lead_error["helix_residual_mm"] > 0.03
    drift = [(constant(0.5), 0.0), (constant(0.9), 0.0), (constant(1.07), 6 / 360)]
    drifting = analyze(drift)  # the last pass 6 deg late: 0.029 mm off the groove
    assert drifting["helix_residual_mm"] > 0.015
    assert drifting["passes"][2]["helix_residual_mm"] > drifting["passes"][0]["helix_residual_mm"]


def test_wrong_flank_offset_is_measured():
    report = analyze(THREE, tan=math.tan(math.radians(20.0)))
    assert report["infeed_angle_deg"] == pytest.approx(20.0, abs=0.01)
    assert report["helix_residual_mm"] > 0.05  # (0.566 - 0.364) x depth, less the fitted phase


def test_two_starts_are_two_grooves():
    passes = [(constant(0.5), 0.0), (constant(0.5), 0.5), (constant(1.07), 0.0), (constant(1.07), 0.5)]
    report = analyze(passes, thread=dict(THREAD, starts=2))
    assert [p["start"] for p in report["passes"]] == [0, 1, 0, 1]
    assert [p["doc_mm"] for p in report["passes"]] == pytest.approx([0.5, 0.5, 0.57, 0.57])
    assert report["full_depth"] and report["helix_residual_mm"] < 1e-6
    # read as one start, the second groove is half a lead off the first: a quarter lead
    # off whatever helix is fitted
    assert analyze(passes)["helix_residual_mm"] >= 1.75 / 4 - 1e-6


def test_internal_thread_depth_grows_the_radius():
    t, x, z, theta = samples(THREE, radius=8e-3)
    internal = analyze_thread(t, 16e-3 - x, z, theta, dict(THREAD, major_radius=8.0, internal=True))
    assert internal["full_depth"]
    assert [p["depth_mm"] for p in internal["passes"]] == pytest.approx([0.5, 0.9, 1.07])


def test_no_synchronised_pass_is_an_error():
    t = np.arange(0.0, 1.0, T)
    with pytest.raises(ValueError, match="no synchronised pass"):
        analyze_thread(t, np.full_like(t, 7e-3), 4e-3 - 0.01 * t, OMEGA * t * 0.5, THREAD)
