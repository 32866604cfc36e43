"""When the bridge may take its next servo steps.

In real time (WallPacing) the steps follow the wall clock. In simulation (Lockstep) the
bridge owns time. While the axes move it steps as fast as setpoints
allow and waits for the planner (up to ``underrun_timeout`` of wall time) rather than
run dry; at rest with nothing buffered ahead, sim time follows the wall clock, so that
new jobs can be scheduled a little ahead of it.
"""
from __future__ import annotations

from cnc_msgs_py.units import NS

from .servo import ServoLoop

IDLE_GRACE_S = 0.5  # wall time the stream may take to continue after running out at rest
# (a job paused at rest right at a chunk's end) before idle sim time starts to run; the
# bridge drains its buffer in blocks within milliseconds, so this is the planner's time to
# answer, which a loaded CPU stretches (0.1 s was too short under the full suite)
RECORDER_WINDOW_NS = 100_000_000  # sim time the bridge may run ahead of what a recorder
# has written: far inside the 20 s of joint_states history, so no sample is ever dropped,
# and short, so a recorder's view of the machine (a test's, a cell's) stays current
RECORDER_TIMEOUT_S = 1.0  # wall time without word from the recorder before it counts as gone
# (a recorder that stopped reading): shorter than the planner's 2 s feedback watchdog


class Lockstep:
    def __init__(self, period_ns: int, underrun_timeout_s: float, t_ns: int, wall_s: float) -> None:
        self.period_ns = period_ns
        self.underrun_timeout_s = underrun_timeout_s
        self.starved_since: float | None = None  # wall time the wait for setpoints began
        self.idle = True
        self.wall_start, self.sim_at_wall_start = wall_s, t_ns  # idle sim time runs from here
        self.recorded_ns: int | None = None  # what a recorder has written (None: no recorder)
        self.recorder_heard = 0.0  # wall time of its last word

    def recorded(self, stamp_ns: int, wall_s: float) -> None:
        """A recorder has written every joint_states sample up to ``stamp_ns``."""
        self.recorded_ns = stamp_ns if self.recorded_ns is None else max(self.recorded_ns, stamp_ns)
        self.recorder_heard = wall_s

    def may_step(self, loop: ServoLoop, t_ns: int, wall_s: float) -> bool:
        """May the loop take its step at ``t_ns`` now (wall time ``wall_s``)?

        While the axes move it waits only when the step at ``t_ns`` itself has no
        setpoint, so a job's last point (at rest) is stepped at once; after the underrun
        timeout it steps anyway, and the loop raises its buffer-ran-dry alarm and stops.
        A recorder that has fallen RECORDER_WINDOW_NS behind holds the clock until it
        catches up (backpressure), unless it has been silent for RECORDER_TIMEOUT_S; idle
        time then runs on from where it was held.
        """
        if self.recorded_ns is not None:
            if wall_s - self.recorder_heard > RECORDER_TIMEOUT_S:
                self.recorded_ns = None  # the recorder is gone: run on without it
            elif t_ns - self.recorded_ns > RECORDER_WINDOW_NS:
                if self.idle:
                    # Idle time resumes from here, not with a burst catching up the wall
                    # clock: a job scheduled on the held clock would start in the past.
                    self.wall_start, self.sim_at_wall_start = wall_s, t_ns
                return False
        if loop.starved(t_ns):
            if self.starved_since is None:
                self.starved_since = wall_s
            if wall_s - self.starved_since < self.underrun_timeout_s:
                return False
        self.starved_since = None
        end = loop.buffer.end_ns
        if loop.at_rest and (end is None or end < t_ns):
            if not self.idle:  # the stream just ran out at rest: grace, then wall time
                self.idle = True
                self.wall_start, self.sim_at_wall_start = wall_s + IDLE_GRACE_S, t_ns
            return t_ns + self.period_ns - self.sim_at_wall_start <= (wall_s - self.wall_start) * NS
        self.idle = False
        return True


class WallPacing:
    """How many servo steps a real-time bridge takes now.

    The steps due are those the wall clock has passed. After a stall (a loaded CPU) they can
    reach past the buffered setpoints while the chunk that continues them already waits in
    the subscription's queue; rclpy's executor runs ready timers before subscriptions, so
    the bridge first gives the queue one turn (steps nothing) and only then runs dry.
    """

    def __init__(self, period_ns: int) -> None:
        self.period_ns = period_ns
        self.gave_queue_a_turn = False

    def steps_due(self, loop: ServoLoop, t_ns: int, now_ns: int) -> int:
        """Steps to take from ``t_ns`` at wall time ``now_ns`` (0: none now)."""
        due = (now_ns - t_ns) // self.period_ns
        if due <= 0:
            return 0
        if loop.starved(t_ns) and not self.gave_queue_a_turn:
            self.gave_queue_a_turn = True
            return 0
        self.gave_queue_a_turn = False
        return due
