"""Dwells (G82) on feedback: a dwelled hole's last stroke and its dwell as one Z command,
pre-compensated with the drive model so that the feedback stops at the depth without
passing it and holds it for the dwell (learned, or where that cannot land, aimed and then
settled onto the depth)."""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.drill.bottom import Bottoms, reference
from cnc_planner.kinds.drill.cycle import DrillCycle, DrillError
from cnc_planner.kinds.drill.z_axis import ZAxis, z_move, z_samples, z_state
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.compensation import compensation_band, learned_command
from cnc_planner.motion.moves import Limits, RuckigMove
from cnc_planner.motion.timeline import Piece

DWELL_BLEND_S = 0.05  # s: a dwelled hole's stroke correction fades in over this (or half the stroke)
DWELL_PHASES = 8  # offsets against the servo grid a dwelled stroke's correction is learned at
DWELL_TOLERANCE = 1e-6  # m (or an encoder count): the feedback is at a dwell's bottom within this
DWELL_KEPT = 2e-6  # m (or an encoder count): a learned dwell correction landing this close is kept
DWELL_SETTLE_TIME_CONSTANTS = 3.0  # of the drive (1/kp + velocity lag): a settle onto a dwell's bottom
DWELL_SETTLE_ROUNDS = 10  # drive-model rounds aiming a settled dwell's stroke and slowing its settle


def _arrival_periods(machine: Machine, feedback: np.ndarray, end: int, bottom: float) -> int:
    """Servo periods after sample ``end`` (the stroke's end) from which the feedback
    stays at the bottom within DWELL_TOLERANCE (or an encoder count)."""
    tolerance = max(DWELL_TOLERANCE, machine.drives["z"].resolution)
    off = np.nonzero(np.abs(feedback[end:] - bottom) > tolerance)[0]
    return int(off[-1]) + 1 if len(off) else 0


