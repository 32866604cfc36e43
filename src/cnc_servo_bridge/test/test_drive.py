"""Servo drive model against hand-computed steps.

mill3's x drive: kp = 50 1/s, velocity_ff = 1, accel_ff = 0, velocity_lag = 1 ms,
resolution 0.1 um; axis limits 0.8 m/s, 9.8 m/s^2. With a 1 ms servo period the
velocity loop decays by exp(-T / lag) = exp(-1) per step.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge import _drive_kernel
from cnc_servo_bridge.drive import ACCELERATION_HEADROOM, VELOCITY_HEADROOM, DriveModel

MILL = load_machine("mill3")
T = 1e-3
DECAY = math.exp(-1.0)
RES = 1e-7


def x_drive(machine=MILL) -> DriveModel:
    return DriveModel(machine, T, ("x",))


def with_x_drive(**changes):
    drive = dataclasses.replace(MILL.drives["x"], **changes)
    return dataclasses.replace(MILL, drives={**MILL.drives, "x": drive})


def step(model: DriveModel, p: float, v: float = 0.0, a: float = 0.0) -> float:
    return float(model.step(np.array([p]), np.array([v]), np.array([a]))[0])


def test_constants_from_the_machine():
    model = DriveModel(MILL, T)
    assert model.joints == ("x", "y", "z", "spindle")
    assert model.decay == pytest.approx([DECAY, DECAY, DECAY, math.exp(-0.5)])
    assert model.v_limit == pytest.approx([0.96, 0.96, 0.72, 1256.4])  # 1.2 * max velocity
    assert model.dv_limit == pytest.approx([0.0147, 0.0147, 0.0147, 0.75])  # 1.5 * max accel * T
    assert (VELOCITY_HEADROOM, ACCELERATION_HEADROOM) == (1.2, 1.5)


def test_first_step_from_rest_for_a_step_reference():
    model = x_drive()
    r = 1e-5  # 10 um step
    error = step(model, r)
    assert error == r  # measured 0 before the step
    v_cmd = 50.0 * r  # 5e-4 m/s, far below the clamp
    v1 = v_cmd * (1 - DECAY)  # 3.1606e-4 m/s after one lag step
    p1 = 0.5 * v1 * T  # trapezoid: 1.5803e-7 m
    assert model.state.velocity[0] == pytest.approx(v1, rel=1e-12)
    assert model.state.position[0] == pytest.approx(p1, rel=1e-12)
    assert p1 == pytest.approx(1.5803e-7, rel=1e-4)
    assert model.state.measured[0] == pytest.approx(2e-7, abs=1e-18)  # quantised to 0.1 um


def test_second_step_hand_computed():
    model = x_drive()
    r = 1e-5
    step(model, r)
    v1, p1 = model.state.velocity[0], model.state.position[0]
    error = step(model, r)
    assert error == pytest.approx(r - 2e-7, abs=1e-18)  # against the quantised reading
    v_cmd = 50.0 * (r - 2e-7)
    v2 = v_cmd + (v1 - v_cmd) * DECAY
    assert model.state.velocity[0] == pytest.approx(v2, rel=1e-12)
    assert model.state.position[0] == pytest.approx(p1 + 0.5 * (v1 + v2) * T, rel=1e-12)


def test_velocity_feed_forward_first_step():
    # No position error, v_ref = 10 mm/s: v_cmd = v_ref, the lag lets (1 - e^-1) through.
    model = x_drive()
    step(model, 0.0, v=0.01)
    assert model.state.velocity[0] == pytest.approx(0.01 * (1 - DECAY), rel=1e-12)
    assert model.state.position[0] == pytest.approx(0.5 * 0.01 * (1 - DECAY) * T, rel=1e-12)


def test_acceleration_feed_forward_first_step():
    model = x_drive(with_x_drive(accel_ff=1.0))
    step(model, 0.0, v=0.01, a=2.0)
    v_cmd = 0.01 + 1.0 * 0.001 * 2.0  # velocity_ff v + accel_ff * lag * a = 0.012
    assert model.state.velocity[0] == pytest.approx(v_cmd * (1 - DECAY), rel=1e-12)


def test_zero_steady_state_error_at_constant_velocity():
    v = 0.05  # 3000 mm/min
    n = 600
    t = np.arange(n) * T
    p_ref = (v * t)[:, None]
    v_ref = np.full_like(p_ref, v)
    model = x_drive()
    measured, velocity = model.simulate(p_ref, v_ref, np.zeros_like(p_ref))
    error = p_ref[:, 0] - measured[:, 0]
    # v_cmd = v + kp e settles where e = 0; only the encoder's quantisation remains
    assert np.abs(error[300:]).max() <= RES / 2 + 1e-12
    assert velocity[-1, 0] == pytest.approx(v, rel=1e-6)
    assert abs(model.state.position[0] - v * n * T) <= RES / 2  # the truth, within a count
    # the start is the transient: the drive began at rest while the reference moved
    assert np.abs(error).max() > 10 * RES


def test_without_velocity_feed_forward_the_error_is_v_over_kp():
    v = 0.05
    p_ref = (v * np.arange(600) * T)[:, None]
    model = x_drive(with_x_drive(velocity_ff=0.0))
    measured, _ = model.simulate(p_ref, np.full_like(p_ref, v), np.zeros_like(p_ref))
    error = p_ref[-100:, 0] - measured[-100:, 0]
    # kp e = v in steady state: e = 0.05 / 50 = 1 mm (less half a period of travel,
    # as the trapezoid integrates the lag: v T / 2 relative to the sampled reference)
    assert error.mean() == pytest.approx(v / 50.0, abs=RES + v * T)
    assert np.ptp(error) <= 2 * RES


def test_quantisation_to_the_resolution():
    model = DriveModel(MILL, T)
    values = np.array([1.26e-7, -3.44e-7, 0.1234567891, 1.234567e-3])
    q = model.quantise(values)
    assert q[0] == pytest.approx(1e-7, abs=1e-20)
    assert q[1] == pytest.approx(-3e-7, abs=1e-20)
    assert q[2] == pytest.approx(0.1234568, abs=1e-15)
    assert q[3] == pytest.approx(1.23e-3, abs=1e-15)  # spindle: 1e-5 rad steps
    state = model.reset(np.array([0.01234567891, 0.0, -0.2, 3.14159265]))
    assert state.position[0] == 0.01234567891  # the truth is not quantised
    assert state.measured[0] == pytest.approx(0.0123457, abs=1e-15)
    assert state.measured[3] == pytest.approx(3.14159, abs=1e-12)
    assert np.all(state.velocity == 0.0)


def test_limits_clamp_velocity_and_acceleration():
    model = x_drive()
    step(model, 1.0)  # a 1 m step: v_cmd 50 m/s -> clamped
    dv = 1.5 * 9.8 * T  # 0.0147 m/s per step
    assert model.state.velocity[0] == pytest.approx(dv, rel=1e-12)
    assert model.state.position[0] == pytest.approx(0.5 * dv * T, rel=1e-12)
    velocities = [model.state.velocity[0]]
    for _ in range(200):
        step(model, 1.0)
        velocities.append(model.state.velocity[0])
    velocities = np.array(velocities)
    assert np.all(np.diff(velocities) <= dv * (1 + 1e-12))
    assert velocities.max() <= 0.96 * (1 + 1e-12)
    # the velocity loop converges on the clamped command: 1.2 * 0.8 m/s
    assert velocities[-1] == pytest.approx(0.96, rel=1e-9)


def test_negative_step_clamps_symmetrically():
    model = x_drive()
    step(model, -1.0)
    assert model.state.velocity[0] == pytest.approx(-0.0147, rel=1e-12)


def test_simulate_reports_the_reading_before_each_step():
    model = x_drive()
    p_ref = np.array([[0.0], [1e-5], [1e-5]])
    measured, velocity = model.simulate(p_ref, np.zeros_like(p_ref), np.zeros_like(p_ref))
    # row i is read before step i: the step to 1e-5 (row 1) shows from row 2 on
    assert measured[:, 0] == pytest.approx([0.0, 0.0, 2e-7], abs=1e-18)
    assert velocity[1, 0] == 0.0
    assert velocity[2, 0] == pytest.approx(50.0 * 1e-5 * (1 - DECAY), rel=1e-12)


def test_joints_are_independent():
    model = DriveModel(MILL, T, ("x", "z"))
    model.step(np.array([1e-5, 0.0]), np.zeros(2), np.zeros(2))
    assert model.state.position[1] == 0.0 and model.state.position[0] > 0.0


def _reference_run(model: DriveModel, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The step-by-step reference: measured position before each step."""
    out = np.empty_like(p)
    for i in range(len(p)):
        out[i] = model.state.measured
        model.step(p[i], v[i], a[i])
    return out


