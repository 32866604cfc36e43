"""The bridge's servo loop: following a reference, alarms, jerk-limited stops, recovery."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from ruckig import ControlInterface, InputParameter, Ruckig, Trajectory

from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge.servo import DRIVES_DISABLED, ServoLoop
from cnc_servo_bridge.setpoints import SetpointError

MILL = load_machine("mill3")
JOINTS = list(MILL.joint_names)
AXES = [MILL.axes[j] for j in JOINTS]
MS = 1_000_000
DT = 1e-3


def ruckig_reference(target=None, velocity=None, duration_s=None):
    """A ruckig trajectory from rest at 0 to a position (or to a velocity) on every joint,
    sampled every 1 ms: arrays p, v, a of shape (n, joints)."""
    inp = InputParameter(len(JOINTS))
    inp.current_position = [0.0] * len(JOINTS)
    inp.max_velocity = [a.max_velocity for a in AXES]
    inp.max_acceleration = [a.max_acceleration for a in AXES]
    inp.max_jerk = [a.max_jerk for a in AXES]
    if velocity is not None:
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity = list(velocity)
    else:
        inp.target_position = list(target)
    trajectory = Trajectory(len(JOINTS))
    Ruckig(len(JOINTS)).calculate(inp, trajectory)
    end = trajectory.duration if duration_s is None else duration_s
    n = int(np.ceil(end / DT)) + 1
    samples = np.array([trajectory.at_time(min(i * DT, trajectory.duration)) for i in range(n)])
    p, v, a = samples[:, 0], samples[:, 1], samples[:, 2]
    if duration_s is not None and duration_s > trajectory.duration:  # cruise on at the target velocity
        late = np.arange(n) * DT > trajectory.duration
        p_end = np.array(trajectory.at_time(trajectory.duration)[0])
        p[late] = p_end + np.outer(np.arange(n)[late] * DT - trajectory.duration, velocity)
    if velocity is None:
        v[-1] = 0.0
        a[-1] = 0.0
    return p, v, a


def feed(loop: ServoLoop, p, v, a, start_ns: int, now_ns: int, chunk: int = 100) -> None:
    """Hand the loop the whole reference in chunks, as the planner would."""
    for i in range(0, len(p), chunk):
        times = start_ns + np.arange(i, min(i + chunk, len(p))) * MS
        loop.accept(JOINTS, times, p[i:i + chunk], v[i:i + chunk], a[i:i + chunk], now_ns)


def run(loop: ServoLoop, t0_ns: int, steps: int):
    """Step the loop; returns times, feedback and the references it followed."""
    times, measured, errors, refs = [], [], [], []
    for k in range(steps):
        t = t0_ns + k * MS
        fb = loop.step(t)
        times.append(t)
        measured.append(fb.positions)
        errors.append(fb.following_error)
        refs.append(tuple(np.array(x, dtype=float) for x in loop.reference))
    ref = tuple(np.array([r[k] for r in refs]) for k in range(3))
    return np.array(times), np.array(measured), np.array(errors), ref


def assert_within_limits(p: np.ndarray, rel: float = 1e-6) -> None:
    for k, axis in enumerate(AXES):
        assert np.abs(np.diff(p[:, k])).max() / DT <= axis.max_velocity * (1 + rel) + 1e-9, axis.name
        assert np.abs(np.diff(p[:, k], 2)).max() / DT**2 <= axis.max_acceleration * (1 + rel) + 1e-6, axis.name
        assert np.abs(np.diff(p[:, k], 3)).max() / DT**3 <= axis.max_jerk * (1 + rel) + 1e-3, axis.name


def test_follows_a_smooth_reference_with_small_following_error():
    p, v, a = ruckig_reference(target=[0.1, 0.05, -0.02, 300.0])
    loop = ServoLoop(MILL, MS)
    feed(loop, p, v, a, start_ns=50 * MS, now_ns=0)
    _, measured, errors, ref = run(loop, 0, 50 + len(p) + 300)
    assert loop.alarm == ""
    limit = np.array([MILL.drives[j].following_error_limit for j in JOINTS])
    assert np.all(np.abs(errors).max(axis=0) < limit / 4)
    assert np.abs(errors[:, :3]).max() < 0.5e-3  # below half a millimetre on every linear axis
    assert np.array_equal(loop.max_following_error, np.abs(errors).max(axis=0))
    # it arrives: within one encoder count of the target, at rest
    assert measured[-1] == pytest.approx([0.1, 0.05, -0.02, 300.0], abs=1e-5)
    assert measured[-1, :3] == pytest.approx([0.1, 0.05, -0.02], abs=1e-7)
    assert np.abs(loop.drives.state.velocity).max() < 1e-4
    # the loop followed the buffered reference: held at the start, then the samples
    assert np.all(ref[0][:50] == 0.0)
    assert np.array_equal(ref[0][50:50 + len(p)], p)
    assert loop.at_rest


def test_acceleration_feed_forward_reduces_the_error():
    p, v, a = ruckig_reference(target=[0.1, 0.0, 0.0, 0.0])
    errors = []
    for accel_ff in (0.0, 1.0):
        drive = dataclasses.replace(MILL.drives["x"], accel_ff=accel_ff)
        machine = dataclasses.replace(MILL, drives={**MILL.drives, "x": drive})
        loop = ServoLoop(machine, MS)
        feed(loop, p, v, a, start_ns=10 * MS, now_ns=0)
        errors.append(np.abs(run(loop, 0, len(p) + 10)[2][:, 0]).max())
    assert errors[1] < errors[0] / 2


def cruising_loop():
    """A loop whose buffer ends while x and y cruise at constant velocity (a = 0)."""
    p, v, a = ruckig_reference(velocity=[0.1, -0.05, 0.0, 0.0], duration_s=0.3)
    assert v[-1] == pytest.approx([0.1, -0.05, 0.0, 0.0]) and np.abs(a[-1]).max() < 1e-12
    loop = ServoLoop(MILL, MS)
    feed(loop, p, v, a, start_ns=10 * MS, now_ns=0)
    return loop, 10 * MS + (len(p) - 1) * MS, p


def test_buffer_underrun_while_moving_raises_an_alarm_and_stops_jerk_limited():
    loop, end_ns, p = cruising_loop()
    times, measured, _, ref = run(loop, 0, 600)
    last = int(np.searchsorted(times, end_ns))
    assert "ran dry" in loop.alarm
    # up to the last buffered point: the reference as sent
    assert np.array_equal(ref[0][10:last + 1], p)
    # then a stop: speed falls monotonically to zero, positions within the axis limits
    speed = np.abs(ref[1][last:, :2])
    assert np.all(np.diff(speed, axis=0) <= 1e-12)
    assert np.all(speed[-1] == 0.0)
    assert_within_limits(ref[0])
    # braking from 0.1 m/s at a = 0: v < A^2/J = 0.48 m/s, so two jerk phases of
    # sqrt(v/J) each, T = 2 sqrt(0.1 / 200) = 44.7 ms on x ...
    braking = 2 * np.sqrt(0.1 / 200.0)
    moving = np.flatnonzero(np.abs(ref[1][:, 0]) > 0.0)
    stop_s = (moving[-1] - last) * DT
    assert stop_s == pytest.approx(braking, abs=1.5 * DT)
    # ... and covers v T / 2 (a symmetric ramp), and no point lies beyond the stop
    rest = ref[0][moving[-1] + 1:, 0]
    assert np.all(rest == rest[0])
    assert rest[0] - p[-1, 0] == pytest.approx(0.1 * braking / 2, rel=0.05)
    # the drives come to rest there
    assert measured[-1, 0] == pytest.approx(rest[0], abs=1e-6)
    assert loop.at_rest and loop.alarm  # the alarm stays latched until it is reset


def test_starved_reports_the_coming_underrun():
    loop, end_ns, _ = cruising_loop()
    assert not loop.starved(0)  # at rest: nothing to starve
    run(loop, 0, 100)
    assert not loop.starved(end_ns) and loop.starved(end_ns + 1)


def test_the_alarm_latches_until_reset_after_the_stop_then_a_new_chunk_runs():
    loop, end_ns, _ = cruising_loop()
    times, _, _, ref = run(loop, 0, int(end_ns / MS) + 5)
    assert loop.alarm and not loop.at_rest  # stopping
    now = int(times[-1]) + MS
    held = ref[0][-1]
    assert not loop.reset_alarm()  # not while the axes still move
    with pytest.raises(SetpointError, match="alarm latched"):
        loop.accept(JOINTS, np.array([now + 10 * MS]), held[None, :], np.zeros((1, 4)), np.zeros((1, 4)), now)
    times, _, _, ref = run(loop, now, 200)
    assert loop.at_rest and loop.alarm
    now = int(times[-1]) + MS
    stopped = ref[0][-1]
    p, v, a = ruckig_reference(target=[-0.01, 0.01, 0.0, 0.0])
    with pytest.raises(SetpointError, match="alarm latched"):  # stopped, but not acknowledged
        loop.accept(JOINTS, now + 20 * MS + np.arange(len(p)) * MS, p + stopped, v, a, now)
    assert loop.reset_alarm() and loop.alarm == ""
    loop.accept(JOINTS, now + 20 * MS + np.arange(len(p)) * MS, p + stopped, v, a, now)
    _, measured, _, _ = run(loop, now, 20 + len(p) + 200)
    assert loop.alarm == ""
    assert measured[-1, :2] == pytest.approx(stopped[:2] + [-0.01, 0.01], abs=1e-7)


def test_disabling_mid_motion_stops_jerk_limited_without_alarm_and_refuses_setpoints():
    loop, _, p = cruising_loop()
    _, _, _, before = run(loop, 0, 200)  # x cruises at 0.1 m/s, y at -0.05 m/s by now
    now = 200 * MS
    loop.disable(now)
    held = before[0][-1]
    with pytest.raises(SetpointError, match="drives disabled"):
        loop.accept(JOINTS, np.array([now + 10 * MS]), held[None, :], np.zeros((1, 4)), np.zeros((1, 4)), now)
    _, measured, _, after = run(loop, now, 300)
    ref = [np.vstack([b, c]) for b, c in zip(before, after)]
    # the stop continues the reference that was followed (no jump), within every limit
    assert_within_limits(ref[0])
    speed = np.abs(after[1][:, 0])
    assert np.all(np.diff(speed) <= 1e-12) and speed[-1] == 0.0
    braking = 2 * np.sqrt(0.1 / 200.0)  # as for the underrun stop above: 44.7 ms on x
    assert np.count_nonzero(speed) * DT == pytest.approx(braking, abs=1.5 * DT)
    assert after[0][-1, 0] - held[0] == pytest.approx(0.1 * braking / 2, rel=0.05)
    assert after[0][-1, 0] < p[-1, 0]  # short of where the buffered setpoints went
    assert measured[-1, :2] == pytest.approx(after[0][-1, :2], abs=1e-6)  # the drives at rest there
    assert loop.alarm == "" and loop.at_rest and not loop.enabled


def test_enabled_again_the_loop_takes_setpoints_from_where_it_stopped():
    loop = ServoLoop(MILL, MS, start_position=np.array([0.1, 0.0, 0.0, 0.0]), enabled=False)
    p, v, a = ruckig_reference(target=[0.02, 0.0, 0.0, 0.0])
    with pytest.raises(SetpointError) as refused:
        feed(loop, p + [0.1, 0, 0, 0], v, a, start_ns=10 * MS, now_ns=0)
    assert str(refused.value) == DRIVES_DISABLED
    _, measured, _, _ = run(loop, 0, 50)  # disabled, it holds and still reports feedback
    assert measured[-1] == pytest.approx([0.1, 0.0, 0.0, 0.0], abs=1e-6)
    loop.enable()
    feed(loop, p + [0.1, 0, 0, 0], v, a, start_ns=60 * MS, now_ns=50 * MS)
    _, measured, _, _ = run(loop, 50 * MS, 10 + len(p) + 200)
    assert measured[-1, 0] == pytest.approx(0.12, abs=1e-6) and loop.alarm == ""


def test_following_error_trip_raises_an_alarm_and_stops():
    tight = dataclasses.replace(MILL.drives["y"], following_error_limit=2e-5)
    machine = dataclasses.replace(MILL, drives={**MILL.drives, "y": tight})
    p, v, a = ruckig_reference(target=[0.0, 0.1, 0.0, 0.0])
    loop = ServoLoop(machine, MS)
    feed(loop, p, v, a, start_ns=10 * MS, now_ns=0)
    times, measured, errors, ref = run(loop, 0, 10 + len(p) + 300)
    assert loop.alarm.startswith("following error on y")
    trip = int(np.argmax(np.abs(errors[:, 1]) > 2e-5))
    assert trip > 10  # on the way, not at the start
    assert np.array_equal(ref[0][:trip + 1], np.vstack([np.zeros((10, 4)), p])[:trip + 1])
    # it stopped short of the target, jerk-limited, and stands still
    assert ref[0][-1, 1] < 0.1
    assert_within_limits(ref[0])
    assert np.all(ref[1][-100:] == 0.0)
    after = np.abs(ref[1][trip:, 1])
    peak = int(np.argmax(after))
    assert np.all(np.diff(after[peak:]) <= 1e-12) and after[-1] == 0.0
    assert loop.at_rest
    # no second alarm: the loop holds where it stopped and the drive settles there
    assert measured[-1, 1] == pytest.approx(ref[0][-1, 1], abs=1e-6)


def test_at_rest_without_a_buffer_holds_without_alarm():
    loop = ServoLoop(MILL, MS, start_position=np.array([0.1, -0.1, 0.05, 2.0]))
    _, measured, errors, ref = run(loop, 0, 100)
    assert loop.alarm == ""
    assert np.all(ref[0] == [0.1, -0.1, 0.05, 2.0])
    assert measured[-1] == pytest.approx([0.1, -0.1, 0.05, 2.0], abs=1e-5)
    assert np.abs(errors).max() <= 1e-5


@pytest.mark.parametrize("start, field", [([0.0, 0.0, 0.0], "3 values for the 4 joints x, y, z, spindle"),
                                          ([0.0, 0.7, 0.0, 0.0], "y at 0.7 is outside its travel")])
def test_a_start_position_that_does_not_fit_the_machine_is_refused(start, field):
    with pytest.raises(ValueError, match=f"start_position: {field}"):
        ServoLoop(MILL, MS, start_position=np.array(start))


# --- stepping in blocks ------------------------------------------------------------------

def twin_loops(chunk_points: int, offset_ns: int = 0, start_ns: int = 5 * MS):
    """Two loops fed the same reference: chunks of ``chunk_points``, stamps ``offset_ns`` off
    the servo grid (so the loop interpolates), starting after a held first point."""
    p, v, a = ruckig_reference(target=[0.05, -0.03, 0.02, 200.0])
    loops = [ServoLoop(MILL, MS), ServoLoop(MILL, MS)]
    for loop in loops:
        feed(loop, p, v, a, start_ns + offset_ns, 0, chunk_points)
    return loops, len(p)


def step_both(single: ServoLoop, block: ServoLoop, steps: int, seed: int, fault=None, hold_in_blocks=False):
    """Single-step one loop, run the other in random block lengths; returns both feedbacks."""
    rng = np.random.default_rng(seed)
    out_single = [single.step(k * MS) for k in range(steps)]
    out_block, k = [], 0
    while k < steps:
        if fault is not None and k == fault[0]:
            fault[1](block)
        limit = fault[0] - k if fault is not None and k < fault[0] else steps - k
        taken = block.run(k * MS, int(min(rng.integers(1, 150), limit)), hold_in_blocks)
        out_block += taken
        k += len(taken)
    return out_single, out_block


def assert_same(out_single, out_block):
    assert len(out_single) == len(out_block)
    for a, b in zip(out_single, out_block):
        assert a.stamp_ns == b.stamp_ns
        assert np.array_equal(a.positions, b.positions)
        assert np.array_equal(a.velocities, b.velocities)
        assert np.array_equal(a.following_error, b.following_error)


@pytest.mark.parametrize("chunk_points, offset_ns", [(100, 0), (37, 0), (100, 400_000)])
def test_blocks_equal_single_steps_exactly(chunk_points, offset_ns):
    (single, block), n = twin_loops(chunk_points, offset_ns)
    out_single, out_block = step_both(single, block, n + 50, seed=chunk_points + offset_ns)
    assert_same(out_single, out_block)
    assert np.array_equal(single.max_following_error, block.max_following_error)
    assert all(np.array_equal(x, y) for x, y in zip(single.reference, block.reference))
    assert block.alarm == single.alarm  # off the grid, the last point is passed moving: the same stop


def test_holding_at_rest_in_blocks_equals_single_steps_exactly():
    """A real-time bridge holds in blocks: before a job (its first point held too), after
    it, and from a start off the grid; the same feedback as stepping one period at a time."""
    for start_ns, offset_ns in ((0, 0), (300 * MS, 400_000)):
        (single, block), n = twin_loops(100, offset_ns, start_ns)
        out_single, out_block = step_both(single, block, start_ns // MS + n + 400, seed=7, hold_in_blocks=True)
        assert_same(out_single, out_block)
        assert all(np.array_equal(x, y) for x, y in zip(single.reference, block.reference))
        assert block.alarm == single.alarm
    held = block.run(len(out_block) * MS, 100, hold_in_blocks=True)
    assert len(held) == 100 and block.at_rest


def test_a_block_ends_at_the_step_that_trips_and_the_stop_follows_as_single_stepped():
    (single, block), n = twin_loops(100)
    hit = 200  # a crash displaces x by 8 mm (beyond its 5 mm limit) before step 200 of both loops

    def crash(loop: ServoLoop) -> None:
        loop.inject("x", 0.008)

    out_single = [single.step(k * MS) for k in range(hit)]
    crash(single)
    out_single += [single.step(k * MS) for k in range(hit, n)]
    _, out_block = step_both(ServoLoop(MILL, MS), block, n, seed=3, fault=(hit, crash))
    assert single.alarm.startswith("following error on x")
    assert block.alarm == single.alarm
    assert_same(out_single, out_block)
