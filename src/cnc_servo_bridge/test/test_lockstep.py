"""When the simulated bridge steps: lockstep with the setpoints, idle time on the wall clock."""
from __future__ import annotations

import numpy as np
from ruckig import InputParameter, Ruckig, Trajectory

from cnc_msgs_py.machine import load_machine
from cnc_servo_bridge.lockstep import IDLE_GRACE_S, RECORDER_TIMEOUT_S, RECORDER_WINDOW_NS, Lockstep, WallPacing
from cnc_servo_bridge.servo import ServoLoop

MILL = load_machine("mill3")
JOINTS = list(MILL.joint_names)
MS = 1_000_000
TIMEOUT_S = 1.0


def move(start: list[float], target: list[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A jerk-limited move from rest to rest, every 1 ms (as a job, or a move of one)."""
    inp = InputParameter(len(JOINTS))
    inp.current_position = start
    inp.target_position = target
    axes = [MILL.axes[j] for j in JOINTS]
    inp.max_velocity = [a.max_velocity for a in axes]
    inp.max_acceleration = [a.max_acceleration for a in axes]
    inp.max_jerk = [a.max_jerk for a in axes]
    trajectory = Trajectory(len(JOINTS))
    Ruckig(len(JOINTS)).calculate(inp, trajectory)
    n = int(np.ceil(trajectory.duration * 1e3)) + 1
    p, v, a = (np.array(x) for x in zip(*(trajectory.at_time(min(i / 1e3, trajectory.duration)) for i in range(n))))
    v[-1], a[-1] = 0.0, 0.0
    return p, v, a


def loaded_loop(points: slice = slice(None), start_x: float = 0.0, target_x: float = 0.02) -> tuple[ServoLoop, int]:
    """A loop at rest at t=0 with (part of) an X move (20 mm unless told) buffered from 10 ms on."""
    p, v, a = move([start_x, 0.0, 0.0, 0.0], [target_x, 0.0, 0.0, 0.0])
    p, v, a = p[points], v[points], a[points]
    loop = ServoLoop(MILL, MS, p[0])
    times = 10 * MS + np.arange(len(p)) * MS
    loop.accept(JOINTS, times, p, v, a, 0)
    return loop, int(times[-1])


def test_a_job_is_stepped_to_its_last_point_without_waiting():
    loop, end_ns = loaded_loop()
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    wall = 0.0
    t = 0
    while t <= end_ns:
        # sim time runs ahead of the wall clock while setpoints are buffered: wall stays put
        assert lockstep.may_step(loop, t, wall), f"waited at {t / 1e9:.3f} s (job ends at {end_ns / 1e9:.3f} s)"
        loop.step(t)
        t += MS
    assert loop.at_rest and not loop.alarm
    # then idle: after a grace, sim time follows the wall clock
    assert not lockstep.may_step(loop, t, wall)
    assert not lockstep.may_step(loop, t, wall + IDLE_GRACE_S)
    assert lockstep.may_step(loop, t, wall + IDLE_GRACE_S + 1.5e-3)


def test_a_stream_that_ran_out_at_rest_continues_within_the_grace():
    """A job paused at rest right at the end of a chunk: the next chunk, sent as the
    planner sees the last feedback, starts at the step not taken yet and is accepted."""
    loop, end_ns = loaded_loop()
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    t = 0
    while lockstep.may_step(loop, t, 0.0):
        loop.step(t)
        t += MS
    assert t == end_ns + MS  # ran out at rest: waiting
    p, v, a = move([0.02, 0.0, 0.0, 0.0], [0.0] * 4)
    loop.accept(JOINTS, t + np.arange(len(p)) * MS, p, v, a, now_ns=t)
    assert lockstep.may_step(loop, t, IDLE_GRACE_S / 2)


def test_a_stream_cut_short_while_moving_waits_then_runs_dry():
    loop, end_ns = loaded_loop(slice(0, 60))  # the planner fell silent mid-move
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    t = 0
    while t <= end_ns:
        assert lockstep.may_step(loop, t, 0.0)
        loop.step(t)
        t += MS
    assert not loop.at_rest
    assert not lockstep.may_step(loop, t, 0.0)  # waits for setpoints...
    assert not lockstep.may_step(loop, t, TIMEOUT_S - 1e-3)
    assert lockstep.may_step(loop, t, TIMEOUT_S)  # ...for the underrun timeout, then steps
    loop.step(t)
    assert loop.alarm.startswith("setpoint buffer ran dry")


def test_idle_sim_time_follows_the_wall_clock():
    loop = ServoLoop(MILL, MS)
    lockstep = Lockstep(MS, TIMEOUT_S, 5 * MS, wall_s=100.0)
    assert not lockstep.may_step(loop, 5 * MS, 100.0)
    assert lockstep.may_step(loop, 5 * MS, 100.001)
    assert not lockstep.may_step(loop, 15 * MS, 100.005)  # 10 ms of sim after 5 ms of wall
    assert lockstep.may_step(loop, 15 * MS, 100.0115)


def long_move_loop() -> tuple[ServoLoop, int]:
    """A 0.9 m X move (about 1.3 s): longer than the recorder's window."""
    return loaded_loop(start_x=-0.45, target_x=0.45)


def test_the_clock_waits_for_a_slow_recorder_and_runs_on_as_it_catches_up():
    loop, end_ns = long_move_loop()
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    lockstep.recorded(0, wall_s=0.0)  # a recorder has written the sample at 0
    t, wall = 0, 0.0
    while lockstep.may_step(loop, t, wall):
        loop.step(t)
        t += MS
    assert t == RECORDER_WINDOW_NS + MS < end_ns  # held one window ahead of the recorder
    wall = 0.5 * RECORDER_TIMEOUT_S
    assert not lockstep.may_step(loop, t, wall)  # still held: the recorder is slow, not gone
    lockstep.recorded(100 * MS, wall)  # it caught up 100 ms
    for _ in range(100):
        assert lockstep.may_step(loop, t, wall)
        loop.step(t)
        t += MS
    assert not lockstep.may_step(loop, t, wall)


def test_a_recorder_that_fell_silent_no_longer_holds_the_clock():
    loop, _ = long_move_loop()
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    lockstep.recorded(0, wall_s=0.0)
    t = RECORDER_WINDOW_NS + MS
    assert not lockstep.may_step(loop, t, RECORDER_TIMEOUT_S)
    assert lockstep.may_step(loop, t, RECORDER_TIMEOUT_S + 0.01)  # gone: the machine runs on


def test_idle_time_held_by_a_recorder_runs_on_from_where_it_was_held():
    """A recorder that stops reading holds the idle clock, then counts as gone: time runs
    on from there at the wall's pace. Catching up the wall in one burst moved the clock a
    second past what the planner had read, and the job it scheduled started in the past."""
    loop = ServoLoop(MILL, MS)
    lockstep = Lockstep(MS, TIMEOUT_S, 0, wall_s=0.0)
    lockstep.recorded(0, wall_s=0.0)
    t, wall = 0, 0.0
    while wall < 0.5:
        while lockstep.may_step(loop, t, wall):
            loop.step(t)
            t += MS
        wall += 1e-3
    assert t == RECORDER_WINDOW_NS + MS  # held one window ahead of the recorder
    for wall in np.arange(0.5, RECORDER_TIMEOUT_S + 0.3, 1e-3):  # held, then the recorder gone
        while lockstep.may_step(loop, t, wall):
            loop.step(t)
            t += MS
    held_wall = RECORDER_TIMEOUT_S  # the last wall time the recorder still held the clock
    stepped_since = (t - RECORDER_WINDOW_NS - MS) / 1e9
    assert abs(stepped_since - (wall - held_wall)) < 3e-3, f"{stepped_since:.3f} s of sim in {wall - held_wall:.3f} s of wall"


def test_real_time_steps_after_a_stall_let_the_queued_chunk_in_before_running_dry():
    """The bridge stalled 200 ms mid-move; the steps due reach past the buffer. It steps to
    the buffer's end, steps nothing once (the executor then delivers the queued chunk), and
    goes on with it; without a chunk it runs dry on its next turn."""
    for chunk_queued in (True, False):
        loop, end_ns = loaded_loop(slice(0, 60))
        pacing = WallPacing(MS)
        now = end_ns + 200 * MS
        t = 0
        while (due := pacing.steps_due(loop, t, now)) > 0:
            t += MS * len(loop.run(t, due))
        assert t == end_ns + MS and not loop.alarm  # stepped to the buffer's end, no further
        if chunk_queued:
            p, v, a = (x[60:] for x in move([0.0, 0.0, 0.0, 0.0], [0.02, 0.0, 0.0, 0.0]))
            loop.accept(JOINTS, t + np.arange(len(p)) * MS, p, v, a, now_ns=t)
        while (due := pacing.steps_due(loop, t, now)) > 0:
            t += MS * len(loop.run(t, due))
        assert t == now  # caught up with the wall clock
        assert bool(loop.alarm) is not chunk_queued, loop.alarm
