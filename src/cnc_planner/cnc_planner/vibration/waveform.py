"""Low-frequency vibration cutting: a feed move whose progress pulses with the spindle angle.

The feed axis moves forward past the feed line to a turning point A_k on the amplitude line
(Q*F ahead) and returns to a return point B_k on the feed line, D times per spindle
revolution (or once every E revolutions, R of them spent in the retreat). Because the
vibration phase slips against the spindle from one revolution to the next, the return of
revolution n+1 re-enters the path cut in revolution n: the tool cuts air there and the chip
breaks. Everything is locked to the absolute spindle angle, so B_k lies at spindle angle
k*2pi/D whatever the move's start.

The vibration of one cycle (u in [0, 1), u = D*theta/2pi) is w(u) = (1 - cos(2pi*phi(u)))/2:
w(0) = 0 is the return point, w(1 - r) = 1 the turning point, r the fraction of the cycle
spent in the retreat (1/2 with D, R/E with E and R). The phase warp phi runs the forward
stroke and the retreat at their own pace but with the same rate at both points, so
acceleration and jerk are continuous and the axis limits follow from the maxima of w's
derivatives.

E and R without Q (er_vibration) follow the method's drawing instead: straight strokes at
one speed (straight_waveform, reversals jerk-limited blends), the retreat a little past
B1 (ER_DEPARTURE), since the drawing itself only touches the previous revolution.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from cnc_msgs_py.machine import Axis
from cnc_msgs_py.units import to_mm

from cnc_planner.motion.compensation import COMPENSATION_TAIL, INVERSE_BAND, compensation_band, learned_command

if TYPE_CHECKING:
    from cnc_servo_bridge.drive import DriveModel

TWO_PI = 2.0 * math.pi
PHASE_SAMPLES = 4096  # points per vibration cycle when scanning the waveform
MAX_EARLIER_REVS = 64  # revolutions looked back for the surface a return can re-enter
LEAD_PERIODS = 8  # rest before the ramp: room for a compensated command to lead the drive
# E and R without Q: the method's straight strokes (equal_speed_q), each reversal this share
# of a vibration long (jerk-limited; 0.16 rev at E 2), and the retreat running ER_DEPARTURE
# feeds per rev past B1: the smallest departure (0.01 steps) that air-cuts in every
# vibration by >= 1 um on the commands and on feedback for E 2, R 0.5 (docs/drill.md).
STRAIGHT_CORNER = 0.08
ER_DEPARTURE = 0.03


class VibrationError(ValueError):
    """A vibration setting that cannot break chips, or that the axis cannot follow.

    ``field`` names the job field (``vibration.Q``, or ``length`` for the feed move itself)
    and ``reason`` says why; the message is the one line "field: reason" a rejection needs.
    """

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


@dataclass(frozen=True)
class Vibration:
    """Chip-breaking vibration: D vibrations per revolution, or one per E revolutions.

    Q is the amplitude in feeds per revolution (amplitude = Q*F). With E and R (D < 1) the
    retreat takes R of the E revolutions; with D the forward stroke and retreat are equal.
    """

    D: float | None
    Q: float
    E: float | None = None
    R: float | None = None
    corner: float | None = None  # straight strokes with reversals this share of a cycle long

    def __post_init__(self) -> None:
        if (self.D is None) == (self.E is None and self.R is None):
            raise VibrationError("vibration", "give D, or E and R (for D < 1), but not both")
        _require_positive("vibration.Q", self.Q)
        if self.D is not None:
            _require_positive("vibration.D", self.D)
            return
        for name, value in (("E", self.E), ("R", self.R)):
            if value is None:
                raise VibrationError(f"vibration.{name}", f"E and R go together, {name} is missing")
            _require_positive(f"vibration.{name}", value)
        if self.E <= 1.0:
            raise VibrationError("vibration.E", f"{self.E:g} revolutions per vibration gives D >= 1; give D instead")
        if self.R >= self.E:
            raise VibrationError(
                "vibration.R", f"the retreat ({self.R:g} revs) must be shorter than the vibration (E = {self.E:g} revs)"
            )

    def shape(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The waveform and its derivatives: cosine strokes, or straight ones (``corner``)."""
        if self.corner is None:
            return waveform(u, self._retreat_fraction)
        return straight_waveform(u, self._retreat_fraction, self.corner)

    @property
    def vibrations_per_rev(self) -> float:
        """The effective D: D itself, or 1/E."""
        return self.D if self.D is not None else 1.0 / self.E

    @property
    def _retreat_fraction(self) -> float:
        return 0.5 if self.D is not None else self.R / self.E

    @property
    def _field(self) -> str:
        return "vibration.D" if self.D is not None else "vibration.E"


