"""Drive identification: each axis's servo drive fitted from recorded commands and feedback.

A real machine is commissioned by measuring its drives, not by believing their data sheet.
Each servo period k the drive (cnc_servo_bridge.drive, docs/machines.md) takes the reference
it received d periods after it was commanded and moves its motor velocity w towards

    v_cmd[k] = ff * v[k-d] + af * lag * a[k-d] + kp * (p[k-d] - y[k]) - f * sign(w[k])

    w[k+1]   = decay * w[k] + (1 - decay) * v_cmd[k],      decay = exp(-T / lag)

with y the measured position (encoder, after backlash and noise) and f the Coulomb friction.
For a given delay d this is linear in (decay, (1-decay) ff, (1-decay) af lag, (1-decay) kp,
(1-decay) f): one least-squares fit per candidate delay, the delay with the least residual
wins and the parameters follow from the coefficients. Where the loop leaves the linear
model it is left out of the fit: the velocity command at its clamp, the velocity at its
acceleration rate limit, an axis held by friction (w = 0), a stop the recording does not
hold the reference of. Friction stays in only where its coefficient is significant.
Backlash shows as the load (what the encoder reads) trailing the motor (the integral of its
velocity) by half the lost motion either way: the difference between the two directions.

The bridge publishes the motor velocity and the measured position at every servo stamp,
before that period's step, and samples the buffered setpoints at that stamp
(cnc_servo_bridge.setpoints): ``trace`` rebuilds exactly that reference from the recorded
chunks. The fitted drives are then run (DriveModel) on the same references, and the
simulated feedback against the recorded one is the fit's residual.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Drive, Machine, Tolerance
from cnc_servo_bridge.drive import ACCELERATION_HEADROOM, VELOCITY_HEADROOM, DriveModel
from cnc_servo_bridge.setpoints import SetpointBuffer

from .recording import Run

MAX_DELAY_PERIODS = 20  # the longest transport delay tried (20 ms at a 1 ms servo period)
MIN_SAMPLES = 200  # fewer usable servo periods than this: the axis was not excited
FRICTION_T = 10.0  # friction's coefficient must exceed its standard error this many times...
FRICTION_FLOOR = 1e-4  # ...and this fraction of the axis's RMS velocity, to be kept
CLAMP_MARGIN = 0.98  # a velocity command this close to its clamp may have been clamped
OUTLIER = 20.0  # one-step residuals beyond this many robust deviations are left out once
BACKLASH_MOVING = 0.01  # of the axis's top speed: the motor counts as moving one way
BACKLASH_RESOLUTIONS = 3.0  # lost motion below this many encoder steps is none
# The tolerance an identified drive keeps (docs/machines.md#commissioning-a-real-machine): the
# fit is exact on an emulated plant, but a real loop drifts with load and temperature between
# commissionings. +-2 % on the loop and +-0.5 % on the feed-forward keep drill_row's holes
# within 5 um of depth and its cycle within 1 % of the exact plan's (+-5 %: 5.8 um short,
# 3.6 % slower); the delay is counted in whole servo periods and does not drift.
IDENTIFIED = Tolerance(kp=(0.98, 1.02), velocity_ff=(0.995, 1.005), accel_ff=(0.995, 1.005),
                       velocity_lag=(0.98, 1.02), delay=(0.0, 0.0))
LOSS_MARGIN = 0.1  # identified backlash and friction may be this fraction more


@dataclass
class Trace:
    """One recording on its servo grid: the reference the drives used at stamps t0 - D*T ..
    (D = MAX_DELAY_PERIODS rows of history first) and the feedback from t0 on (NaN where a
    stamp is missing). ``known`` is False where the reference is not in the recording (a stop
    after a chunk that ended moving)."""

    name: str
    period: float
    joints: tuple[str, ...]
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    known: np.ndarray
    y: np.ndarray
    w: np.ndarray

    @classmethod
    def of(cls, period: float, joints: tuple[str, ...], reference: tuple[np.ndarray, ...], feedback: tuple[np.ndarray, ...],
           name: str = "") -> Trace:
        """A trace from arrays: references (p, v, a; rows of joints every servo period, from
        rest) and the feedback at the same stamps (y, w), as DriveModel.simulate gives them for
        a plan sampled offline; the history before the first row is that row at rest."""
        p, v, a = (np.asarray(x, dtype=float) for x in reference)
        rest = np.zeros((MAX_DELAY_PERIODS, p.shape[1]))
        return cls(name, period, joints, np.concatenate((np.tile(p[0], (MAX_DELAY_PERIODS, 1)), p)),
                   np.concatenate((rest, v)), np.concatenate((rest, a)), np.ones(len(p) + MAX_DELAY_PERIODS, dtype=bool),
                   *(np.asarray(x, dtype=float) for x in feedback))


@dataclass(frozen=True)
class AxisFit:
    """One axis identified: the fitted drive (tolerance narrowed) or why not, and how well
    simulated feedback matches the recorded one, described drive and fitted (um or urad)."""

    joint: str
    drive: Drive | None
    samples: int = 0
    note: str = ""
    backlash_identified: bool = False
    noise: float = 0.0
    residual_described: tuple[float, float] = (float("nan"), float("nan"))  # max, RMS
    residual_fitted: tuple[float, float] = (float("nan"), float("nan"))


def servo_period(run: Run) -> float:
    """The bridge's servo period: the spacing of its feedback stamps (s)."""
    if len(run.feedback_t) < 2:
        raise ValueError("no feedback recorded (joint_states)")
    return float(np.median(np.diff(np.round(run.feedback_t * 1e9)))) / 1e9