@pytest.mark.parametrize("joints", [("x", "y", "z", "spindle"), ("x", "z")])  # the kernel's two-joint loop
@pytest.mark.parametrize("seed", range(6))
def test_compiled_kernel_equals_the_step_by_step_model(seed, joints):
    """Random references on random drives, hard enough to hit the velocity clamp, the
    acceleration rate limit and every encoder resolution, give the same positions, on
    every joint of the mill and on two of them (the thread cycle's pair)."""
    rng = np.random.default_rng(seed)
    drives = {j: dataclasses.replace(MILL.drives[j], kp=float(rng.uniform(10, 150)),
                                     velocity_ff=float(rng.uniform(0, 1)), accel_ff=float(rng.uniform(0, 1)),
                                     velocity_lag=float(rng.uniform(2e-4, 1e-2)),
                                     resolution=float(10 ** rng.uniform(-8, -5)))
              for j in MILL.joint_names}
    machine = dataclasses.replace(MILL, drives=drives)
    n = 3000
    # Steps and ramps of up to 0.2 m: far beyond what the clamps let the drive follow.
    p = np.cumsum(rng.normal(0, 1e-3, (n, 4)), axis=0) + np.repeat(rng.uniform(-0.2, 0.2, (n // 500, 4)), 500, axis=0)
    v = rng.normal(0, 0.5, (n, 4))
    a = rng.normal(0, 20, (n, 4))
    start = rng.uniform(-0.1, 0.1, 4)
    columns = [MILL.joint_names.index(j) for j in joints]
    p, v, a, start = p[:, columns], v[:, columns], a[:, columns], start[columns]
    reference, fast = DriveModel(machine, T, joints), DriveModel(machine, T, joints)
    reference.reset(start)
    fast.reset(start)
    expected = _reference_run(reference, p, v, a)
    measured, velocity, error = fast.run(p, v, a)
    assert np.max(np.abs(measured - expected)) <= 1e-12
    assert np.max(np.abs(fast.state.position - reference.state.position)) <= 1e-12
    assert np.max(np.abs(error - (p - expected))) <= 1e-12
    # The clamps were active: the model did not just follow a linear filter.
    linear = [i for i, j in enumerate(joints) if j != "spindle"]
    assert np.max(np.abs(np.diff(velocity, axis=0))) >= 0.999 * np.min(fast.dv_limit[linear])
    assert np.max(np.abs(velocity[:, linear])) >= 0.999 * np.min(fast.v_limit[linear])


def _kernel_arguments(rows: int, joints: int) -> list:
    """Arguments of the C kernel in its order: references, state, gains, period, out."""
    refs = [np.zeros((rows, joints)) for _ in range(3)]
    return [*refs, *(np.zeros(joints) for _ in range(3)), *(np.ones(joints) for _ in range(7)), T,
            np.empty((3, rows, joints))]


def _read_only(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@pytest.mark.parametrize("argument, replacement, error, message", [
    (1, np.zeros((4, 2)), ValueError, "v_ref: expected 10 values, got 8"),
    (14, np.empty((3, 4, 2)), ValueError, "out: expected 30 values, got 24"),
    (6, np.ones(3), ValueError, "kp: expected 2 values, got 3"),
    (0, np.zeros((5, 3)), ValueError, "p_ref: 15 values are not rows of 2 joints"),
    (2, np.zeros((5, 2), dtype=np.float32), TypeError, "a_ref: expected a float64 array"),
    (1, np.zeros((2, 5)).T, ValueError, "not C-contiguous"),
    (4, _read_only(np.zeros(2)), ValueError, "read-only"),  # the kernel writes the state in place
])
def test_the_compiled_kernel_refuses_arrays_it_would_overrun(argument, replacement, error, message):
    """The kernel works through raw pointers: every array's size, type and layout is
    checked before it runs, so a wrong one raises instead of corrupting memory."""
    args = _kernel_arguments(5, 2)
    args[argument] = replacement
    with pytest.raises(error, match=message):
        _drive_kernel.run(*args)
    _drive_kernel.run(*_kernel_arguments(5, 2))  # the same call with every array right runs


def test_the_kernel_steps_any_number_of_joints_alike():
    """The kernel keeps up to six joints in registers and steps more one after another per
    row: seven joints at once give, bit for bit, what each gives alone (joints share nothing)."""
    rng = np.random.default_rng(7)
    rows, joints = 2000, 7
    refs = [np.cumsum(rng.normal(0, 1e-3, (rows, joints)), axis=0), rng.normal(0, 0.5, (rows, joints)),
            rng.normal(0, 20, (rows, joints))]
    start = [rng.uniform(-0.1, 0.1, joints), np.zeros(joints), np.zeros(joints)]
    gains = [rng.uniform(10, 150, joints), rng.uniform(0, 1, joints), rng.uniform(0, 1e-2, joints),
             rng.uniform(0.5, 0.99, joints), np.full(joints, 0.5), np.full(joints, 5e-3),
             10 ** rng.uniform(-8, -5, joints)]
    together = np.empty((3, rows, joints))
    _drive_kernel.run(*(x.copy() for x in refs), *(x.copy() for x in start), *gains, T, together)
    for j in range(joints):
        alone = np.empty((3, rows, 1))
        _drive_kernel.run(*(np.ascontiguousarray(x[:, j:j + 1]) for x in refs), *(x[j:j + 1].copy() for x in start),
                          *(g[j:j + 1] for g in gains), T, alone)
        assert np.array_equal(alone[..., 0], together[..., j])
    assert np.ptp(together[0], axis=0).min() > 0.0  # every joint moved


def test_simulate_starts_at_rest_at_the_first_reference():
    model = x_drive()
    p = np.linspace(0.01, 0.02, 50)[:, None]
    v = np.full_like(p, 0.2)
    positions, velocities = model.simulate(p, v, np.zeros_like(p))
    assert positions[0, 0] == pytest.approx(0.01, abs=RES)
    assert velocities[0, 0] == 0.0
    assert np.all(np.diff(positions[:, 0]) >= 0)


@pytest.mark.parametrize("delays_ms", [(0.0, 0.0, 0.0), (0.0, 1.0, 2.0)])
def test_shared_references_give_what_references_copied_to_every_column_give(delays_ms):
    """run_shared reads each column's joint reference in place, its delay later: over blocks
    (references in transit between them) it gives, bit for bit, run's positions, velocities
    and following errors on the references copied to every column."""
    rng = np.random.default_rng(3)
    drives = [dataclasses.replace(MILL.drives["x"], kp=float(rng.uniform(20, 120)), delay=d * 1e-3,
                                  velocity_lag=float(rng.uniform(5e-4, 5e-3))) for d in delays_ms]
    columns = [(j, d) for d in drives for j in ("x", "y")]
    source = np.tile(np.arange(2), len(drives))
    n = 2500
    p = np.cumsum(rng.normal(0, 1e-4, (n, 2)), axis=0)
    v, a = rng.normal(0, 0.05, (n, 2)), rng.normal(0, 3, (n, 2))
    copied, shared = DriveModel.columns(MILL, T, columns), DriveModel.columns(MILL, T, columns)
    for model in (copied, shared):
        model.reset(p[0][source])
    for lo in range(0, n, 700):
        block = [x[lo:lo + 700] for x in (p, v, a)]
        for one, other in zip(copied.run(*(x[:, source] for x in block)), shared.run_shared(*block, source)):
            assert np.array_equal(one, other)
    assert np.array_equal(copied.state.position, shared.state.position)


def test_a_velocity_below_the_smallest_normal_double_is_zero():
    """A velocity decaying at rest would stick at the smallest subnormal (0.61 of it rounds
    back up to it); the model makes it zero, the compiled kernel as the step model does."""
    model = x_drive()
    model.reset(np.zeros(1))
    model.state.velocity = np.array([5e-300])
    for _ in range(2000):
        model.step(np.zeros(1), np.zeros(1), np.zeros(1))
    assert model.state.velocity[0] == 0.0
    fast = x_drive()
    fast.reset(np.zeros(1))
    fast.state.velocity = np.array([5e-300])
    _, velocity, _ = fast.run(np.zeros((2000, 1)), np.zeros((2000, 1)), np.zeros((2000, 1)))
    assert velocity[-1, 0] == 0.0 and np.all((velocity == 0.0) | (np.abs(velocity) >= np.finfo(float).tiny))
