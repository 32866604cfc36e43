"""Drive compensation, written once: a command correction learned against the drive model
so that the bridge's feedback, not only the command, follows the planned motion.

Every kind that must be exact on feedback uses it: the vibrated feed (the waveform's
turning points), the drill's S1 moves and hole bottoms, and the thread's passes. The
reference is sampled on the servo grid at rest at both ends; a few iterative-learning
passes against DriveModel.simulate, with the exact inverse of the drive's linear part as
learning operator (faded out over a band below half the servo rate), give the correction;
``settled`` keeps it until it has died out.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cnc_msgs_py.machine import Drive, Machine
from cnc_msgs_py.plant import tolerance_corners
from cnc_servo_bridge.drive import DriveModel


TWO_PI = 2.0 * math.pi
COMPENSATION_TAIL = 0.25  # s: longest the compensated command may settle after the motion
COMPENSATION_PASSES = 3  # simulate-and-correct passes; the first already lands within counts
INVERSE_BAND = (0.15, 0.35)  # share of the servo rate: full inverse below, faded out up to
QUANTISATION_SHARE = 0.05  # of the acceleration limit that chasing encoder counts may cost
SETTLED = 1.0e-9  # m: command correction below this counts as settled


def tolerance_drives(machine: Machine, joint: str) -> list[Drive]:
    """The described drive of a joint and the corners of its tolerance that differ from it:
    the plants a command compensated for the description is checked on (one drive alone
    where the tolerance is closed)."""
    described = machine.drives[joint]
    return [described] + [d for d in tolerance_corners(described) if d != described]


def corner_plants(machine: Machine, joints: list[str]) -> list[dict[str, Drive]]:
    """The described drives, then the k-th corner of every joint's tolerance together (a
    joint with fewer corners repeats them; one whose tolerance is closed stays as described)."""
    each = [tolerance_drives(machine, j) for j in joints]
    return [{j: c[k % len(c)] for j, c in zip(joints, each)} for k in range(max(len(c) for c in each))]


def compensation_band(drive: DriveModel, max_acceleration: float) -> tuple[float, float]:
    """The band (shares of the servo rate) a correction may use on this drive's encoder:
    INVERSE_BAND, narrowed on a coarse encoder so that chasing its counts (a count at
    frequency f costs resolution * (2 pi f)^2 of acceleration) stays within
    QUANTISATION_SHARE of the acceleration limit."""
    resolution = float(np.max(drive.resolution))
    f_max = math.sqrt(QUANTISATION_SHARE * max_acceleration / resolution) / TWO_PI * drive.period
    hi = min(INVERSE_BAND[1], f_max)
    return hi * INVERSE_BAND[0] / INVERSE_BAND[1], hi


def learn_correction(
    drive: DriveModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, fixed: int,
    band: tuple[float, float] = INVERSE_BAND, weight: np.ndarray | None = None,
) -> np.ndarray:
    """Command correction (n, joints) that makes the drive's simulated feedback follow the
    reference p (with its derivatives v, a), sampled every servo period, at rest at both ends.

    A few iterative-learning passes against DriveModel.simulate with the exact inverse of
    the drive's linear part as learning operator (see VibrationFeed); the first `fixed`
    samples stay uncorrected, so the command starts at rest where the reference does;
    `band` (shares of the servo rate) is where the inverse fades out: nothing above it is
    corrected, encoder quantisation included. ``weight`` (n,), from 0 to 1, fades the
    correction in where the command must join a piece before it (a drill's final stroke
    starts at feed, where the drive already lags). Returns the best correction seen.
    """
    n = p.shape[0]
    learn = _learning_operator(drive, n, band)
    correction = np.zeros_like(p)
    best, best_error = correction, math.inf
    for passes_left in range(COMPENSATION_PASSES - 1, -1, -1):
        dv, da = _derivatives(correction, drive.period)
        feedback = drive.simulate(p + correction, v + dv, a + da)[0]
        error = p - feedback
        judged = error if weight is None else error[weight >= weight.max()]  # where it acts in full
        worst = np.max(np.abs(judged))
        if worst < best_error:
            best, best_error = correction, worst
        if not passes_left:  # a correction learned now would never be simulated, nor chosen
            break
        correction = correction + learn(error)
        correction[:fixed] = 0.0  # starts at rest; leads by the rest left before the motion
        if weight is not None:
            correction *= weight[:, None]
    return best


def settled(
    correction: np.ndarray, motion_end: int, period: float, tolerance: float = SETTLED
) -> np.ndarray:
    """The correction (n, joints) up to where it has settled below `tolerance` (m), but not
    before sample `motion_end`, ending at exactly zero; with its derivatives:
    (3, kept, joints). The command lasts (kept - 1) servo periods."""
    unsettled = np.flatnonzero(np.abs(correction) > tolerance)  # flat, in order: any(axis=1) loops per row
    last = max(motion_end, int(unsettled[-1]) // correction.shape[1] + 1 if unsettled.size else 0)
    kept = correction[: last + 1].copy()
    kept[-1] = 0.0
    return np.stack([kept, *_derivatives(kept, period)])


def learned_command(
    drive: DriveModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, fixed: int, motion_end: int, period: float,
    band: tuple[float, float] = INVERSE_BAND, tolerance: float = SETTLED, weight: np.ndarray | None = None,
    keep_from: int = 0,
) -> np.ndarray:
    """The correction (3, kept, joints) that makes the drive follow the reference p: learned
    (learn_correction), then kept from sample ``keep_from`` until it has settled (settled)."""
    correction = learn_correction(drive, p, v, a, fixed, band, weight)
    return settled(correction[keep_from:], motion_end, period, tolerance)


def _learning_operator(drive: DriveModel, n: int, band: tuple[float, float]) -> Callable[[np.ndarray], np.ndarray]:
    """error (n, joints) -> the correction that removes it: the error convolved with the
    inverse drive response's kernel (_inverse_response) over lags -(n-1)..n-1.

    Computed circularly on a length the FFT is fast at (_fast_length) and at least 2n - 1,
    with the response sampled at that length's bins: no lag wraps onto another, and the
    kernel is the response's, aliased at that period. Until now it was aliased at 2n (the
    error zero-padded to 2n): on the shipped drives the kernel falls off as the cube of
    the lag (the fade is smooth to its first derivative), so the two differ by its aliased
    tail, 3e-7 of the correction at n = 443 and 5e-11 at 15505 (test_compensation), and the
    recorded plans moved by at most 4e-14 m on the lathes and 4e-11 m on the mills. This
    needs no transform of length 2n (numpy's FFT is slow on lengths with a large prime
    factor: thread_m16's 2n = 31010 = 2*5*7*443) nor one of the kernel. Where the kernel
    does not die out (a drive whose loop term K vanishes on the unit circle inside the
    band), no sampling of it is the inverse; the learning passes judge either.
    """
    length = _fast_length(2 * n - 1)
    response = _inverse_response(drive, length, band)
    return lambda error: np.fft.irfft(np.fft.rfft(error, length, axis=0) * response, length, axis=0)[:n]


def _fast_length(n: int) -> int:
    """The least 2^i 3^j 5^k >= n."""
    best = 1
    while best < n:
        best *= 2
    power5 = 1
    while power5 < best:
        power35 = power5
        while power35 < best:
            length = power35
            while length < n:
                length *= 2
            best = min(best, length)
            power35 *= 3
        power5 *= 5
    return best


def _derivatives(x: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """Central first and second differences (along axis 0) of a sequence at rest at both ends."""
    padded = np.concatenate((x[:1], x, x[-1:]))
    return (padded[2:] - padded[:-2]) / (2 * period), (padded[2:] - 2 * x + padded[:-2]) / period**2


def _inverse_response(drive: DriveModel, n: int, band: tuple[float, float] = INVERSE_BAND) -> np.ndarray:
    """Frequency response (np.fft.rfft bins of an n-sample sequence, a column per joint)
    from a feedback error to the command correction that removes it, for each joint's
    linear drive part.

    Per servo period the drive computes v_cmd = ff*v_ref + af*lag*a_ref + kp*(p_ref - y) from
    the encoder reading y taken before the step, lags it by exp(-T/lag) and integrates the
    velocity with the trapezoidal rule; our correction reaches it as p_ref with its central
    differences as v_ref and a_ref. Hence y = G*(K*p_ref - kp*y) with
    G = (1-decay)*T*(1+z) / (2*(z-decay)*(z-1)) and K = ff*D1 + af*lag*D2 + kp, and the
    inverse is (1/G + kp)/K, times z^d for a transport delay of d periods (the drive receives
    p_ref d periods late, so y = G*(K*z^-d*p_ref - kp*y)). G vanishes at half the servo rate (trapezoidal rule), so the
    inverse is faded out over `band`; the vibration lives far below it.

    z, 1/z and the fade are the same for every joint, and only the bins the fade keeps are
    computed; a division by the servo period is the multiplication by its reciprocal that
    numpy's complex division by a real number is, bit for bit.
    """
    period = drive.period
    f = np.fft.rfftfreq(n)  # cycles per servo period
    lo, hi = band
    below = f[f < hi]  # from hi up the fade is 0
    fade = np.sin(0.5 * math.pi * np.clip((hi - below) / (hi - lo), 0.0, 1.0)) ** 2
    kept = fade > 0
    z = np.exp(2j * math.pi * below[kept])
    z_inv = 1 / z
    # the joints' common terms, each computed once (the products below keep their order)
    z_less_1, z_plus_1, central, second = z - 1, 1 + z, z - z_inv, z - 2 + z_inv
    out = np.zeros((f.size, np.ravel(drive.kp).size), dtype=complex)
    fade, within = fade[kept], out[:below.size]  # the bins kept: f below hi, fade above 0
    for j, (kp, ff, af, lag, decay, delay) in enumerate(zip(*(np.ravel(x).tolist() for x in (
            drive.kp, drive.velocity_ff, drive.accel_ff, drive.lag, drive.decay, drive.delay_steps)))):
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_g = 2 * (z - decay) * z_less_1 / ((1 - decay) * period * z_plus_1)
            k = ff * central * (1 / (2 * period)) + af * lag * second * (1 / period**2) + kp
            within[kept, j] = (inv_g + kp) / k * fade
            if delay:  # the command reaches the drive `delay` periods late: correct that much earlier
                within[kept, j] *= z ** delay
    return out
