"""Bottoms on feedback: where the Z command turns so that the drive's feedback turns at a
hole's programmed depth.

The last feed stroke of a hole (plain, or a pecked hole's last peck after its retract and
re-entry) turns where the drive model's feedback turns at the programmed depth
(turning_point). A dwelled hole's last stroke ends at the depth itself instead,
pre-compensated so that its feedback stops there (dwell.py); a vibrated one is
compensated as a whole (VibrationFeed). Below R no Z acceleration ramp is shorter than
BOTTOM_TURN_PERIODS servo periods (z_axis.py), so that no bottom depends on where the
servo instants fall. No drive inside the description's tolerance turns below the
programmed depth: the turning point rises by the deepest one's overshoot.
"""
from __future__ import annotations

import itertools
import math
from typing import Callable

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.drill.cycle import RETURN_CLEARANCE, DrillCycle, DrillError
from cnc_planner.kinds.drill.peck import peck_moves
from cnc_planner.kinds.drill.retract import Retract
from cnc_planner.kinds.drill.z_axis import ZAxis, z_move, z_samples, z_state
from cnc_planner.motion.compensation import tolerance_drives
from cnc_planner.motion.moves import RuckigMove

BOTTOM_ROUNDS = 6  # drive-model rounds placing the Z command's turning point at a hole's bottom
BOTTOM_PHASES = 4  # offsets of a stroke against the servo grid that its turning point is aimed over
BOTTOM_STEADY_S = 0.3  # s of steady feed before R in those rounds: the drive settles into it
LEFT_MATERIAL_LIMIT = 0.2e-3  # m: the most a bottom may rise for the tolerance (ISO 2768-m's
# +-0.2 mm of a 6-30 mm depth); a wider tolerance refuses the job rather than drill short


def reference(cycle: DrillCycle, start: float, lead_in: tuple[RuckigMove, ...], stroke: RuckigMove,
              after: RuckigMove | None, tail: int, phase: float) -> tuple[np.ndarray, ...]:
    """The Z command around a hole's last stroke on a servo grid shifted by ``phase``
    periods: BOTTOM_STEADY_S of steady feed into ``start`` (or into the lead-in moves),
    the stroke from time 0, then ``after`` (an exit) or rest, for ``tail``
    periods more. Returns p, v, a and the index of the stroke's first sample."""
    period, feed = cycle.servo_period, cycle.feed
    lead = sum(m.duration for m in lead_in)
    k = np.arange(-math.ceil(BOTTOM_STEADY_S / period) - math.ceil(lead / period),
                  math.ceil(stroke.duration / period - phase) + tail)
    tau = (phase + k) * period
    p, v, a = start - feed * tau, np.full(len(tau), -feed), np.zeros(len(tau))
    if lead_in:  # at the first move's start velocity (a feed, or rest) before it
        p0, v0, _ = z_state(lead_in[0], 0.0)
        p[tau < 0], v[tau < 0] = p0 + v0 * (tau[tau < 0] + lead), v0
        begin = -lead
        for move in lead_in:
            inside = (tau >= begin) & (tau < begin + move.duration)
            p[inside], v[inside], a[inside] = z_samples(move, tau[inside] - begin)
            begin += move.duration
    inside = tau >= 0
    p[inside], v[inside], a[inside] = z_samples(stroke, tau[inside])
    beyond = tau >= stroke.duration
    if after is not None:
        p[beyond], v[beyond], a[beyond] = z_samples(after, tau[beyond] - stroke.duration)
    return p, v, a, int(np.argmax(inside))


