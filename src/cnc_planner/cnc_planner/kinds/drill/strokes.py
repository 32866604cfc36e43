"""S2 below the X/Y plane: the feed strokes that drill a hole, plain, pecked or vibrated,
and the dwell at its bottom.

Each hole may have its own surface, R and bottom (hole_planes; r_z is then the plane X/Y
moves above, the highest R, and Z falls fast from it to the hole's R); the feed to the
bottom is plain, vibrated (chip breaking locked to the spindle angle, VibrationFeed: Z
reaches R at rest) or in pecks (peck.py); a dwell (G82) may follow. X/Y stands still over
the hole throughout. A move between two holes that passes over a clamp has its own,
higher X/Y plane (air_planes): the retract before it, its air arc and the fall into the
next hole run to and from that plane, every other move stays at r_z.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.drill.bottom import Bottoms
from cnc_planner.kinds.drill.cycle import DrillCycle, DrillError
from cnc_planner.kinds.drill.dwell import Dwells
from cnc_planner.kinds.drill.peck import peck_moves
from cnc_planner.kinds.drill.z_axis import ZAxis, add_z, z_move
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.timeline import Piece
from cnc_planner.vibration.feed import vibration_error
from cnc_planner.vibration.waveform import VibrationError, VibrationFeed


class Strokes:
    """The feed of each hole from the X/Y plane to its bottom and the dwell there."""

    def __init__(self, machine: Machine, cycle: DrillCycle, z: ZAxis, bottoms: Bottoms, dwells: Dwells):
        self.machine = machine
        self.cycle = cycle
        self.z = z
        self.bottoms = bottoms
        self.dwells = dwells
        self._vibrated: dict[tuple[float, float], VibrationFeed] = {}
        self._settling: list[tuple[PlanBuilder, float, float, VibrationFeed]] = []

    def feed_to_depth(self, builder: PlanBuilder, t_down: float, hole: int, overlapped: bool,
                      plane: float) -> float:
        """S2 below the X/Y plane (Z at ``plane``): fast down to the hole's own R if it lies lower, the feed
        (plain, vibrated or in pecks) to the bottom, then the dwell (G82); returns when Z
        leaves the bottom. ``overlapped``: Z arrives at the plane moving (the air arc).
        In the overlapped cycle a dwelled hole's last stroke and dwell are one compensated
        command (dwell.Dwells); the conventional cycle holds its plain command."""
        c = self.cycle
        _, top, bottom = c.planes(hole)
        v = c.entry_velocity if overlapped else 0.0
        t = t_down
        if top < plane - 1e-12:
            t = add_z(builder, t, z_move(self.z.rapid, plane, v, 0.0, top, v))
        compensated_dwell = c.dwell > 0 and overlapped and c.compensate_xy and c.vibration is None
        if c.vibration is not None:
            end = self.vibrated(builder, t, hole)
        elif compensated_dwell:
            if c.peck is not None:
                t = self.pecks(builder, t, hole, v, last=False)
            return self.dwells.stroke(builder, t, hole)
        elif c.peck is not None:
            end = self.pecks(builder, t, hole, v)
        elif overlapped:
            end = add_z(builder, t, self.z.stroke(top, self.bottoms.turning_point(hole)))
        else:
            end = builder.linear({"z": self.bottoms.turning_point(hole)}, c.feed, start=t)
        if c.dwell > 0:
            builder.timelines["z"].add_hold(end, c.dwell)
            builder.event(end, "dwell", hole=hole, seconds=c.dwell)
        return end + c.dwell

    def vibrated(self, builder: PlanBuilder, t_down: float, hole: int) -> float:
        """S2 below R with the chip-breaking vibration: Z from rest at the hole's R to rest
        at its bottom, the waveform locked to the spindle angle and its command
        pre-compensated with the drive model (VibrationFeed); returns when the motion
        arrives at the bottom. What follows (a dwell, the retract) starts there: the
        command's correction, still settling, rides on it (settle_corrections), so no
        revolution is spent at the bottom waiting for it. Strokes are cached by length and
        start angle, since the timing search replans the cycle."""
        c = self.cycle
        _, top, bottom = c.planes(hole)
        angle = builder.timelines[SPINDLE].position_at(t_down)
        key = (round(top - bottom, 12), round(math.fmod(angle, 2 * math.pi), 9))
        if key not in self._vibrated:
            z = self.machine.axes["z"]
            try:
                self._vibrated[key] = VibrationFeed(
                    top - bottom, c.feed * 2 * math.pi / c.spindle_speed, c.vibration, c.spindle_speed, z,
                    start_angle=angle, servo_period=c.servo_period,
                    drive_model_factory=lambda: DriveModel(self.machine, c.servo_period, ("z",)))
            except VibrationError as err:
                named = vibration_error(err)  # a vibration.X field, or the stroke's length: the depth
                raise (DrillError("drill.depth", named.reason) if named.field == "length" else named) from err
        move = self._vibrated[key]

        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            progress, v, a = move.sample(t)
            return top - progress, -v, -a

        end = t_down + move.settle_start
        builder.timelines["z"].add(Piece(t_down, move.settle_start, sample), bottom)
        if move.duration > move.settle_start:
            self._settling.append((builder, end, t_down + move.duration, move))
        builder.event(t_down, "vibration_feed", start=[top], direction=[-1.0], joints=["z"],
                      length=top - bottom, feed_per_rev=c.feed * 2 * math.pi / c.spindle_speed,
                      field="drill", hole=hole, vibration=c.vibration_choice)
        builder.event(end, "vibration_end", hole=hole)
        return end

    def settle_corrections(self, builder: PlanBuilder) -> None:
        """Superimpose each vibrated stroke's settling correction (VibrationFeed.settling)
        on the Z pieces that follow it in ``builder``: call once the cycle's Z is complete.

        Raises:
            DrillError: a correction outlasts the Z pieces planned after its stroke (the
                cycle would end while Z still settles), which the cycle never plans.
        """
        mine = [entry for entry in self._settling if entry[0] is builder]
        self._settling = [entry for entry in self._settling if entry[0] is not builder]
        z = builder.timelines["z"]
        for _, t0, t1, move in mine:
            covered = 0.0
            for k, piece in enumerate(z.pieces):
                lo, hi = max(piece.start, t0), min(piece.end, t1)
                if hi > lo:
                    z.replace(k, Piece(piece.start, piece.duration, _with_settling(piece, t0, t1, move)))
                    covered += hi - lo
            if covered < t1 - t0 - 1e-9:
                raise DrillError("drill", f"the Z command still settles {t1 - t0 - covered:.3f} s after the cycle")

    def pecks(self, builder: PlanBuilder, t: float, hole: int, v0: float, last: bool = True) -> float:
        """The peck sequence of a hole from its R (moving at v0) to rest at its bottom, its
        last feed turning at the turning point; without that feed if not ``last`` (a
        dwelled hole's, compensated with its dwell)."""
        c = self.cycle
        surface, top, bottom = c.planes(hole)
        steps = peck_moves(self.z.peck_move, c.peck, c.feed, top, v0, surface, bottom,
                           self.bottoms.turning_point(hole))
        for k, step in enumerate(steps):
            if step.kind == "feed" and step.peck > 0:
                builder.event(t, "peck", hole=hole, peck=step.peck, previous_bottom=step.bottom)
            elif step.kind == "reentry":
                builder.event(t, "reentry", hole=hole, peck=step.peck, previous_bottom=step.bottom)
            if last or k < len(steps) - 1:
                t = add_z(builder, t, step.move)
        return t


def _with_settling(piece: Piece, t0: float, t1: float, move: VibrationFeed):
    """The piece's sampler plus the stroke's settling correction (down: Z is -progress)
    between plan times t0 (its settle_start) and t1."""
    base = piece.sample
    offset = move.settle_start - t0

    def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, v, a = base(t)
        g = t + piece.start
        inside = (g >= t0) & (g < t1)
        if inside.any():
            p, v, a = p.copy(), v.copy(), a.copy()
            ds, dv, da = move.settling(g[inside] + offset)
            p[inside] -= ds
            v[inside] -= dv
            a[inside] -= da
        return p, v, a

    return sample
