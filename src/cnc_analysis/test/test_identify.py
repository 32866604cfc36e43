"""Drive identification (cnc_analysis.identify): the reference rebuilt exactly as the bridge
sampled it, and drives drawn inside and somewhat beyond the default tolerance recovered from
their simulated feedback on a tuning-routine excitation (kp and velocity_lag within 5 %, the
delay exact), Coulomb friction and backlash where the plant has them."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnc_analysis.identify import MAX_DELAY_PERIODS, Trace, identify, reference, trace
from cnc_analysis.recording import Chunk, Run
from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge.drive import DriveModel
from cnc_servo_bridge.setpoints import SetpointBuffer, Setpoints

PERIOD = 1e-3
MS = 1_000_000
MILL = load_machine("mill3")


def _move(distance: float, duration: float) -> tuple[np.ndarray, ...]:
    """A smooth point-to-point move (sine-jerk velocity bell) sampled every servo period."""
    s = np.arange(round(duration / PERIOD) + 1) * PERIOD / duration
    two_pi = 2 * np.pi
    return (distance * (s - np.sin(two_pi * s) / two_pi), distance / duration * (1 - np.cos(two_pi * s)),
            distance / duration ** 2 * two_pi * np.sin(two_pi * s))


def excitation() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a calibration job does to one axis (m): short and long moves both ways, a creep
    and a medium feed, a pause after each so the loop settles."""
    p, v, a, at = [np.zeros(50)], [np.zeros(50)], [np.zeros(50)], 0.0
    for distance, duration in ((0.001, 0.06), (-0.001, 0.06), (-0.2, 0.6), (0.2, 0.6), (0.0005, 0.8),
                               (-0.0005, 0.8), (0.015, 0.4), (-0.015, 0.4)):
        dp, dv, da = _move(distance, duration)
        p += [at + dp, np.full(100, at + distance)]
        v += [dv, np.zeros(100)]
        a += [da, np.zeros(100)]
        at += distance
    return tuple(np.concatenate(x) for x in (p, v, a))


def recorded(drives: dict, seed: int = 0) -> Trace:
    """The excitation on x, y and z, fed through the plant as the bridge runs it, as a trace."""
    joints = ("x", "y", "z")
    p, v, a = (np.column_stack([x] * 3) for x in excitation())
    p = p + np.array(MILL.home_position[:3])
    feedback = DriveModel(MILL, PERIOD, joints, drives={**MILL.drives, **drives}, seed=seed).simulate(p, v, a)
    return Trace.of(PERIOD, joints, (p, v, a), feedback, "synthetic")


def test_reference_is_what_the_bridge_sampled():
    """Stamp by stamp the reference equals SetpointBuffer.sample's: on the grid, between the
    points of a chunk with a coarser spacing, held at rest in a gap, before the first point."""
    rng = np.random.default_rng(3)
    buffer = SetpointBuffer(MILL)
    chunks = [(100 * MS, MS, 50), (150 * MS, MS, 30), (300 * MS, 4 * MS, 20)]
    times, rows = [], []
    for start, spacing, count in chunks:
        t = start + np.arange(count, dtype=np.int64) * spacing
        values = [rng.normal(size=(count, 4)) * 1e-3 for _ in range(3)]
        values[1][-1] = 0.0 if start == 150 * MS else values[1][-1]  # the second chunk ends at rest
        buffer.insert(Setpoints(t, *values))
        times.append(t)
        rows.append(values)
    stamps = np.arange(0, 400 * MS, MS, dtype=np.int64)
    command = tuple(np.concatenate([r[i] for r in rows]) for i in range(3))
    p, v, a, known = reference(np.concatenate(times), command, np.array([c[0] for c in chunks]), stamps)
    held = (command[0][0], np.zeros(4), np.zeros(4))
    for i, stamp in enumerate(stamps):
        sampled = buffer.sample(int(stamp))
        if sampled is None:  # in a gap: the bridge holds its last reference at rest
            sampled = (held[0], np.zeros(4), np.zeros(4))
            assert known[i] == (stamp < 300 * MS)  # past the last chunk, which ends moving: a stop
        held = sampled
        if known[i]:
            for ours, bridge in zip((p[i], v[i], a[i]), sampled):
                np.testing.assert_array_equal(ours, bridge)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kp=st.floats(0.6, 1.4), lag=st.floats(1.0, 3.0), ff=st.floats(0.9, 1.0), delay=st.integers(0, 3),
       noise=st.floats(0.0, 2e-7), seed=st.integers(0, 100))
