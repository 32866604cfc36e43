"""The servo loop of the bridge: reference from the buffer, drive model, alarms, stops.

One ``step`` per servo period. The reference comes from the setpoint buffer; when the
buffer runs dry while the axes still move (planner gone) or an axis trips its following
error limit, the loop raises an alarm and brings every joint to a jerk-limited stop
(ruckig) from the reference it was following, then holds.

The drives are enabled or not (the bridge node's lifecycle: active or inactive). Disabling
them is the same jerk-limited stop without an alarm; disabled, the loop holds, still
reports feedback, and refuses setpoints with the reason.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import Trajectory

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.plant import Plant, description_plant

from .drive import DriveModel, warm_up
from .setpoints import REST_VELOCITY, SetpointBuffer, SetpointError
from .stop import velocity_trajectory

DRIVES_DISABLED = "drives disabled (bridge inactive): activate the bridge to accept setpoints"


@dataclass
class Feedback:
    """What the encoders read at ``stamp_ns``, before that period's step."""

    stamp_ns: int
    positions: np.ndarray
    velocities: np.ndarray
    following_error: np.ndarray


def _check_start(machine: Machine, start: np.ndarray) -> None:
    """Where the axes stand at power-up: one value per joint, inside the travel."""
    joints = machine.joint_names
    if start.shape != (len(joints),):
        raise ValueError(f"start_position: {start.size} values for the {len(joints)} joints {', '.join(joints)}")
    for joint, position in zip(joints, start):
        if not machine.axes[joint].within_travel(position):
            raise ValueError(f"start_position: {joint} at {position:g} is outside its travel")


def _check_delays(plant: Plant, period_ns: int) -> None:
    """A transport delay is a whole number of servo periods: anything else is a typo."""
    for joint, drive in plant.drives.items():
        periods = drive.delay * 1e9 / period_ns
        if abs(periods - round(periods)) > 1e-6:
            raise ValueError(f"plant {plant.name}: drive.{joint}.delay: {drive.delay:g} s is not a whole number of "
                             f"servo periods ({period_ns / 1e9:g} s)")