class Bottoms:
    """Each hole's last stroke: where it starts and where its command turns."""

    def __init__(self, machine: Machine, cycle: DrillCycle, z: ZAxis,
                 fast_exit: Callable[[float, float], Retract]):
        self.machine = machine
        self.cycle = cycle
        self.z = z
        self.fast_exit = fast_exit
        self._turns: dict[tuple[float, ...], float] = {}
        self._by_hole: dict[int, float] = {}  # each emit of the timing search asks every hole again
        self._approaches: dict[tuple[float, float, float], tuple[float, tuple[RuckigMove, ...]]] = {}

    def turning_point(self, hole: int) -> float:
        """Where the Z command turns at a hole's bottom, the exit starting there: a feed
        stroke (plain, or a pecked hole's last) turns where the drive's feedback turns at
        the programmed depth. A drive with velocity lag overshoots the end of a feed stroke
        (about 16 um on mill3 at 1200 mm/min), one without full feed-forward falls short.
        A dwelled hole's command ends at the bottom itself, pre-compensated so that the
        feedback stops there (dwell.Dwells); a vibrated one is compensated as a whole."""
        if hole not in self._by_hole:
            c = self.cycle
            _, _, bottom = c.planes(hole)
            plain = not c.compensate_xy or c.vibration is not None or c.dwell > 0
            self._by_hole[hole] = bottom if plain else self._aimed_turn(*self.final_approach(hole), bottom)
        return self._by_hole[hole]

    def final_approach(self, hole: int) -> tuple[float, tuple[RuckigMove, ...]]:
        """Where a hole's last feed stroke starts (feeding) and the Z moves that bring the
        tool there from a steady feed: none for a plain stroke or a single peck (fed from
        R), the previous peck's feed, the last retract and the re-entry for a pecked hole
        (a slow drive is still behind the previous peck when the retract starts)."""
        c = self.cycle
        surface, top, bottom = c.planes(hole)
        if c.peck is None:
            return top, ()
        if (surface, top, bottom) not in self._approaches:
            steps = peck_moves(self.z.peck_move, c.peck, c.feed, top, -c.feed, surface, bottom)
            lead = tuple(step.move for step in steps[-4:-1]) if len(steps) >= 4 else ()
            self._approaches[(surface, top, bottom)] = (z_state(lead[-1], lead[-1].duration)[0] if lead else top, lead)
        return self._approaches[(surface, top, bottom)]

    def _aimed_turn(self, start: float, lead_in: tuple[RuckigMove, ...], bottom: float) -> float:
        """The turning point of a last stroke from ``start``: the drive model runs the
        approach, the stroke and two exits, and the turning point moves by the error, a few
        rounds (one on mill3; a stiff drive whose bottom feedback rings needs about five, as
        the stroke's shape changes with its end)."""
        c = self.cycle
        key = (start, bottom, *(z_state(m, 0.0)[0] for m in lead_in))
        if key not in self._turns:
            period = c.servo_period
            drive = DriveModel(self.machine, period, ("z",))
            steady = math.ceil(BOTTOM_STEADY_S / period)
            turn = bottom
            for _ in range(BOTTOM_ROUNDS):
                stroke = self.z.stroke(start, turn)
                # The exit law is chosen later, per hole, and a stroke starts anywhere
                # between two servo instants: aim between the extremes of the fastest and
                # the gentlest exit (rest to rest above R) sampled at BOTTOM_PHASES, so
                # that every hole lands close.
                errors = []
                for exit_move, phase in itertools.product(self._exits(turn), np.arange(BOTTOM_PHASES) / BOTTOM_PHASES):
                    p, v, a, k0 = reference(c, start, lead_in, stroke, exit_move,
                                            math.ceil(exit_move.duration / period) + steady, phase)
                    drive.reset(p[:1])
                    drive.state.velocity[:] = v[0]
                    errors.append(float(np.min(drive.run(p[:, None], v[:, None], a[:, None])[0][k0:, 0]) - bottom))
                error = 0.5 * (min(errors) + max(errors))
                if abs(error) < 0.5 * float(drive.resolution[0]):
                    break
                turn -= error
                if not self.machine.axes["z"].within_travel(turn):
                    raise DrillError("drill", f"bottom_z: the drive needs a command at {turn} m, outside the Z travel")
            self._turns[key] = turn + self._overshoot(start, lead_in, turn, bottom)
        return self._turns[key]

    def _exits(self, turn: float) -> tuple[RuckigMove, RuckigMove]:
        """The fastest exit from a turning point and the gentlest (rest to rest above R)."""
        c = self.cycle
        return self.fast_exit(turn, c.r_z).move, z_move(self.z.turn, turn, 0.0, 0.0, c.r_z + RETURN_CLEARANCE)

    def _overshoot(self, start: float, lead_in: tuple[RuckigMove, ...], turn: float, bottom: float) -> float:
        """How far the deepest Z drive inside the tolerance goes below ``bottom`` when the
        command turns at ``turn`` (0 if none does): the turning point rises by that much, so
        that no plant inside the tolerance drills deeper than programmed (material is left
        rather than cut; identifying the drives narrows the tolerance and gives it back)."""
        c = self.cycle
        period = c.servo_period
        corners = tolerance_drives(self.machine, "z")[1:]  # the described drive lands on the bottom
        if not corners:
            return 0.0
        stroke = self.z.stroke(start, turn)
        deepest = bottom
        for exit_move in self._exits(turn):  # every corner at once, a column each
            p, v, a, k0 = reference(c, start, lead_in, stroke, exit_move,
                                    math.ceil(exit_move.duration / period) + math.ceil(BOTTOM_STEADY_S / period), 0.0)
            drives = DriveModel.columns(self.machine, period, [("z", d) for d in corners])
            drives.reset(np.full(len(corners), p[0]))
            feedback = drives.run_shared(p[:, None], v[:, None], a[:, None], np.zeros(len(corners), np.int64))[0]
            deepest = min(deepest, float(np.min(feedback[k0:])))
        if bottom - deepest > LEFT_MATERIAL_LIMIT:
            z = self.machine.drives["z"].tolerance
            raise DrillError("drill", f"a Z drive inside its tolerance (kp x{z.kp[0]:g}-{z.kp[1]:g}, velocity_lag "
                                      f"x{z.velocity_lag[0]:g}-{z.velocity_lag[1]:g}, delay {z.delay[0] * 1e3:g}-"
                                      f"{z.delay[1] * 1e3:g} ms) overshoots the bottom by {(bottom - deepest) * 1e3:.3f} mm: "
                                      f"leaving that much material is more than {LEFT_MATERIAL_LIMIT * 1e3:g} mm; "
                                      "narrow drive.z.tolerance (cnc-identify), or dwell at the bottom")
        return bottom - deepest