def test_drawn_plants_are_recovered(kp, lag, ff, delay, noise, seed):
    drives = {j: dataclasses.replace(MILL.drives[j], kp=MILL.drives[j].kp * kp, velocity_ff=ff, noise=noise,
                                     velocity_lag=MILL.drives[j].velocity_lag * lag, delay=delay * PERIOD)
              for j in ("x", "y", "z")}
    fits = identify([recorded(drives, seed)], MILL)
    for joint, drive in drives.items():
        fitted = fits[joint].drive
        assert fitted is not None, fits[joint].note
        assert abs(fitted.kp / drive.kp - 1) < 0.05
        assert abs(fitted.velocity_lag / drive.velocity_lag - 1) < 0.05
        assert abs(fitted.velocity_ff - ff) < 0.01
        assert fitted.delay == delay * PERIOD
        assert fitted.friction == 0.0 and fitted.backlash == 0.0
        assert fits[joint].residual_fitted[0] < 0.25 + 6 * noise * 1e6  # um: an encoder step or two, and the noise
        assert fitted.tolerance.delay == (0.0, 0.0) and fitted.tolerance.kp == (0.98, 1.02)


def test_friction_and_backlash_are_found_where_the_plant_has_them():
    worn = {j: dataclasses.replace(MILL.drives[j], friction=3e-4, backlash=4e-6, noise=1e-7) for j in ("x", "y", "z")}
    fits = identify([recorded(worn, seed=1)], MILL)
    for joint in worn:
        fitted = fits[joint].drive
        assert abs(fitted.friction / 3e-4 - 1) < 0.05
        assert abs(fitted.backlash / 4e-6 - 1) < 0.1
        assert abs(fits[joint].noise / 1e-7 - 1) < 0.2
        assert abs(fitted.kp / 50.0 - 1) < 0.05 and abs(fitted.velocity_lag / 1e-3 - 1) < 0.05
        assert fits[joint].residual_fitted[1] < fits[joint].residual_described[1]
        assert fitted.tolerance.friction == 3e-5 and fitted.tolerance.backlash > 0


def test_an_axis_that_never_moves_keeps_its_description():
    trace = recorded({})
    trace.w[:, 1] = 0.0  # y never moved
    fits = identify([trace], MILL)
    assert fits["y"].drive is None and "not excited" in fits["y"].note
    assert fits["x"].drive is not None


def test_a_recording_is_used_up_to_its_alarm():
    """A following error trips the bridge's alarm: from there it stops the axes on a reference
    of its own while the recorded setpoints go on. The trace ends at the trip, judged on the
    recording as the bridge judges it, and the fit is the plant's all the same."""
    slow = {j: dataclasses.replace(MILL.drives[j], velocity_lag=0.003, delay=0.002) for j in ("x", "y", "z")}
    synthetic = recorded(slow)
    rows = slice(MAX_DELAY_PERIODS, None)
    error = np.abs(synthetic.p[rows, 0] - synthetic.y[:, 0])
    limit = 0.8 * error.max()
    machine = dataclasses.replace(MILL, drives={**MILL.drives, "x": dataclasses.replace(
        MILL.drives["x"], following_error_limit=limit)})
    alarm = int(np.argmax(error > limit))
    y, w = synthetic.y.copy(), synthetic.w.copy()
    w[alarm + 1:] = w[alarm] * 0.97 ** np.arange(1, len(w) - alarm)[:, None]  # the bridge's own stop
    y[alarm + 1:] = y[alarm] + np.cumsum(w[alarm + 1:], axis=0) * PERIOD
    stamps = np.arange(len(y), dtype=np.int64) * MS
    run = Run(joints=("x", "y", "z"), feedback_t=stamps / 1e9, feedback=y, feedback_velocity=w,
              command_t=stamps / 1e9, command=synthetic.p[rows], command_velocity=synthetic.v[rows],
              command_acceleration=synthetic.a[rows], chunks=[Chunk(0, int(stamps[-1]), len(stamps), False)],
              statuses=[{"state": "aborted", "stamp_ns": (alarm + 30) * MS}])
    cut = trace(run, machine)
    assert cut.known[rows][:alarm].all() and not cut.known[rows][alarm:].any()
    fits = identify([cut], machine)
    for joint in slow:
        assert fits[joint].drive is not None, fits[joint].note
        assert fits[joint].drive.velocity_lag == pytest.approx(0.003, rel=1e-3)
        assert fits[joint].drive.delay == pytest.approx(0.002, abs=1e-12)
        assert fits[joint].residual_fitted[0] < 0.25