def equal_speed_q(E: float, R: float) -> float:
    """Q of the method's E/R waveform: forward and backward at one speed, the turning point
    A1 R revolutions before the return point B1, B1 E revolutions after the start.

    Over a vibration the feed line advances E*F; forward (E - R revs) and back (R revs) at
    one speed v: v*(E - R) - v*R = E*F, so v = E*F/(E - 2R) and A1 stands
    v*(E - R) - (E - R)*F = Q*F ahead of the feed line. Needs R < E/2.

    With straight strokes (the method's drawing) that waveform only touches the previous
    revolution's path: for E 2, R 0.5 the forward stroke from B1 retraces it for half a
    revolution with zero clearance, and breaks no chip (its _min_q is exactly this Q).
    ``er_vibration`` therefore retreats ER_DEPARTURE past B1.
    """
    if not 0.0 < 2.0 * R < E:
        raise VibrationError("vibration.R", f"equal forward and backward speed needs 0 < R < E/2 = {E / 2:g}")
    return 2.0 * R * (E - R) / (E - 2.0 * R)


def er_vibration(E: float, R: float) -> Vibration:
    """E and R without Q, as the method draws it: straight strokes at one speed, reversals
    STRAIGHT_CORNER of a vibration long, the retreat ER_DEPARTURE feeds past B1 (Q a little
    above equal_speed_q), so that the chip really breaks."""
    return Vibration(D=None, Q=equal_speed_q(E, R) + ER_DEPARTURE, E=E, R=R, corner=STRAIGHT_CORNER)


