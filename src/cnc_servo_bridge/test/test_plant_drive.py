"""The drive model with a plant's losses: transport delay, Coulomb friction, backlash and
encoder noise, against hand-computed behaviour and against the step-by-step model."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge.drive import DriveModel

MILL = load_machine("mill3")
T = 1e-3


def x_drive(**changes) -> DriveModel:
    return DriveModel(MILL, T, ("x",), drives={"x": dataclasses.replace(MILL.drives["x"], **changes)})


def ramp(n: int, speed: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A reference ramp at ``speed`` (m/s) from rest at 0, one row per servo period."""
    t = np.arange(n) * T
    return (speed * t)[:, None], np.full((n, 1), speed), np.zeros((n, 1))


def test_a_delay_shifts_the_response_by_whole_periods():
    plain, late = x_drive(), x_drive(delay=0.003)
    p, v, a = ramp(400)
    fb_plain = plain.run(p, v, a)[0]
    fb_late, _, error = late.run(p, v, a)
    assert np.array_equal(fb_late[3:], fb_plain[:-3])  # the same response, three periods later
    assert np.array_equal(fb_late[:4], np.zeros((4, 1)))  # nothing moves before the command arrives
    assert np.allclose(error, p - fb_late)  # following error against the command as sent


def test_a_delay_runs_the_same_in_blocks_and_in_one_piece():
    whole, blocks = x_drive(delay=0.002), x_drive(delay=0.002)
    p, v, a = ramp(300)
    expected = whole.run(p, v, a)[0]
    got = np.concatenate([blocks.run(p[k:k + 7], v[k:k + 7], a[k:k + 7])[0] for k in range(0, 300, 7)])
    assert np.array_equal(got, expected)


def test_friction_holds_the_axis_until_the_command_breaks_it_away():
    friction = 0.0005  # m/s: kp * e must pass it, i.e. e > 10 um at kp 50
    drive = x_drive(friction=friction, velocity_ff=0.0)
    p = np.full((200, 1), 5e-6)  # asks for 5 um: kp * e = 0.25 mm/s < 0.5 mm/s
    fb = drive.run(p, np.zeros_like(p), np.zeros_like(p))[0]
    assert np.all(fb == 0.0) and drive.state.velocity[0] == 0.0
    p = np.full((2000, 1), 50e-6)  # 50 um: breaks away, stops short by about f / kp = 10 um
    fb = drive.run(p, np.zeros_like(p), np.zeros_like(p))[0]
    assert fb[-1, 0] == pytest.approx(50e-6 - friction / 50.0, abs=1e-6)
    assert abs(drive.state.velocity[0]) < 1e-9  # at rest: the command no longer overcomes the friction


def test_backlash_loses_motion_at_a_reversal_and_the_scale_shows_it():
    backlash = 20e-6
    loose, tight = x_drive(backlash=backlash), x_drive()
    loose.reset(np.zeros(1))
    loose.displace(0, 0.0)
    n = 600
    p = np.concatenate((np.linspace(0, 1e-3, n // 2), np.linspace(1e-3, 0, n // 2)))[:, None]
    v = np.gradient(p[:, 0], T)[:, None]
    a = np.zeros_like(p)
    fb_loose, fb_tight = loose.run(p, v, a)[0], tight.run(p, v, a)[0]
    # the load (what the scale reads) trails the motor by b/2 while moving one way
    assert loose.state.position[0] - loose.state.load[0] == pytest.approx(-backlash / 2, abs=1e-9)
    # the closed loop drives the load where it is told: both end near the reference
    assert abs(fb_loose[-1, 0]) < 30e-6 and abs(fb_tight[-1, 0]) < 30e-6
    assert not np.array_equal(fb_loose, fb_tight)


def test_noise_is_seeded_and_only_where_asked():
    p, v, a = ramp(100)
    one, two = (DriveModel(MILL, T, ("x", "y"), drives={**MILL.drives, "x": dataclasses.replace(
        MILL.drives["x"], noise=1e-6)}, seed=3) for _ in range(2))
    fb1 = one.run(np.hstack([p, p]), np.hstack([v, v]), np.hstack([a, a]))[0]
    fb2 = two.run(np.hstack([p, p]), np.hstack([v, v]), np.hstack([a, a]))[0]
    assert np.array_equal(fb1, fb2)
    assert np.std(fb1[1:, 0] - fb1[1:, 1]) > 2e-7  # x noisy, y (a noiseless encoder) not
    assert np.all(np.abs(np.round(fb1[:, 1] / 1e-7) * 1e-7 - fb1[:, 1]) < 1e-15)


@settings(max_examples=30, deadline=None)
@given(kp=st.floats(10, 120), lag=st.floats(3e-4, 6e-3), ff=st.floats(0.5, 1.0), delay=st.integers(0, 4),
       friction=st.floats(0, 2e-3), backlash=st.floats(0, 5e-5), noise=st.floats(0, 1e-6), seed=st.integers(0, 99))
def test_compiled_plant_equals_the_step_by_step_model(kp, lag, ff, delay, friction, backlash, noise, seed):
    drives = {j: dataclasses.replace(MILL.drives[j], kp=kp, velocity_lag=lag, velocity_ff=ff, delay=delay * T,
                                     friction=friction, backlash=backlash, noise=noise) for j in ("x", "z")}
    rng = np.random.default_rng(seed)
    n = 400
    p = np.cumsum(rng.normal(0, 2e-5, (n, 2)), axis=0)
    v = np.gradient(p, T, axis=0)
    a = np.gradient(v, T, axis=0)
    fast, slow = (DriveModel(MILL, T, ("x", "z"), drives=drives, seed=seed) for _ in range(2))
    measured, velocity, error = fast.run(p, v, a)
    for i in range(n):
        assert np.max(np.abs(slow.state.measured - measured[i])) <= 1e-12
        step_error = slow.step(p[i], v[i], a[i])
        assert np.max(np.abs(step_error - error[i])) <= 1e-12
    assert np.max(np.abs(slow.state.position - fast.state.position)) <= 1e-12


def test_a_snapshot_takes_a_block_again_exactly():
    drive = DriveModel(MILL, T, ("x",), drives={"x": dataclasses.replace(
        MILL.drives["x"], delay=0.002, friction=1e-4, backlash=1e-5, noise=1e-7)}, seed=1)
    p, v, a = ramp(200)
    drive.run(p[:50], v[:50], a[:50])
    saved = drive.snapshot()
    first = drive.run(p[50:], v[50:], a[50:])[0]
    drive.restore(saved)
    again = drive.run(p[50:], v[50:], a[50:])[0]
    assert np.array_equal(first, again)


def test_the_servo_loop_runs_the_plant_and_refuses_a_delay_off_the_servo_grid():
    from cnc_msgs_py.plant import parse_plant
    from cnc_servo_bridge.servo import ServoLoop

    plant = parse_plant({"name": "soft", "drive": {"z": {"kp": 35.0, "delay": 0.002}}}, MILL)
    loop = ServoLoop(MILL, 1_000_000, plant=plant)
    assert loop.plant.name == "soft"
    assert list(loop.drives.kp) == [50.0, 50.0, 35.0, 50.0] and list(loop.drives.delay_steps) == [0, 0, 2, 0]
    odd = parse_plant({"name": "odd", "drive": {"x": {"delay": 0.0015}}}, MILL)
    with pytest.raises(ValueError, match=r"plant odd: drive\.x\.delay: 0\.0015 s is not a whole number of servo periods"):
        ServoLoop(MILL, 1_000_000, plant=odd)