def reference(command_t_ns: np.ndarray, command: tuple[np.ndarray, ...], chunk_starts_ns: np.ndarray,
              stamps_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The reference (p, v, a; rows of joints) the bridge sampled at each stamp from the
    executed points (``command``, at ``command_t_ns``; chunks start at ``chunk_starts_ns``),
    and whether the recording holds it: inside a chunk linear between its points (on the servo
    grid, the point itself); before the first point that point held at rest; past a chunk's
    last point, up to the next chunk, that point held at rest if the chunk ended at rest, and
    if it ended moving a stop the recording does not hold (known False)."""
    p_cmd, v_cmd, a_cmd = command
    k = np.searchsorted(command_t_ns, stamps_ns, side="right") - 1
    row = np.maximum(k, 0)
    last = np.append(np.isin(command_t_ns[1:], chunk_starts_ns), True)  # a point a chunk ends at
    on_point = (k >= 0) & (command_t_ns[row] == stamps_ns)
    between = (k >= 0) & ~on_point & ~last[row]
    held = (k >= 0) & ~on_point & last[row]
    p, v, a = p_cmd[row].copy(), v_cmd[row].copy(), a_cmd[row].copy()
    v[(k < 0) | held] = 0.0
    a[(k < 0) | held] = 0.0
    if between.any():
        kb = row[between]
        w = ((stamps_ns[between] - command_t_ns[kb]) / (command_t_ns[kb + 1] - command_t_ns[kb]))[:, None]
        for out, x in ((p, p_cmd), (v, v_cmd), (a, a_cmd)):
            out[between] = x[kb] + w * (x[kb + 1] - x[kb])
    known = ~(held & np.any(v_cmd[row] != 0.0, axis=1))
    return p, v, a, known


def trace(run: Run, machine: Machine, name: str = "") -> Trace:
    """A recorded run on its servo grid (the spindle included; fits leave it out), known up
    to its first alarm: from there the bridge stopped the axes on a reference of its own
    that no recorded setpoint holds (a following error beyond the machine's limit or an
    encoder outside the travel, judged on the recording as the bridge judges them, or a job
    aborted, whichever comes first)."""
    period = servo_period(run)
    period_ns = round(period * 1e9)
    stamps = np.round(run.feedback_t * 1e9).astype(np.int64)
    first = int(stamps[0])
    n = int((stamps[-1] - first) // period_ns) + 1
    grid = first + (np.arange(n + MAX_DELAY_PERIODS, dtype=np.int64) - MAX_DELAY_PERIODS) * period_ns
    if len(run.command_t) == 0:
        raise ValueError(f"{name or 'recording'}: no setpoints recorded (joint_trajectory)")
    command_t = np.round(run.command_t * 1e9).astype(np.int64)
    starts = np.array([c.stamp_ns for c in run.chunks], dtype=np.int64)
    p, v, a, known = reference(command_t, (run.command, run.command_velocity, run.command_acceleration), starts, grid)
    y = np.full((n, len(run.joints)), np.nan)
    w = np.full((n, len(run.joints)), np.nan)
    index = (stamps - first) // period_ns
    on_grid = (stamps - first) % period_ns == 0
    y[index[on_grid]] = run.feedback[on_grid]
    w[index[on_grid]] = run.feedback_velocity[on_grid]
    limit = np.array([machine.drives[j].following_error_limit for j in run.joints])
    encoders = np.full((n, len(machine.joint_names)), np.nan)  # the machine's joints, as recorded
    for i, joint in enumerate(machine.joint_names):
        if joint in run.joints:
            encoders[:, i] = y[:, run.joints.index(joint)]
    with np.errstate(invalid="ignore"):
        tripped = np.flatnonzero(np.any(np.abs(p[MAX_DELAY_PERIODS:] - y) > limit, axis=1)
                                 | np.any(SetpointBuffer(machine).outside_travel(encoders), axis=1))
    aborted = [s["stamp_ns"] for s in run.statuses if s.get("state") == "aborted" and "stamp_ns" in s]
    alarm = min(([int(grid[MAX_DELAY_PERIODS + tripped[0]])] if len(tripped) else []) + aborted, default=None)
    if alarm is not None:
        known[grid >= alarm] = False
    return Trace(name, period, tuple(run.joints), p, v, a, known, y, w)


def _regressors(tr: Trace, j: int, delay: int) -> tuple[np.ndarray, np.ndarray]:
    """Columns (w[k], v[k-d], a[k-d], p[k-d] - y[k], -sign w[k]) and targets w[k+1], k = 0..n-2."""
    n, lead = len(tr.y), MAX_DELAY_PERIODS - delay
    p, v, a = (x[lead:lead + n - 1, j] for x in (tr.p, tr.v, tr.a))
    y, w = tr.y[:-1, j], tr.w[:-1, j]
    return np.column_stack((w, v, a, p - y, -np.sign(w))), tr.w[1:, j]


def _usable(tr: Trace, j: int, dv_limit: float) -> np.ndarray:
    """The steps k -> k+1 inside the linear model, for every candidate delay alike."""
    n = len(tr.y)
    w0, w1 = tr.w[:-1, j], tr.w[1:, j]
    known = np.ones(n - 1, dtype=bool)
    for delay in range(MAX_DELAY_PERIODS + 1):
        lead = MAX_DELAY_PERIODS - delay
        known &= tr.known[lead:lead + n - 1]
    finite = np.isfinite(w0) & np.isfinite(w1) & np.isfinite(tr.y[:-1, j])
    with np.errstate(invalid="ignore"):
        return (known & finite & (w0 != 0.0) & (w1 != 0.0)
                & (np.abs(w1 - w0) < dv_limit * (1.0 - 1e-6)))


def _solve(x: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Least squares on columns scaled to unit RMS: coefficients, residual sum of squares,
    and the coefficients' standard errors."""
    scale = np.sqrt(np.mean(x * x, axis=0))
    scale[scale == 0.0] = 1.0
    xs = x / scale
    theta, _, rank, _ = np.linalg.lstsq(xs, target, rcond=None)
    residual = target - xs @ theta
    rss = float(residual @ residual)
    if rank < x.shape[1]:
        return theta / scale, rss, np.full(x.shape[1], np.inf)
    dof = max(len(target) - x.shape[1], 1)
    cov = np.linalg.inv(xs.T @ xs) * rss / dof
    return theta / scale, rss, np.sqrt(np.maximum(np.diag(cov), 0.0)) / scale


def fit_axis(traces: list[Trace], machine: Machine, joint: str) -> AxisFit:
    """One axis's drive from every trace together (not yet simulated: ``identify`` does)."""
    described = machine.drives[joint]
    axis = machine.drive_axes[joint]
    period = traces[0].period
    dv_limit = ACCELERATION_HEADROOM * axis.max_acceleration * period
    v_limit = VELOCITY_HEADROOM * axis.max_velocity
    columns = [tr.joints.index(joint) for tr in traces]
    masks = [_usable(tr, j, dv_limit) for tr, j in zip(traces, columns)]
    count = int(sum(m.sum() for m in masks))
    if count < MIN_SAMPLES:
        return AxisFit(joint, None, count, f"not excited: {count} usable servo periods of motion")

    def stacked(delay: int, keep: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        parts = [_regressors(tr, j, delay) for tr, j in zip(traces, columns)]
        return (np.concatenate([x[m] for (x, _), m in zip(parts, keep)]),
                np.concatenate([t[m] for (_, t), m in zip(parts, keep)]))

    delay = min(range(MAX_DELAY_PERIODS + 1), key=lambda d: _solve(*stacked(d, masks))[1])
    x, target = stacked(delay, masks)
    keep = np.ones(len(target), dtype=bool)
    used = np.arange(5)
    for _ in range(3):  # leave out gross outliers (a stop no alarm marked) and clamped commands
        theta, _, err = _solve(x[keep][:, used], target[keep])
        full = np.zeros(5)
        full[used] = theta
        decay = full[0]
        residual = target - x @ full
        spread = 1.4826 * np.median(np.abs(residual[keep])) + 1e-12 * np.sqrt(np.mean(target * target))
        keep &= np.abs(residual) <= OUTLIER * spread
        if not 0.0 < decay < 1.0:  # the outliers' fit: what is left decides
            continue
        keep &= np.abs(x[:, 1:4] @ full[1:4]) < CLAMP_MARGIN * v_limit * (1.0 - decay)
        f_index = int(np.flatnonzero(used == 4)[0]) if 4 in used else None
        if f_index is not None:
            friction = theta[f_index] / (1.0 - decay)
            rms_w = float(np.sqrt(np.mean(target * target)))
            if not (theta[f_index] > FRICTION_T * err[f_index] and friction > FRICTION_FLOOR * rms_w):
                used = np.arange(4)
    theta, _, _ = _solve(x[keep][:, used], target[keep])
    full = np.zeros(5)
    full[used] = theta
    decay = full[0]
    if not 0.0 < decay < 1.0 or full[3] <= 0.0:
        return AxisFit(joint, None, int(keep.sum()), f"no stable first-order velocity loop with a positive gain "
                                                     f"fits (decay {decay:.3g}, kp term {full[3]:.3g})")
    gain = 1.0 - decay
    lag = -period / np.log(decay)
    accel_ff = full[2] / (gain * lag) if np.any(x[:, 2] != 0.0) else described.accel_ff
    backlash, noise = _backlash(traces, columns, described.resolution)
    fitted = replace(described, kp=_round(full[3] / gain), velocity_ff=_factor(full[1] / gain),
                     accel_ff=_factor(accel_ff), velocity_lag=_round(lag), delay=delay * period,
                     friction=_round(max(full[4] / gain, 0.0)),
                     backlash=described.backlash if backlash is None else _round(backlash))
    fitted = replace(fitted, tolerance=narrowed(fitted, described.tolerance if backlash is None else None))
    return AxisFit(joint, fitted, int(keep.sum()), backlash_identified=backlash is not None, noise=noise)


def _round(value: float) -> float:
    """Six significant digits: what a description needs, readable in its YAML."""
    return float(f"{value:.6g}")


def _factor(value: float) -> float:
    """A feed-forward gain to 1e-6 (a fit of 1e-14 is none)."""
    return float(round(float(value), 6)) + 0.0


def narrowed(drive: Drive, losses: Tolerance | None = None) -> Tolerance:
    """The tolerance of an identified drive: IDENTIFIED, and LOSS_MARGIN of its identified
    backlash and friction (``losses``: the tolerance to keep them from where backlash was
    not identified)."""
    backlash = losses.backlash if losses is not None else LOSS_MARGIN * drive.backlash
    return replace(IDENTIFIED, backlash=_round(backlash), friction=_round(LOSS_MARGIN * drive.friction))


def _backlash(traces: list[Trace], columns: list[int], resolution: float) -> tuple[float | None, float]:
    """Lost motion from the load (the encoder) against the motor (the integral of its
    velocity): moving up the load trails by b/2, moving down it leads by b/2. None when the
    axis never moved both ways; with it the encoder noise (standard deviation)."""
    weighted, weight, spreads = 0.0, 0, []
    for tr, j in zip(traces, columns):
        y, w = tr.y[:, j], tr.w[:, j]
        present = np.isfinite(y) & np.isfinite(w)
        if not present.all():  # the motor integrates over a gap-free stretch only
            stop = int(np.argmin(present))
            y, w = y[:stop], w[:stop]
        if len(y) < 2:
            continue
        motor = y[0] + np.concatenate(([0.0], np.cumsum(0.5 * (w[:-1] + w[1:]) * tr.period)))
        offset = y - motor
        fast = BACKLASH_MOVING * np.max(np.abs(w))
        up, down = offset[w > fast], offset[w < -fast]
        if min(len(up), len(down)) < MIN_SAMPLES // 4:
            continue
        n = min(len(up), len(down))
        weighted += n * (np.median(down) - np.median(up))
        weight += n
        spreads += [up - np.median(up), down - np.median(down)]
    if not weight:
        return None, 0.0
    deviation = 1.4826 * float(np.median(np.abs(np.concatenate(spreads))))
    noise = float(np.sqrt(max(deviation ** 2 - resolution ** 2 / 12.0, 0.0)))
    noise = noise if noise > 0.5 * resolution else 0.0  # below that: the quantisation's own spread
    backlash = weighted / weight
    return (backlash if backlash > BACKLASH_RESOLUTIONS * resolution else 0.0), noise


def residuals(traces: list[Trace], machine: Machine, drives: dict[str, Drive], joints: tuple[str, ...]
              ) -> dict[str, tuple[float, float]]:
    """The drives run on each trace's reference from rest at its start (DriveModel): simulated
    minus recorded position per joint, max and RMS (um or urad) over the known stamps."""
    errors: dict[str, list[np.ndarray]] = {j: [] for j in joints}
    for tr in traces:
        model = DriveModel(machine, tr.period, joints, drives=drives)
        columns = [tr.joints.index(j) for j in joints]
        rows = slice(MAX_DELAY_PERIODS, None)
        simulated, _ = model.simulate(*(x[rows][:, columns] for x in (tr.p, tr.v, tr.a)))
        judged = tr.known[rows] & np.all(np.isfinite(tr.y[:, columns]), axis=1)
        for i, j in enumerate(joints):
            errors[j].append((simulated[judged, i] - tr.y[judged, columns[i]]) * 1e6)
    out = {}
    for j, parts in errors.items():
        e = np.concatenate(parts)
        out[j] = (float(np.max(np.abs(e))), float(np.sqrt(np.mean(e * e)))) if len(e) else (float("nan"),) * 2
    return out


def identify(traces: list[Trace], machine: Machine) -> dict[str, AxisFit]:
    """Every axis but the spindle fitted over all traces together (one machine, one servo
    period), with the residual of the described and of the fitted drives."""
    periods = {round(tr.period * 1e9) for tr in traces}
    if len(periods) != 1:
        raise ValueError(f"recordings at different servo periods ({sorted(p / 1e6 for p in periods)} ms)")
    joints = tuple(j for j in machine.joint_names if j != SPINDLE)
    fits = {j: fit_axis(traces, machine, j) for j in joints}
    fitted = {j: f.drive if f.drive is not None else machine.drives[j] for j, f in fits.items()}
    before = residuals(traces, machine, dict(machine.drives), joints)
    after = residuals(traces, machine, fitted, joints)
    return {j: replace(f, residual_described=before[j], residual_fitted=after[j]) for j, f in fits.items()}