class Dwells:
    """The compensated last stroke and dwell of each dwelled hole."""

    def __init__(self, machine: Machine, cycle: DrillCycle, z: ZAxis, bottoms: Bottoms):
        self.machine = machine
        self.cycle = cycle
        self.z = z
        self.bottoms = bottoms
        self._corrections: dict[tuple[float, ...], tuple[np.ndarray, float]] = {}

    def correction(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                   phase: float) -> tuple[np.ndarray, float]:
        """The drive-model correction (3, k) of a dwelled hole's last stroke and its dwell,
        at the servo instants from the stroke's start (the first ``phase`` periods after
        it; a stiff drive's bottom depends on where they fall), and how long after the
        stroke's end the feedback arrives (s): the command (stroke to the bottom plus
        correction) makes the feedback stop at the bottom and hold it. Learned first
        (_learned, the fastest); where its feedback still misses the bottom by
        more than DWELL_KEPT (a drive far behind after a fast re-entry, ringing or without
        acceleration headroom), the stroke is aimed and settled instead (_settled),
        and whichever lands closer is kept."""
        key = (start, bottom, phase, *(z_state(m, 0.0)[0] for m in lead_in))
        if key not in self._corrections:
            learned = self._learned(start, lead_in, bottom, phase)
            if abs(learned[2]) > max(DWELL_KEPT, self.machine.drives["z"].resolution):
                learned = min(learned, self._settled(start, lead_in, bottom, phase), key=lambda c: abs(c[2]))
            self._corrections[key] = learned[:2]
        return self._corrections[key]

    def _learned(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                 phase: float) -> tuple[np.ndarray, float, float]:
        """The correction learned against the drive model, and its feedback's deepest
        point past the bottom (m, negative = deeper). The correction makes the feedback
        follow the stroke to rest at the bottom and hold there, where a plain stroke's
        feedback would overshoot it and come back (velocity lag) or creep in late
        (no full feed-forward). It fades in over the first DWELL_BLEND_S of
        the stroke (the drive arrives lagging from the moves before it; longer, into the
        dwell, where the command would break the Z limits otherwise) and out over the
        dwell's last DWELL_BLEND_S (what is left there chases encoder counts); where the
        drive cannot catch up by the stroke's end (a slow drive after a fast re-entry), the
        command rests at the bottom until the feedback is there, and the dwell counts from
        then: it is held on feedback."""
        c = self.cycle
        period = c.servo_period
        stroke = self.z.stroke(start, bottom)
        drive = DriveModel(self.machine, period, ("z",))
        band = compensation_band(drive, self.machine.axes["z"].max_acceleration)  # a coarse encoder's counts
        late = 0
        blends = [min(DWELL_BLEND_S, 0.5 * stroke.duration)] + [DWELL_BLEND_S * 2 ** k for k in range(4)]
        for _ in range(2):  # learn, then learn again with the rest the feedback needs
            p, v, a, k0 = reference(c, start, lead_in, stroke, None, math.ceil(c.dwell / period) + late, phase)
            tau = (phase + np.arange(len(p)) - k0) * period
            fade = min(DWELL_BLEND_S, 0.5 * c.dwell)
            for blend in blends:  # a drive far behind needs a longer fade-in within the limits
                share = np.clip(np.minimum(tau / blend, (tau[-1] - tau) / fade), 0.0, 1.0)
                weight = np.sin(0.5 * math.pi * share) ** 2
                kept = learned_command(drive, p[:, None], v[:, None], a[:, None], 0, len(p) - k0 - 1, period, band,
                                       weight=weight, keep_from=k0)
                command = np.zeros((3, len(p)))
                command[:, k0:k0 + kept.shape[1]] = kept[:, :, 0]
                if (np.max(np.abs(v + command[1])) <= self.z.rapid.velocity
                        and np.max(np.abs(a + command[2])) <= self.z.rapid.acceleration):
                    break
            feedback = drive.simulate(*(x[:, None] + dx[:, None] for x, dx in zip((p, v, a), command)))[0][:, 0]
            end = k0 + math.ceil(stroke.duration / period - phase)
            arrived = _arrival_periods(self.machine, feedback, end, bottom)
            if arrived <= late:
                break
            late = arrived
        return kept[:, :, 0], late * period, float(np.min(feedback[k0:]) - bottom)

    def _settled(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float,
                 phase: float) -> tuple[np.ndarray, float, float]:
        """The correction without learning, as (correction, arrival, deepest point past
        the bottom): the stroke turns where the drive model's feedback reaches the bottom
        and no deeper (aimed like a plain stroke's turning point), then the command
        settles onto the bottom in a smooth rest-to-rest move over
        DWELL_SETTLE_TIME_CONSTANTS of the drive (slower while the settle itself would
        pass the bottom), where the feedback comes to rest for the dwell. The command
        stays within the plain Z limits: it holds where a learned correction has no room
        (a drive far behind after a fast re-entry, or one that rings)."""
        c = self.cycle
        period = c.servo_period
        stroke = self.z.stroke(start, bottom)
        drive = DriveModel(self.machine, period, ("z",))
        settle_time = DWELL_SETTLE_TIME_CONSTANTS * (1.0 / float(drive.kp[0]) + float(drive.lag[0]))
        aim = 0.5 * max(DWELL_TOLERANCE, float(drive.resolution[0]))
        turn, late, best = bottom, 0, None
        for _ in range(DWELL_SETTLE_ROUNDS):
            aimed = self.z.stroke(start, turn)
            # jerk alone limits it to the settle time: the smoothest rest-to-rest move
            jerk = min(self.z.rapid.jerk, 32.0 * abs(turn - bottom) / settle_time**3) or self.z.rapid.jerk
            settle = z_move(Limits(self.z.rapid.velocity, self.z.rapid.acceleration, jerk), turn, 0.0, 0.0, bottom,
                             duration=settle_time)
            settled_at = math.ceil((aimed.duration + settle.duration - stroke.duration) / period)
            tail = math.ceil(c.dwell / period) + max(late, settled_at) + math.ceil(settle_time / period)
            p, v, a, k0 = reference(c, start, lead_in, aimed, settle, tail, phase)
            drive.reset(p[:1])
            drive.state.velocity[:] = v[0]
            feedback = drive.run(p[:, None], v[:, None], a[:, None])[0][:, 0]
            end = k0 + math.ceil(stroke.duration / period - phase)
            late = max(settled_at, _arrival_periods(self.machine, feedback, end, bottom))
            deepest = k0 + int(np.argmin(feedback[k0:]))
            error = float(feedback[deepest] - bottom)
            if best is None or abs(error) < abs(best[2]):
                plain = np.stack(z_samples(stroke, (phase + np.arange(len(p) - k0)) * period))
                best = (np.stack((p, v, a))[:, k0:] - plain, late * period, error)
            if abs(error) <= aim:
                break
            if (phase + deepest - k0) * period > aimed.duration + 0.5 * settle.duration:
                settle_time *= 2.0  # the settle itself passes the bottom: slower, the turn stays
                continue
            turn -= error
            if not self.machine.axes["z"].within_travel(turn):
                raise DrillError("drill", f"bottom_z: the drive needs a command at {turn} m, outside the Z travel")
        return best

    def stroke(self, builder: PlanBuilder, t: float, hole: int) -> float:
        """A dwelled hole's last stroke and its dwell as one compensated Z command
        (correction); returns the end of the dwell."""
        c = self.cycle
        bottom = c.planes(hole)[2]
        start, lead_in = self.bottoms.final_approach(hole)
        stroke = self.z.stroke(start, bottom)
        # the first servo instant after t, in periods, to 1/DWELL_PHASES
        phase = round((math.ceil(t / c.servo_period - 1e-9) - t / c.servo_period) * DWELL_PHASES) / DWELL_PHASES
        correction, late = self.correction(start, lead_in, bottom, phase)
        grid = (phase + np.arange(correction.shape[1])) * c.servo_period

        def sample(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return tuple(x + np.interp(tt, grid, dx, right=0.0)  # type: ignore[return-value]
                         for x, dx in zip(z_samples(stroke, tt), correction))

        arrival = t + stroke.duration + late
        builder.timelines["z"].add(Piece(t, arrival + c.dwell - t, sample), bottom)
        builder.event(arrival, "dwell", hole=hole, seconds=c.dwell)
        return arrival + c.dwell