def _require_positive(field: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise VibrationError(field, f"expected a finite number, got {value!r}")
    if value <= 0:
        raise VibrationError(field, f"must be > 0, got {value:g}")


def waveform(u: np.ndarray, r: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """w(u) in [0, 1] and its first three derivatives per cycle; r = retreat fraction of a
    cycle. Unitless, so any axis or direction can scale it by its own amplitude.

    At r = 0.5 (threads, and every vibration given by D) both strokes share one phase rate
    and w is a plain cosine: computed as such, the same values as the general form's, bit
    for bit."""
    x = np.mod(u, 1.0)
    if r == 0.5:
        s, co = np.sin(TWO_PI * x), np.cos(TWO_PI * x)
        pi = math.pi
        return (1.0 - co) / 2.0, pi * s, 2 * pi**2 * co, -4 * pi**3 * s
    retreat = x >= 1.0 - r
    m_fwd, m_ret = 0.5 / (1.0 - r), 0.5 / r
    c = min(m_fwd, m_ret)  # phase rate at B and A, shared by both strokes
    span = np.where(retreat, r, 1.0 - r)
    m = np.where(retreat, m_ret, m_fwd)
    x0 = np.where(retreat, x - (1.0 - r), x)
    k = TWO_PI * x0 / span
    phi = np.where(retreat, 0.5, 0.0) + c * x0 + (m - c) * (x0 - span * np.sin(k) / TWO_PI)
    d1 = c + (m - c) * (1.0 - np.cos(k))
    d2 = (m - c) * TWO_PI * np.sin(k) / span
    d3 = (m - c) * TWO_PI**2 * np.cos(k) / span**2
    s, co = np.sin(TWO_PI * phi), np.cos(TWO_PI * phi)
    pi = math.pi
    w = (1.0 - co) / 2.0
    w1 = pi * s * d1
    w2 = 2 * pi**2 * co * d1**2 + pi * s * d2
    w3 = -4 * pi**3 * s * d1**3 + 6 * pi**2 * co * d1 * d2 + pi * s * d3
    return w, w1, w2, w3


def lift(u: np.ndarray) -> np.ndarray:
    """waveform(u)[0] at r = 0.5 alone, bit for bit: the cosine without its derivatives,
    for checks that only ask where the tool is (the thread's chip check)."""
    return (1.0 - np.cos(TWO_PI * np.mod(u, 1.0))) / 2.0


def straight_waveform(u: np.ndarray, r: float, corner: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The method's drawing: w rises at one speed from B (u = 0) to A (u = 1 - r, w = 1) and
    falls at another back to B, each reversal a jerk-limited blend ``corner`` of a cycle
    long centred on the vertex (the velocity follows a half cosine, so the acceleration is
    continuous). Outside the reversals w is the sharp triangle; inside it stays a little
    short of the vertex (by about 0.09 * corner * the change of slope)."""
    x = np.mod(u, 1.0)
    s_f, s_b = 1.0 / (1.0 - r), -1.0 / r
    w = np.where(x < 1.0 - r, s_f * x, 1.0 + s_b * (x - (1.0 - r)))
    w1 = np.where(x < 1.0 - r, s_f, s_b)
    w2, w3 = np.zeros_like(x), np.zeros_like(x)
    for vertex, change in ((0.0, s_f - s_b), (1.0 - r, s_b - s_f)):
        t = np.mod(x - vertex + corner / 2.0, 1.0)  # from the reversal's start
        inside = t < corner
        k = np.pi * t[inside] / corner
        before = np.where(t[inside] < corner / 2.0, 0.0, 1.0)  # the sharp slope switches at the vertex
        w[inside] += change * (corner * (k / np.pi / 2.0 - np.sin(k) / (2 * np.pi)) - before * (t[inside] - corner / 2))
        w1[inside] += change * ((1.0 - np.cos(k)) / 2.0 - before)
        w2[inside] = change * np.pi / (2 * corner) * np.sin(k)
        w3[inside] = change * np.pi**2 / (2 * corner**2) * np.cos(k)
    return w, w1, w2, w3


def _min_q(vib: Vibration) -> float:
    """Smallest Q at which some return reaches the surface of an earlier revolution.

    Revolution n is m revolutions behind by m*F, so it is re-entered where the vibration
    of m revolutions ago stood at least m*F/(Q*F) further ahead: Q > m / max(w(u - mD) - w(u)).
    """
    u = np.arange(PHASE_SAMPLES) / PHASE_SAMPLES
    w = vib.shape(u)[0]
    best = math.inf
    for m in range(1, MAX_EARLIER_REVS + 1):
        if m >= best:
            break
        gain = np.max(vib.shape(u - m * vib.vibrations_per_rev)[0] - w)
        if gain > 1e-9:
            best = min(best, m / gain)
    return best


def _speed_limits(
    vib: Vibration, feed_per_rev: float, axis: Axis
) -> list[tuple[float, str, float, str]]:
    """Per axis limit: (max spindle speed in rad/s, quantity, limit, unit).

    Velocity grows with the spindle speed, acceleration with its square, jerk with its cube,
    so each limit gives a spindle speed at which the waveform just touches it.
    """
    u = np.arange(PHASE_SAMPLES) / PHASE_SAMPLES
    _, w1, w2, w3 = vib.shape(u)
    d, amp = vib.vibrations_per_rev, vib.Q * feed_per_rev
    # progress per radian of spindle, and its derivatives: velocity = omega * that, etc.
    per_rad = [
        feed_per_rev / TWO_PI * np.max(np.abs(1.0 + vib.Q * d * w1)),
        amp * (d / TWO_PI) ** 2 * np.max(np.abs(w2)),
        amp * (d / TWO_PI) ** 3 * np.max(np.abs(w3)),
    ]
    limits = [
        (axis.max_velocity, "velocity", "m/s"),
        (axis.max_acceleration, "acceleration", "m/s^2"),
        (axis.max_jerk, "jerk", "m/s^3"),
    ]
    return [
        ((limit / k) ** (1.0 / (i + 1)), name, limit, unit)
        for i, (k, (limit, name, unit)) in enumerate(zip(per_rad, limits))
    ]


def _rpm(rad_s: float) -> float:
    return rad_s * 60.0 / TWO_PI


def check_vibration(
    vib: Vibration, feed_per_rev: float, spindle_speed_rad_s: float, axis: Axis
) -> None:
    """Reject a vibration that breaks no chip, or that the feed axis cannot follow.

    Raises:
        VibrationError: one line naming the field and what would work (min Q, max rpm).
        ValueError: feed per revolution or spindle speed not positive.
    """
    if not feed_per_rev > 0 or not spindle_speed_rad_s > 0:
        raise ValueError(
            f"vibration needs a forward feed and a turning spindle, got F={feed_per_rev} m/rev, "
            f"spindle {spindle_speed_rad_s} rad/s"
        )
    d = vib.vibrations_per_rev
    if abs(d - round(d)) < 1e-9:
        raise VibrationError(
            "vibration.D", f"{d:g} is a whole number of vibrations/rev: every return lands in phase "
            f"with the previous revolution, so there is no air-cut; use e.g. D={round(d) + 0.5:g}"
        )
    q_min = _min_q(vib)
    if not vib.Q > q_min:
        raise VibrationError(
            "vibration.Q", f"{vib.Q:g} gives no air-cut at D={d:g}; "
            f"need Q > {math.ceil(q_min * 100 - 1e-6) / 100:.2f}"
        )
    limits = _speed_limits(vib, feed_per_rev, axis)
    omega_max, name, limit, unit = min(limits)
    if spindle_speed_rad_s > omega_max:
        order = ("velocity", "acceleration", "jerk").index(name) + 1
        need = limit * (spindle_speed_rad_s / omega_max) ** order
        raise VibrationError(
            vib._field, f"the {axis.name} axis cannot follow {d:g} vibrations/rev at "
            f"{_rpm(spindle_speed_rad_s):.0f} rpm (needs {name} {need:.3g} {unit} > {limit:g}); "
            f"max spindle speed {math.floor(_rpm(omega_max)):.0f} rpm"
        )


def _ruckig(start: tuple[float, float, float], target: tuple[float, float, float], axis: Axis,
            minimum_duration: float | None = None) -> Trajectory | None:
    """A jerk-limited single-axis segment between two states, or None if ruckig finds none."""
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = ([v] for v in start)
    inp.target_position, inp.target_velocity, inp.target_acceleration = ([v] for v in target)
    inp.max_velocity = [axis.max_velocity]
    inp.max_acceleration = [axis.max_acceleration]
    inp.max_jerk = [axis.max_jerk]
    if minimum_duration is not None:
        inp.minimum_duration = minimum_duration
    trajectory = Trajectory(1)
    try:
        result = Ruckig(1).calculate(inp, trajectory)
    except RuckigError:  # raised instead of returned for some numerically hard inputs
        return None
    return trajectory if result in (Result.Working, Result.Finished) else None


def _evaluate(trajectory: Trajectory, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    out = np.array([[x[0] for x in trajectory.at_time(float(ti))] for ti in t]).reshape(-1, 3)
    return out[:, 0], out[:, 1], out[:, 2]


class VibrationFeed:
    """A straight feed move of `length` with the chip-breaking vibration superimposed.

    Timeline of the motion: LEAD_PERIODS servo periods at rest (room for a compensated
    command to lead the drive; kept without compensation too, so both describe one
    motion); a ruckig ramp from rest onto the running waveform at the first servo instant
    it can reach it (position, velocity and acceleration matched); the waveform locked to
    the spindle angle; and, at the last servo instant before the waveform would pass
    `length` from which it can, a time-optimal ruckig stop exactly at `length` without
    overshoot, so every air-cut up to the end is kept. Ramps and waveform stay within the
    axis limits (check_vibration). Near the speed limit the waveform runs at the jerk
    limit and the ramp takes up to a vibration to catch it: with D < 1 the first
    revolutions after the start then cut without air.

    With `drive_model_factory`, `sample` returns the command that makes the drive's
    feedback follow that motion, precomputed on the servo grid. Method: a model inverse
    refined against the model itself. The drive's linear part (position loop, velocity
    feed-forward, velocity-loop lag, encoder read a period late, trapezoidal integration)
    is inverted analytically in the frequency domain from the DriveModel's own parameters
    (_inverse_response); that inverse is the learning operator of a few iterative-learning
    passes against DriveModel.simulate, the very model the bridge runs, which also has
    what the inverse leaves out (rate limits, quantisation). With an exact linear inverse
    each pass is a Newton step: one pass brings the feedback to within an encoder count
    for any gains, where a plain lead-and-filter learning law needs many passes and
    barely converges on a drive without feed-forward (tried). The inverse is non-causal (the
    command must lead), which is what the rest at the start leaves room for; after the
    motion the command keeps settling until its correction is below SETTLED, and
    `duration` includes that. The command leads the motion, so where ruckig switches
    jerk it briefly needs more jerk than the axis limit; the motion itself is the
    waveform above.
    """

    def __init__(
        self,
        length: float,
        feed_per_rev: float,
        vib: Vibration,
        spindle_speed_rad_s: float,
        axis: Axis,
        start_angle: float = 0.0,
        drive_model_factory: Callable[[], DriveModel] | None = None,
        servo_period: float = 1e-3,
    ) -> None:
        if not length > 0:
            raise ValueError(f"length: a vibration feed needs a length > 0, got {length}")
        check_vibration(vib, feed_per_rev, spindle_speed_rad_s, axis)
        self._length = length
        self._f = feed_per_rev
        self._vib = vib
        self._omega = spindle_speed_rad_s
        self._axis = axis
        self._start_angle = start_angle
        self._period = servo_period
        drive = drive_model_factory() if drive_model_factory is not None else None
        self._band = compensation_band(drive, axis.max_acceleration) if drive is not None else INVERSE_BAND
        # the narrower the band, the longer the correction leads the motion
        self._lead_periods = math.ceil(LEAD_PERIODS * INVERSE_BAND[1] / self._band[1])
        self._t_lead = self._lead_periods * servo_period
        self._feed_origin = start_angle + spindle_speed_rad_s * self._t_lead
        self._t_join, self._ramp_in = self._join()
        self._t_stop, self._ramp_out = self._stop()
        self._t_end = self._t_stop + self._ramp_out.duration
        self._correction: np.ndarray | None = None
        # whole servo periods: the move's last setpoint is its end state
        self._duration = math.ceil(self._t_end / servo_period - 1e-9) * servo_period
        if drive is not None:
            self._compensate(drive)

    @property
    def duration(self) -> float:
        """Seconds from the start at rest to the end at rest at `length`, whole servo periods."""
        return self._duration

    @property
    def arrival(self) -> float:
        """Seconds until the motion reaches `length`; the compensated command settles after."""
        return self._t_end

    # -- the ideal waveform -------------------------------------------------------------
    def _steady(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Progress locked to the spindle angle: feed line plus Q*F*w(D*theta/2pi)."""
        d = self._vib.vibrations_per_rev
        theta = self._start_angle + self._omega * t
        rate = d * self._omega / TWO_PI  # vibration cycles per second
        w, w1, w2, _ = self._vib.shape(d * theta / TWO_PI)
        amp = self._vib.Q * self._f
        s = self._f * (theta - self._feed_origin) / TWO_PI + amp * w
        v = self._f * self._omega / TWO_PI + amp * rate * w1
        a = amp * rate**2 * w2
        return s, v, a

    def _state(self, t: float) -> tuple[float, float, float]:
        s, v, a = self._steady(np.array([t]))
        return float(s[0]), float(v[0]), float(a[0])

    def _join(self) -> tuple[float, Trajectory]:
        """The first servo instant the axis can reach the running waveform from rest."""
        t_cycle = TWO_PI / (self._vib.vibrations_per_rev * self._omega)
        for k in range(1, int(2 * t_cycle / self._period) + 100):
            t = self._t_lead + k * self._period
            target = self._state(t)
            fastest = _ruckig((0.0, 0.0, 0.0), target, self._axis)
            if fastest is None or fastest.duration > k * self._period:
                continue
            ramp = _ruckig((0.0, 0.0, 0.0), target, self._axis, minimum_duration=k * self._period)
            if ramp is not None and abs(ramp.duration - k * self._period) < 1e-9:
                return t, ramp
        raise VibrationError(self._vib._field, "the axis cannot ramp onto the vibration")

    def _stop(self) -> tuple[float, Trajectory]:
        """Leave the waveform as late as possible: the last servo instant before the tool
        would pass `length` from which a time-optimal stop ends at `length` without
        overshoot. Every air-cut the waveform makes before the end is kept."""
        d = self._vib.vibrations_per_rev
        f, amp = self._f, self._vib.Q * self._f
        u = np.arange(PHASE_SAMPLES + 1) / PHASE_SAMPLES
        # furthest the tool gets ahead of a cycle's return point
        reach = float(np.max(f * u / d + amp * self._vib.shape(u)[0]))
        # the first cycle (from return point B_k) that can reach length
        k = math.ceil(d * ((self._length - reach) * TWO_PI / f + self._feed_origin) / TWO_PI)
        t_reach = k * TWO_PI / (d * self._omega) - self._start_angle / self._omega
        t_cycle = TWO_PI / (d * self._omega)
        t = self._t_join + self._period * np.arange(
            math.ceil((t_reach + 2 * t_cycle - self._t_join) / self._period) + 1
        )
        beyond = np.flatnonzero(self._steady(t)[0] > self._length)
        if beyond.size and beyond[0] > 0:
            for t_stop in t[beyond[0] - 1 :: -1]:
                stop = _ruckig(self._state(t_stop), (self._length, 0.0, 0.0), self._axis)
                if stop is not None and stop.position_extrema[0].max <= self._length + 1e-12:
                    return float(t_stop), stop
        raise VibrationError(
            "length", f"a {to_mm(self._length):g} mm feed is too short to ramp onto the vibration "
            f"at D={d:g} and stop (one vibration reaches {to_mm(reach):.3g} mm)"
        )

    def _ideal(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, v, a = (np.zeros_like(t) for _ in range(3))
        steady = (t >= self._t_join) & (t < self._t_stop)
        s[steady], v[steady], a[steady] = self._steady(t[steady])
        for t0, t1, seg in ((self._t_lead, self._t_join, self._ramp_in),
                            (self._t_stop, self._t_end, self._ramp_out)):
            inside = (t >= t0) & (t < t1)
            if inside.any():
                s[inside], v[inside], a[inside] = _evaluate(seg, t[inside] - t0)
        s[t >= self._t_end] = self._length
        return s, v, a

    # -- servo lag pre-compensation -----------------------------------------------------
    def _compensate(self, drive: DriveModel) -> None:
        """Learn the command correction that makes the simulated feedback follow the ideal."""
        if not math.isclose(drive.period, self._period):
            raise ValueError(
                f"drive_model_factory: the drive runs every {drive.period} s, "
                f"the move every {self._period} s"
            )
        n = math.ceil((self._t_end + COMPENSATION_TAIL) / self._period) + 1
        t = np.arange(n) * self._period
        s, v, a = self._ideal(t)
        # settled to half an encoder count: the drive cannot show less, and the tool rests at
        # `length` meanwhile, cutting the ring the last revolution left
        self._correction = learned_command(drive, s[:, None], v[:, None], a[:, None], self._lead_periods // 2,
                                           round(self._duration / self._period), self._period, self._band,
                                           tolerance=0.5 * float(drive.resolution[0]))[:, :, 0]
        self._duration = (self._correction.shape[1] - 1) * self._period

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Progress s (m), ds/dt and d2s/dt2 at local times t (s, an array); the command if
        compensating; from `duration` on, the end state at rest."""
        t = np.asarray(t, dtype=float)
        s, v, a = self._ideal(t)
        if self._correction is not None:
            grid = np.arange(self._correction.shape[1]) * self._period
            s, v, a = (x + np.interp(t, grid, c) for x, c in zip((s, v, a), self._correction))
        done = t >= self._duration
        s[done], v[done], a[done] = self._length, 0.0, 0.0
        return s, v, a

    @property
    def settle_start(self) -> float:
        """The first servo instant at or after `arrival`: from it on the motion rests at
        `length` and only the command's correction still moves (``settling``)."""
        return math.ceil(self._t_end / self._period - 1e-9) * self._period

    def settling(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The command's correction at local times t >= settle_start (zero without
        compensation and from `duration` on): what a move that follows from `length` at
        once carries on top of its own command, so that the feedback still arrives as
        planned (the drive is linear; its feedback is the sum of both responses)."""
        s, v, a = self.sample(np.asarray(t, dtype=float))
        return s - self._length, v, a


