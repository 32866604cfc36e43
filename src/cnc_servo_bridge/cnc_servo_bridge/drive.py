"""Servo drive model: one position loop with feed-forward over a first-order velocity loop.

Per axis and servo period T (all joints vectorised), the reference reaching the drive
its transport delay (whole periods) after it was commanded:

    e      = p_ref - p_measured                         following error
    v_cmd  = velocity_ff * v_ref + accel_ff * velocity_lag * a_ref + kp * e
    v_cmd  clamped to +-VELOCITY_HEADROOM * max_velocity
    v'     = v_cmd + (v - v_cmd) * exp(-T / velocity_lag)   (velocity loop lag)
    v'     rate-limited to +-ACCELERATION_HEADROOM * max_acceleration, and 0 below the
           smallest normal double (a decaying v' would stick at the smallest subnormal)
    p'     = p + (v + v') / 2 * T
    p_measured = p' quantised to the encoder resolution

A real axis adds losses (docs/machines.md): Coulomb friction f makes v_cmd - f * sign(v)
the velocity loop's target and stops the axis (v' = 0) rather than reversing it through
the friction, so that at rest it holds until |v_cmd| exceeds f; backlash b lets the load,
which the encoder (a linear scale) reads, trail the motor p by up to b/2 either way; encoder
noise adds a seeded normal draw to every reading.

With accel_ff = 1 the velocity loop's lag is cancelled for slow references; the planner
uses the same model (this module) to predict and pre-compensate the lag.

``step`` is the reference implementation, one period at a time in numpy. ``run`` and
``simulate`` advance many periods at once through a compiled kernel that performs the
same floating-point operations in the same order, so both give the same positions
(tested to 1e-12 m, clamps, losses and quantisation included) at a few hundred times the
speed: the planner's safety searches and the bridge's block stepping use it. The kernel is
a small C function (_drive_kernel.c) that the package's setup.py compiles when it is
installed, so a node loads a few kilobytes of machine code, not a JIT compiler (numba
and LLVM cost each node about 125 MiB of resident memory).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.machine import Drive, Machine

from ._drive_kernel import run as _run
from ._drive_kernel import run_plant as _run_plant
from ._drive_kernel import run_shared as _run_shared

VELOCITY_HEADROOM = 1.2
ACCELERATION_HEADROOM = 1.5
TINY = np.finfo(float).tiny  # the smallest normal double: a velocity below it is zero


@dataclass
class DriveState:
    """Every joint's motor (true position and velocity), its load (the motor's position but
    for backlash) and what the encoders report."""

    position: np.ndarray
    velocity: np.ndarray
    measured: np.ndarray
    load: np.ndarray


class DriveModel:
    """The servo drives of one machine, stepped once per servo period."""

    def __init__(self, machine: Machine, servo_period: float, joints: tuple[str, ...] | None = None,
                 drives: dict[str, Drive] | None = None, seed: int = 0):
        """``drives``: the drives to emulate instead of the description's (a plant, or a
        corner of the description's tolerance); ``seed``: of their encoder noise, if any."""
        joints = joints or machine.joint_names
        self._setup(machine, servo_period, [(j, (drives or machine.drives)[j]) for j in joints], seed)

    @classmethod
    def columns(cls, machine: Machine, servo_period: float, columns: list[tuple[str, Drive]],
                seed: int = 0) -> DriveModel:
        """One model stepping several drives side by side, a column each: (joint, drive) pairs,
        a joint as often as it has drives (the planner runs the corners of a tolerance at
        once, in one kernel call)."""
        model = cls.__new__(cls)
        model._setup(machine, servo_period, columns, seed)
        return model

    def _setup(self, machine: Machine, servo_period: float, columns: list[tuple[str, Drive]], seed: int) -> None:
        self.joints = tuple(j for j, _ in columns)
        self.period = servo_period
        chosen = [d for _, d in columns]
        axes = [machine.drive_axes[j] for j in self.joints]
        self.kp = np.array([d.kp for d in chosen])
        self.velocity_ff = np.array([d.velocity_ff for d in chosen])
        self.accel_ff = np.array([d.accel_ff for d in chosen])
        self.lag = np.array([d.velocity_lag for d in chosen])
        self.resolution = np.array([d.resolution for d in chosen])
        self.following_error_limit = np.array([d.following_error_limit for d in chosen])
        self.delay_steps = np.array([round(d.delay / servo_period) for d in chosen], dtype=np.intp)
        edges = [0] + [k for k in range(1, len(chosen)) if self.delay_steps[k] != self.delay_steps[k - 1]] + [len(chosen)]
        self._delay_runs = [(int(self.delay_steps[a]), a, b) for a, b in zip(edges, edges[1:])]
        self.friction = np.array([d.friction for d in chosen])
        self.backlash = np.array([d.backlash for d in chosen])
        self.noise = np.array([d.noise for d in chosen])
        # The plain kernel where no joint has losses: the described drives, bit for bit as before.
        self.lossy = bool(np.any(self.friction > 0) or np.any(self.backlash > 0) or np.any(self.noise > 0))
        self.rng = np.random.default_rng(seed)
        self.decay = np.exp(-servo_period / self.lag)
        self.v_limit = VELOCITY_HEADROOM * np.array([a.max_velocity for a in axes])
        self.dv_limit = ACCELERATION_HEADROOM * np.array([a.max_acceleration for a in axes]) * servo_period
        self.history: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # references still in transit
        self.state = self.reset(np.zeros(len(self.joints)))

    def quantise(self, position: np.ndarray) -> np.ndarray:
        return np.round(position / self.resolution) * self.resolution

    def reset(self, position: np.ndarray) -> DriveState:
        """Put the drives at rest at a position (power-up, or after a restart)."""
        position = np.asarray(position, dtype=float).copy()
        self.state = DriveState(position, np.zeros_like(position), self.quantise(position), position.copy())
        depth = int(self.delay_steps.max(initial=0))
        if depth:
            self.history = (np.tile(position, (depth, 1)), np.zeros((depth, position.size)),
                            np.zeros((depth, position.size)))
        return self.state

    def snapshot(self) -> tuple:
        """Everything ``run`` changes (state, references in transit, noise draws), for ``restore``."""
        s = self.state
        return (DriveState(s.position.copy(), s.velocity.copy(), s.measured.copy(), s.load.copy()),
                self.history, self.rng.bit_generator.state)

    def restore(self, snapshot: tuple) -> None:
        """Back to a ``snapshot``: a block taken again up to a step that trips."""
        self.state, self.history, self.rng.bit_generator.state = snapshot

    def displace(self, joint: int, offset: float) -> None:
        """Move one joint's motor and load by ``offset`` (a crash, a slipping coupling)."""
        self.state.position[joint] += offset
        self.state.load[joint] += offset

    def _delayed(self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray) -> tuple[np.ndarray, ...]:
        """The references (rows, joints) as each drive receives them, its delay later; the
        last ones stay in transit for the next call."""
        if self.history is None:
            return p_ref, v_ref, a_ref
        depth, n = len(self.history[0]), len(p_ref)
        seen, kept = [], []
        for past, ref in zip(self.history, (p_ref, v_ref, a_ref)):
            out = np.empty_like(ref)
            for delay, first, last in self._delay_runs:  # a slice per run of columns of one delay
                held = min(delay, n)  # rows still in transit from the last call
                out[:held, first:last] = past[depth - delay:depth - delay + held, first:last]
                out[held:, first:last] = ref[:n - held, first:last]
            seen.append(out)
            kept.append(ref[n - depth:].copy() if n >= depth else np.concatenate((past[n:], ref)))
        self.history = tuple(kept)  # type: ignore[assignment]
        return tuple(seen)

    def _noise(self, rows: int) -> np.ndarray:
        """Encoder noise of ``rows`` readings per joint (zeros on noiseless encoders)."""
        if not np.any(self.noise > 0):
            return np.zeros((rows, len(self.joints)))
        return self.rng.standard_normal((rows, len(self.joints))) * self.noise

    def step(self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray) -> np.ndarray:
        """Advance one servo period towards the reference; returns the following error
        (against the reference as commanded, before its transport delay)."""
        s = self.state
        error = p_ref - s.measured
        p_in, v_in, a_in = (x[0] for x in self._delayed(*(np.reshape(np.asarray(x, float), (1, -1))
                                                          for x in (p_ref, v_ref, a_ref))))
        v_cmd = self.velocity_ff * v_in + (self.accel_ff * self.lag) * a_in + self.kp * (p_in - s.measured)
        v_cmd = np.clip(v_cmd, -self.v_limit, self.v_limit)
        direction = np.where(s.velocity != 0.0, np.sign(s.velocity), np.sign(v_cmd))
        target = np.where(self.friction > 0.0, v_cmd - self.friction * direction, v_cmd)
        v_new = target + (s.velocity - target) * self.decay
        v_new = np.where((self.friction > 0.0) & (v_new * direction <= 0.0), 0.0, v_new)
        v_new = s.velocity + np.clip(v_new - s.velocity, -self.dv_limit, self.dv_limit)
        v_new = np.where(np.abs(v_new) < TINY, 0.0 * v_new, v_new)  # subnormal: zero (see the kernel)
        s.position = s.position + 0.5 * (s.velocity + v_new) * self.period
        s.velocity = v_new
        s.load = np.clip(s.load, s.position - 0.5 * self.backlash, s.position + 0.5 * self.backlash)
        s.measured = self.quantise(s.load)
        if self.lossy:
            s.measured = s.measured + self._noise(1)[0]
        return error

    def run(
        self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the drives once per reference row (shape (n, joints)) from their state.

        Row i of the result is what the encoders read (measured position, velocity and
        following error) before step i, as ``step`` would give it row by row.
        """
        p_ref, v_ref, a_ref = (np.ascontiguousarray(x, dtype=float).reshape(-1, len(self.joints))
                               for x in (p_ref, v_ref, a_ref))
        s = self.state
        s.position, s.velocity, s.measured, s.load = (np.array(x, dtype=float)
                                                      for x in (s.position, s.velocity, s.measured, s.load))
        out = np.empty((3, *p_ref.shape))
        received = self._delayed(p_ref, v_ref, a_ref)
        if self.lossy:
            _run_plant(*received, self._noise(len(p_ref)), s.position, s.velocity, s.load, s.measured, self.kp,
                       self.velocity_ff, self.accel_ff * self.lag, self.decay, self.v_limit, self.dv_limit,
                       self.resolution, self.friction, self.backlash, self.period, out)
        else:
            _run(*received, s.position, s.velocity, s.measured, self.kp, self.velocity_ff,
                 self.accel_ff * self.lag, self.decay, self.v_limit, self.dv_limit, self.resolution,
                 self.period, out)
            s.load = s.position.copy()
        if self.history is not None:  # the error against the reference as commanded
            out[2] = p_ref - out[0]
        return out[0], out[1], out[2]

    def run_shared(self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray,
                   source: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``run`` with column j taking column ``source[j]`` of the references given (rows x
        sources): a joint's tolerance corners share its reference, which the kernel reads in
        place, each column its delay later, instead of a copy per column and one more per
        delay (most of the planner's lag search once its kernel ran on normal numbers). The
        same values as ``run`` on the references copied to every column."""
        source = np.ascontiguousarray(source, dtype=np.int64)
        refs = tuple(np.ascontiguousarray(x, dtype=float).reshape(len(x), -1) for x in (p_ref, v_ref, a_ref))
        if self.lossy:
            return self.run(*(x[:, source] for x in refs))
        depth = int(self.delay_steps.max(initial=0))
        if depth:  # the references in transit, one column per source (every column of a source has its own)
            first = [int(np.flatnonzero(source == k)[0]) for k in range(refs[0].shape[1])]
            refs = tuple(np.concatenate((past[:, first], x)) for past, x in zip(self.history, refs))
        s = self.state
        s.position, s.velocity, s.measured = (np.array(x, dtype=float) for x in (s.position, s.velocity, s.measured))
        out = np.empty((3, len(refs[0]) - depth, len(self.joints)))
        _run_shared(*refs, depth, source, self.delay_steps.astype(np.int64), s.position, s.velocity, s.measured,
                    self.kp, self.velocity_ff, self.accel_ff * self.lag, self.decay, self.v_limit, self.dv_limit,
                    self.resolution, self.period, out)
        s.load = s.position.copy()
        if depth:
            self.history = tuple(x[-depth:][:, source] for x in refs)  # type: ignore[assignment]
        return out[0], out[1], out[2]

    def simulate(
        self, p_ref: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Run the drives over references sampled every servo period (shape (n, joints)).

        The drives start at rest at the first reference. Row i of the result is what the
        encoders read at the time of reference row i, before that period's step: exactly
        what the bridge publishes for that instant, computed offline.
        """
        self.reset(p_ref[0])
        positions, velocities, _ = self.run(p_ref, v_ref, a_ref)
        return positions, velocities


def warm_up() -> None:
    """Run the compiled kernels once at a node's start, so a kernel that does not load or
    run fails there and not on the first job's clock."""
    one = np.zeros((1, 1))
    state = [np.zeros(1) for _ in range(3)]
    _run(one, one, one, *state, *(np.ones(1) for _ in range(4)), np.ones(1), np.ones(1), np.ones(1),
         1e-3, np.empty((3, 1, 1)))
    _run_plant(one, one, one, one, *(np.zeros(1) for _ in range(4)), *(np.ones(1) for _ in range(7)),
               np.zeros(1), np.zeros(1), 1e-3, np.empty((3, 1, 1)))