class ServoLoop:
    def __init__(self, machine: Machine, servo_period_ns: int, start_position: np.ndarray | None = None,
                 enabled: bool = True, plant: Plant | None = None):
        """``plant``: the drives emulated, if not the description's (the setpoint rules and
        the axis limits stay the description's, as a real NC's)."""
        warm_up()  # the drive kernel, now: loading it at the first block would stall a real-time loop
        self.machine = machine
        self.joints = machine.joint_names
        self.period_ns = servo_period_ns
        self.plant = plant or description_plant(machine)
        _check_delays(self.plant, servo_period_ns)
        self.drives = DriveModel(machine, servo_period_ns / 1e9, drives=self.plant.drives, seed=self.plant.seed)
        self.buffer = SetpointBuffer(machine)
        start = np.zeros(len(self.joints)) if start_position is None else np.asarray(start_position, float)
        _check_start(machine, start)
        self.drives.reset(start)
        zero = np.zeros(len(self.joints))
        self.reference = (start.copy(), zero.copy(), zero.copy())
        self.alarm = ""
        self.enabled = enabled
        self.max_following_error = np.zeros(len(self.joints))
        self._stop: tuple[Trajectory, int] | None = None
        axes = [machine.axes[j] for j in self.joints]
        self._limits = ([a.max_velocity for a in axes], [a.max_acceleration for a in axes], [a.max_jerk for a in axes])

    @property
    def at_rest(self) -> bool:
        return bool(np.all(np.abs(self.reference[1]) <= REST_VELOCITY)) and self._stop is None

    def accept(self, names: list[str], times_ns: np.ndarray, p, v, a, now_ns: int) -> None:
        """Validate and buffer a chunk. Raises SetpointError (the diagnostic) if refused.

        ``now_ns``: the next step, not taken yet: the earliest a chunk may start."""
        if not self.enabled:
            raise SetpointError(DRIVES_DISABLED)
        if self.alarm:
            raise SetpointError(f"alarm latched ({self.alarm}): waiting for alarm_reset")
        if self._stop is not None:
            raise SetpointError("stopping: setpoints are taken once the axes stand still")
        setpoints = self.buffer.validate(names, times_ns, p, v, a, now_ns, self.reference[:2])
        self.buffer.insert(setpoints)

    def disable(self, now_ns: int) -> None:
        """Drives off (deactivate): a jerk-limited stop from the reference being followed,
        what was buffered dropped, setpoints refused until ``enable``. An alarm's stop
        already running goes on. ``now_ns``: the next step, not taken yet."""
        self.enabled = False
        if self._stop is None:
            self._begin_stop(now_ns - self.period_ns)  # the reference is one period old

    def enable(self) -> None:
        """Drives on (activate): setpoints are accepted again once any stop has run out."""
        self.enabled = True

    def reset_alarm(self) -> bool:
        """Acknowledge a latched alarm once the axes have stopped; True if it cleared."""
        if self._stop is None:
            self.alarm = ""
        return not self.alarm

    def starved(self, t_ns: int) -> bool:
        """Moving, and the buffer does not reach t: the loop would have to stop."""
        if self._stop is not None or self.at_rest:
            return False
        end = self.buffer.end_ns
        return end is None or end < t_ns

    def step(self, t_ns: int) -> Feedback:
        """Advance one servo period from time t."""
        reference = self._reference_at(t_ns)
        self.reference = reference
        error = reference[0] - self.drives.state.measured
        feedback = Feedback(t_ns, self.drives.state.measured.copy(), self.drives.state.velocity.copy(), error)
        self.max_following_error = np.maximum(self.max_following_error, np.abs(error))
        if self._stop is None:
            self._check(t_ns, error, feedback.positions)
        self.drives.step(*reference)
        return feedback

    def run(self, t_ns: int, steps: int, hold_in_blocks: bool = False) -> list[Feedback]:
        """Advance up to ``steps`` servo periods from time t, as many ``step`` calls would.

        Where the buffer holds the reference for several periods (one chunk, no stop
        running) the drive model takes them in one compiled call and the following-error
        and soft-limit checks run over the whole block; the block ends at the first step
        that trips a check, with that step's alarm, as single stepping would end it.
        ``hold_in_blocks``: so does holding at rest with nothing buffered ahead (the
        reference then stays put: a real-time bridge's idle time, which single steps made
        its largest cost). Otherwise (a stop, a dry or empty buffer) it takes one ``step``.
        """
        block = None if self._stop is not None or steps < 2 else self.buffer.sample_block(t_ns, steps, self.period_ns)
        if block is None and hold_in_blocks and self._stop is None and steps >= 2 and self.at_rest:
            end = self.buffer.end_ns
            if end is None or end < t_ns:
                block = tuple(np.broadcast_to(x, (steps, len(self.joints)))
                              for x in (self.reference[0], np.zeros(len(self.joints)), np.zeros(len(self.joints))))
        if block is None or len(block[0]) < 2:
            return [self.step(t_ns)]
        p, v, a = block
        saved = self.drives.snapshot()
        measured, velocity, error = self.drives.run(p, v, a)
        tripped = (np.any(np.abs(error) > self.drives.following_error_limit, axis=1)
                   | np.any(self.buffer.outside_travel(measured), axis=1))
        n = len(p)
        if tripped.any():
            n = int(np.argmax(tripped)) + 1
            if n < len(p):  # take the block again up to the step that trips
                self.drives.restore(saved)
                measured, velocity, error = self.drives.run(p[:n], v[:n], a[:n])
        self.max_following_error = np.maximum(self.max_following_error, np.abs(error[:n]).max(axis=0))
        self.reference = (p[n - 1].copy(), v[n - 1].copy(), a[n - 1].copy())
        feedback = [Feedback(t_ns + i * self.period_ns, measured[i], velocity[i], error[i]) for i in range(n)]
        if tripped[n - 1]:
            self._check(feedback[-1].stamp_ns, error[n - 1], measured[n - 1])
        return feedback

    def _check(self, t_ns: int, error: np.ndarray, measured: np.ndarray) -> None:
        """Following error and soft limits, judged on what the encoders read."""
        tripped = np.argwhere(np.abs(error) > self.drives.following_error_limit)
        if len(tripped):
            j = tripped[0][0]
            self._raise(t_ns, f"following error on {self.joints[j]}: {abs(error[j]):.6f} exceeds "
                              f"{self.drives.following_error_limit[j]:.6f}")
            return
        outside = np.argwhere(self.buffer.outside_travel(measured))
        if len(outside):
            j = outside[0][0]
            self._raise(t_ns, f"soft limit: {self.joints[j]} at {measured[j]:.6f} is outside its travel")

    def inject(self, joint: str, offset: float) -> None:
        """Fault injection: displace one axis (a crash, a slipping coupling) by ``offset``."""
        if joint not in self.joints:
            raise ValueError(f"inject_fault: unknown joint '{joint}'")
        self.drives.displace(self.joints.index(joint), offset)

    def _reference_at(self, t_ns: int):
        if self._stop is not None:
            trajectory, start_ns = self._stop
            local = (t_ns - start_ns) / 1e9
            if local >= trajectory.duration:
                self._stop = None
                p = np.array(trajectory.at_time(trajectory.duration)[0])
                return p, np.zeros_like(p), np.zeros_like(p)
            return tuple(np.array(x) for x in trajectory.at_time(local))
        sample = self.buffer.sample(t_ns)
        if sample is not None:
            return tuple(np.array(x, dtype=float) for x in sample)
        if not self.at_rest:
            # The stop starts from the last reference, one period ago, not from now:
            # otherwise the axes would stand still for a period while moving.
            self._raise(t_ns - self.period_ns, "setpoint buffer ran dry while moving: holding")
            return self._reference_at(t_ns)
        p = self.reference[0]
        return p, np.zeros_like(p), np.zeros_like(p)

    def _raise(self, t_ns: int, alarm: str) -> None:
        """Latch an alarm and stop every joint from the current reference."""
        self.alarm = alarm
        self._begin_stop(t_ns)

    def _begin_stop(self, t_ns: int) -> None:
        """Drop the buffer; bring every joint to rest from the reference taken at ``t_ns``."""
        self.buffer.clear()
        p, v, a = self.reference
        zero = [0.0] * len(self.joints)
        self._stop = (velocity_trajectory(list(p), list(v), list(a), zero, *self._limits), t_ns)

