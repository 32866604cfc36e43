"""The bridge's setpoint buffer: chunk checks, replacement on insert, sampling."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge.setpoints import SetpointBuffer, SetpointError

MILL = load_machine("mill3")
JOINTS = list(MILL.joint_names)  # x, y, z, spindle
MS = 1_000_000
REST = (np.zeros(4), np.zeros(4))


def smooth(t0_ms: int, n: int, d: float = 0.01, duration_ms: int = 500, x0: float = 0.0, begin_ms: int = 0):
    """x follows a quintic rest-to-rest move of d from begin over duration (other joints still).

    Returns names, times (ns), p, v, a for points t0 .. t0 + n - 1 ms of the move.
    """
    k = np.arange(t0_ms, t0_ms + n)
    tau = np.clip((k - begin_ms) / duration_ms, 0.0, 1.0)
    big_t = duration_ms / 1000
    p = np.zeros((n, 4))
    v = np.zeros((n, 4))
    a = np.zeros((n, 4))
    p[:, 0] = x0 + d * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
    v[:, 0] = d / big_t * (30 * tau**2 - 60 * tau**3 + 30 * tau**4)
    a[:, 0] = d / big_t**2 * (60 * tau - 180 * tau**2 + 120 * tau**3)
    return list(JOINTS), (k * MS).astype(np.int64), p, v, a


def still(t0_ms: int, n: int, position=(0.0, 0.0, 0.0, 0.0)):
    times = (np.arange(t0_ms, t0_ms + n) * MS).astype(np.int64)
    p = np.tile(np.asarray(position, float), (n, 1))
    return list(JOINTS), times, p, np.zeros_like(p), np.zeros_like(p)


def add(buffer: SetpointBuffer, chunk, now_ns: int = 0, reference=REST):
    buffer.insert(buffer.validate(*chunk, now_ns, reference))


def refused(buffer: SetpointBuffer, chunk, *words: str, now_ns: int = 0, reference=REST) -> str:
    with pytest.raises(SetpointError) as info:
        buffer.validate(*chunk, now_ns, reference)
    message = str(info.value)
    for word in words:
        assert word in message, message
    return message


# --- validate --------------------------------------------------------------------------------

def test_accepts_a_valid_chunk_and_reorders_joints():
    buffer = SetpointBuffer(MILL)
    names, times, p, v, a = smooth(0, 100)
    order = [3, 2, 0, 1]  # spindle, z, x, y
    points = buffer.validate([names[i] for i in order], times, p[:, order], v[:, order], a[:, order], 0, REST)
    assert points.times_ns.dtype == np.int64
    assert np.array_equal(points.positions, p)
    assert np.array_equal(points.velocities, v)
    assert np.array_equal(points.accelerations, a)
    assert buffer.chunks == type(buffer.chunks)()  # validate does not buffer


def test_refuses_an_unknown_joint():
    names, times, p, v, a = smooth(0, 10)
    names[1] = "w"
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "unknown joint 'w'")


def test_refuses_a_missing_joint():
    names, times, p, v, a = smooth(0, 10)
    refused(SetpointBuffer(MILL), (names[:3], times, p[:, :3], v[:, :3], a[:, :3]), "missing ['spindle']")


def test_refuses_a_joint_named_twice():
    names, times, p, v, a = smooth(0, 10)
    names = names + ["x"]
    p, v, a = (np.hstack([m, m[:, :1]]) for m in (p, v, a))
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "every joint once")


@pytest.mark.parametrize("shift", [(3, 0), (3, -1), (5, -5)])
def test_refuses_times_that_do_not_strictly_increase(shift):
    names, times, p, v, a = smooth(0, 10)
    i, delta = shift
    times = times.copy()
    times[i] = times[i - 1] + delta * MS
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "strictly increase")


@pytest.mark.parametrize("which, value", [(2, np.nan), (3, np.inf), (4, -np.inf)])
def test_refuses_nan_and_infinity(which, value):
    chunk = list(smooth(0, 10))
    chunk[which] = chunk[which].copy()
    chunk[which][5, 1] = value
    refused(SetpointBuffer(MILL), tuple(chunk), "NaN or infinite")


def test_refuses_a_chunk_starting_in_the_past():
    chunk = smooth(100, 10, begin_ms=100)
    message = refused(SetpointBuffer(MILL), chunk, "in the past", now_ns=102 * MS)
    assert "2.000 ms" in message
    SetpointBuffer(MILL).validate(*chunk, 100 * MS, REST)  # starting right now is fine


def test_refuses_a_point_outside_travel():
    names, times, p, v, a = still(0, 10)
    p[7, 2] = 0.1 + 2e-6  # z max is 0.1 m (1 um of tolerance)
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "z setpoint", "outside its travel")
    names, times, p, v, a = still(0, 10, position=(0, 0, 0.1 + 0.5e-6, 0))  # within the tolerance
    SetpointBuffer(MILL).validate(names, times, p, v, a, 0, (p[0], np.zeros(4)))


def test_spindle_has_no_travel():
    names, times, p, v, a = still(0, 2, position=(0, 0, 0, 1e6))
    SetpointBuffer(MILL).validate(names, times, p, v, a, 0, (p[0], np.zeros(4)))


def test_refuses_velocity_beyond_the_limit():
    names, times, p, v, a = smooth(0, 10)
    v[5, 1] = 0.8 * 1.05 + 1e-3  # y: 0.8 m/s plus 5 % slack
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "y velocity", "beyond its limit")


def test_refuses_acceleration_beyond_the_limit():
    names, times, p, v, a = smooth(0, 10)
    a[5, 2] = -11.0  # z: 9.8 m/s^2 plus 5 %
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "z acceleration", "beyond its limit")


def test_refuses_a_jump_inside_a_chunk():
    names, times, p, v, a = still(0, 10)
    p[5:, 0] = 0.001  # 1 mm in 1 ms: more than 0.84 mm an axis may travel
    refused(SetpointBuffer(MILL), (names, times, p, v, a), "x jumps 0.001000 in 1.000 ms")


def test_refuses_a_jump_from_the_buffered_reference():
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 200))  # moving at the end of the buffer
    names, times, p, v, a = smooth(200, 50)
    p[0, 0] += 0.001
    refused(buffer, (names, times, p, v, a), "x jumps")


def test_refuses_a_gap_after_a_moving_setpoint():
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 200))
    refused(buffer, smooth(210, 50), "gap of 11.000 ms")


def test_a_one_point_chunk_may_continue_a_moving_buffer_but_not_after_a_gap():
    # The last chunk of a plan can hold a single point (its end, at rest).
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 100))
    refused(buffer, smooth(102, 1), "gap of 3.000 ms")  # from the last point, at 99 ms
    add(buffer, smooth(100, 1))
    assert buffer.end_ns == 100 * MS


def test_refuses_a_new_trajectory_not_starting_where_the_axes_stand():
    buffer = SetpointBuffer(MILL)
    refused(buffer, smooth(0, 10, x0=0.002), "from rest must start at rest")


def test_refuses_an_empty_chunk():
    names, times, p, v, a = smooth(0, 10)
    refused(SetpointBuffer(MILL), (names, times[:0], p[:0], v[:0], a[:0]), "no points")


def test_accepts_a_contiguous_continuation_and_a_later_start_from_rest():
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 200))
    add(buffer, smooth(200, 400))  # ends at rest at x = 0.01 (t = 500 ms)
    assert buffer.end_ns == 599 * MS
    add(buffer, still(700, 10, position=(0.01, 0, 0, 0)))  # a gap after rest is fine
    assert buffer.end_ns == 709 * MS


# --- insert: replacement ------------------------------------------------------------------

def times_of(buffer):
    return [int(t // MS) for chunk in buffer.chunks for t in chunk.times_ns]


def test_insert_replaces_from_the_first_stamp_inside_a_chunk():
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 100))
    add(buffer, smooth(100, 100))
    add(buffer, smooth(150, 30))  # the same path from 150 ms: a valid replacement
    assert times_of(buffer) == list(range(0, 180))
    assert [len(c.times_ns) for c in buffer.chunks] == [100, 50, 30]


def test_insert_drops_every_chunk_that_starts_later():
    buffer = SetpointBuffer(MILL)
    for start in (0, 100, 200, 300):
        add(buffer, smooth(start, 100))
    add(buffer, smooth(150, 10))
    assert times_of(buffer) == list(range(0, 160))
    assert [len(c.times_ns) for c in buffer.chunks] == [100, 50, 10]


def test_insert_at_a_chunk_boundary_drops_that_chunk():
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(0, 100))
    add(buffer, smooth(100, 100))
    replacement = smooth(100, 20)
    add(buffer, replacement)
    assert [len(c.times_ns) for c in buffer.chunks] == [100, 20]
    assert buffer.chunks[-1].times_ns[0] == 100 * MS


def test_a_chunk_at_the_first_buffered_stamp_replaces_the_whole_buffer():
    # A job canceled before it started: the stop is a single point at the job's start,
    # where the axes still stand.
    buffer = SetpointBuffer(MILL)
    add(buffer, smooth(100, 100, begin_ms=100), now_ns=0)
    add(buffer, smooth(200, 100, begin_ms=100), now_ns=0)
    add(buffer, still(100, 1), now_ns=10 * MS)
    assert times_of(buffer) == [100]
    assert np.all(buffer.chunks[0].positions == 0.0)


def test_a_chunk_after_the_end_is_appended():
    buffer = SetpointBuffer(MILL)
    add(buffer, still(0, 10))
    add(buffer, still(20, 10))
    assert [len(c.times_ns) for c in buffer.chunks] == [10, 10]


# --- sample and level ----------------------------------------------------------------------

def test_sample_holds_the_first_point_before_it_starts():
    buffer = SetpointBuffer(MILL)
    add(buffer, still(100, 5, position=(0.0, 0.0, 0.0, 0.0)))
    add(buffer, smooth(105, 100, begin_ms=105))
    p, v, a = buffer.sample(50 * MS)
    assert np.all(p == 0.0) and np.all(v == 0.0) and np.all(a == 0.0)


def test_sample_at_points_and_between_them():
    buffer = SetpointBuffer(MILL)
    names, times, p, v, a = smooth(0, 300)
    add(buffer, (names, times, p, v, a))
    q, w, b = buffer.sample(120 * MS)
    assert np.array_equal(q, p[120]) and np.array_equal(w, v[120]) and np.array_equal(b, a[120])
    q, w, b = buffer.sample(120 * MS + 250_000)  # a quarter of the way to the next point
    assert q == pytest.approx(0.75 * p[120] + 0.25 * p[121], abs=1e-15)
    assert w == pytest.approx(0.75 * v[120] + 0.25 * v[121], abs=1e-15)
    assert b == pytest.approx(0.75 * a[120] + 0.25 * a[121], abs=1e-12)
    q, _, _ = buffer.sample(299 * MS)
    assert np.array_equal(q, p[299])
    assert buffer.sample(299 * MS + 1) is None


def test_sample_across_chunks_and_drops_consumed_chunks():
    buffer = SetpointBuffer(MILL)
    full = smooth(0, 300)
    for start in (0, 100, 200):
        add(buffer, smooth(start, 100))
    assert len(buffer.chunks) == 3
    for k in (50, 99, 100, 150, 250):
        assert np.array_equal(buffer.sample(k * MS)[0], full[2][k])
    assert len(buffer.chunks) == 1  # the first two were consumed


def test_sample_of_an_empty_buffer_is_none():
    assert SetpointBuffer(MILL).sample(0) is None


def test_level_s():
    buffer = SetpointBuffer(MILL)
    assert buffer.level_s(0) == 0.0 and buffer.end_ns is None
    add(buffer, smooth(100, 400, begin_ms=100))  # last point at 499 ms
    assert buffer.level_s(0) == pytest.approx(0.499)
    assert buffer.level_s(249 * MS) == pytest.approx(0.25)
    assert buffer.level_s(600 * MS) == 0.0
    buffer.clear()
    assert buffer.level_s(0) == 0.0
