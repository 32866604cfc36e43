"""Every pass of every start cut as one continuous motion of x and z (ThreadCycle): the
joins onto each pass's helix, the pull-outs past end_z, and the drive compensation.

Every pass's helix passes start_z at the same spindle phase (the index, plus 360/starts
per start), so all passes land in one groove; z is locked to the spindle angle, not to
time. Each pass pulls out as soon as it is past end_z, into the relief groove. The whole
cycle's x/z command is pre-compensated with the drive model (motion.compensation) so the
bridge's feedback, not only the command, holds lead, depth and flank offset.
"""
from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from ruckig import Trajectory

from cnc_msgs_py.machine import Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.thread._stock_kernel import inside_stock
from cnc_planner.kinds.thread.helix import helix, helix_peaks
from cnc_planner.kinds.thread.joins import Revolution, latest
from cnc_planner.kinds.thread.ramps import Ramps, z_to_speed
from cnc_planner.kinds.thread.spec import JOINTS, TWO_PI, Pass, ThreadError, ThreadSpec, left_standing, passes_of
from cnc_planner.kinds.thread.stretches import Stretch, at_rest, moving, pieces, sample_track
from cnc_planner.motion.compensation import COMPENSATION_TAIL, learned_command

COMPENSATION_BAND = (0.05, 0.12)  # of the servo rate (50..120 Hz at 1 ms): above the vibration,
# below the encoder quantisation noise a wider band would feed into the command's jerk
LEAD_TIME = 0.06  # s at rest before the ramp: the band-limited compensation leads this far
SETTLED_COUNTS = 0.25  # encoder counts: a command correction below this has settled
MAX_AIR_S = 3.0  # s: longest the search for a pass's join looks beyond its earliest start
JOIN_ROOM_REVS = 0.05  # revolutions of helix, at least, between joining it and the face
TURN_ROOM = (0.5e-3, 1e-3, 2e-3)  # m in front of a join where z may turn at rest, so that x
# plunges while z is clear of the face
THROUGH_SPEEDS = (0.03, 0.02, 0.01)  # m/s: speeds at which a z return may cross the face outwards
THROUGH_FRONT = 0.05e-3  # m in front of the face where it crosses at that speed
REVOLUTIONS_AT_ONCE = 2  # helix revolutions of candidate joins evaluated in one call
JOIN_JERK_STEP = 1.0  # of the axis jerk limit: the largest jerk step onto a helix
JERK_PROBE_S = 1e-5  # s: the jerk either side of a join is the acceleration's slope over this
GRID_ROUNDING = 1e-9  # s: an instant this close to a servo instant is read as it
MISS_MARGIN = 1e-6  # s: a join is passed over untried only if z's fastest time misses it by more
# (ruckig's rounding is far below)

Crossing = tuple[float, list[float], Stretch]  # z crossing the face outwards: (cycle time, state, the stretch there)


@dataclass
class CutTiming:
    """Where one pass of one start lies on the cycle's clock (s from the cycle start)."""

    cut: Pass
    start: int
    theta_ref: float  # absolute spindle angle at which this pass's helix passes start_z
    t_begin: float  # its air path begins (the previous pass leaves its helix)
    t_join: float  # on the helix
    t_out: float  # leaves the helix past end_z
    retract: Trajectory  # x out towards spec.air_radius from t_out (the last pass: the clearance
    # radius, unless z runs straight back and x turns back down to it)
    stop: Trajectory  # z to rest from t_out
    t_done: float | None = None  # the last pass, where z turns back at once: when z stops

    @property
    def t_end(self) -> float:
        """When the pass is over: x out and z at rest (the last pass: z turning back)."""
        return self.t_out + max(self.retract.duration, self.stop.duration) if self.t_done is None else self.t_done


class ThreadCycle:
    """Every pass of every start as one continuous motion of x and z, on a clock from the
    cycle start (at rest in front of the face: where the tool stands, or the clearance
    radius at start_z).

    The first pass runs from there straight onto its helix, both axes leaving at the last
    servo instant they can, onto the latest join of its helix revolution. Between passes
    the tool never stops to wait. At the first servo instant past end_z (the relief
    groove) x pulls out, heading for spec.air_radius, and z runs one jerk-limited path onto
    the next pass's running helix, timed to arrive there at the servo instant the spindle
    phase allows: straight from the helix where x leaves the stock in time, else from rest
    once x is out, or crossing the face as soon as it can at THROUGH_SPEEDS and turning in
    front of it (the deepest passes, where x needs that long to plunge), or turning at rest
    TURN_ROOM in front of the join. x turns back from its way out at the latest instant
    from which it still lands on the helix. Which helix revolution a pass joins is the
    earliest whose join lies before the face by ``room`` revolutions (JOIN_ROOM_REVS by
    default; more on a machine whose drives may differ: tolerance.join_room), that the axes
    can reach with the tool never inside the stock over the thread, and where the jerk
    steps by at most JOIN_JERK_STEP. After the last pass z runs straight back to start_z while x pulls
    out and turns back down to the clearance radius (else z waits at rest until x is out),
    inside the cycle. With a drive model the whole cycle is compensated at once
    (motion.compensation): the command's lead-in of each pass runs while the tool is
    still in the air, and only the cycle's start needs LEAD_TIME at rest.
    """

    def __init__(self, spec: ThreadSpec, machine: Machine, period: float, theta0: float,
                 drive: DriveModel | None = None, settled: float = 0.0,
                 start: tuple[float, float] | None = None, pulls: dict[int, float] | None = None,
                 room: float = JOIN_ROOM_REVS) -> None:
        """``theta0``: the spindle angle at cycle time 0 as if it turned at speed already
        (the helix is only ever evaluated after ``settled``, the cycle time before which no
        pass may join it: the spindle is at speed and its following error has died out
        meanwhile, while the axes already approach). ``start``: axis (x, z) where the
        cycle begins at rest, in front of the face (default: the clearance radius at
        start_z); the first pass runs from there straight onto its helix. ``pulls``: m by
        which each pass's depth is raised (spec.left_standing), none by default; ``room``:
        revolutions of helix, at least, between joining it and the face."""
        self.spec, self.machine, self.period, self.theta0 = spec, machine, period, theta0
        self.settled, self.room = settled, room
        self._ramps = Ramps(machine)
        self._retract_states: tuple[Trajectory | None, dict[int, list[float]]] = (None, {})  # _retracting's
        self._within: dict[int, bool] = {}  # _within_ramps' answers by pass
        self._reach_hint: int | None = None  # where in its revolution the last pass's first join in reach lay
        self._turn_hint: int | None = None  # servo periods after a pass's exit that x last turned
        # back after to plunge onto the next helix (_plunge's search starts there)
        self.t_lead = round(LEAD_TIME / period) * period
        self.x_clear = spec.origin[0] + spec.clear_radius
        self.x_air = spec.origin[0] + spec.air_radius
        self.start = start or (self.x_clear, spec.origin[1] + spec.start_z)
        self.tracks: list[list[Stretch]] = [[at_rest(self.start[0])], [at_rest(self.start[1])]]
        self.cuts: list[CutTiming] = []
        for cut in left_standing(passes_of(spec), pulls or {}):
            for start in range(spec.starts):
                self._add(cut, start)
        self.end = np.array([self.x_clear, spec.origin[1] + spec.start_z])
        self.duration = math.ceil(self._finish(self.cuts[-1]) / period - 1e-9) * period
        self._correction: np.ndarray | None = None  # (3, servo instants, 2): learned, on the grid
        self._command: np.ndarray | None = None  # the same: the motion plus the correction
        self._cache: tuple[tuple[int, float, float], np.ndarray] | None = None
        if drive is not None:
            self._compensate(drive)

    def psi(self, theta_ref: float, t: np.ndarray | float) -> np.ndarray | float:
        """Helix angle at cycle time t of the helix that passes start_z at theta_ref."""
        return self.theta0 + self.spec.spindle_speed * t - theta_ref

    def _state(self, cut: Pass, theta_ref: float, t: float) -> np.ndarray:
        return helix(self.spec, cut, np.array([self.psi(theta_ref, t)]))[:, 0, :].T  # rows x, z

    def _add(self, cut: Pass, start: int) -> None:
        spec, period = self.spec, self.period
        if self.cuts:
            last = self.cuts[-1]
            t_begin, x_free = last.t_out, last.t_out + last.retract.duration
            t_go, z_from = self._at_rest_clear(last)
            # z straight from the helix's exit onto the next one (it turns in the relief
            # groove while x pulls out), or, where that would cut the flank, from rest
            # once x has cleared the stock
            starts = [(last.t_out, [float(q[0]) for q in last.stop.at_time(0.0)]), (t_go, [z_from, 0.0, 0.0])]
            # found when a join first needs them: most passes join straight from the exit
            crossings = functools.cache(functools.partial(self._face_crossings, starts[0]))
        else:
            t_begin, x_free = 0.0, self.t_lead
            starts = [(self.t_lead, [self.start[1], 0.0, 0.0])]
            crossings = list  # the first pass comes from rest: it never crosses the face back
        phase = TWO_PI * start / spec.starts
        psi_room = TWO_PI * (spec.start_z / spec.pitch - self.room)  # the latest join before the face
        first = max(math.ceil(starts[0][0] / period - 1e-9) + 1, math.ceil(self.settled / period - 1e-9))
        revolutions = self._revolutions(cut, phase, psi_room, first, first + math.ceil(MAX_AIR_S / period))
        within = self._within_ramps(cut)
        joins = self._past_out_of_reach(revolutions, starts) if within else itertools.chain.from_iterable(revolutions)
        for k, t_join, theta_ref, target, place in joins:
            tried = self._air_path(target, t_join, t_begin, starts, crossings, x_free, place if within else None)
            if tried is not None and self._smooth_join(t_join, tried,
                                                       np.stack([target[:, 2], place[0].probes[place[1]]])):
                break
        else:
            raise ThreadError(
                "thread.start_z", f"the axes cannot reach the helix of pass {cut.index + 1} in front of the "
                f"face within {MAX_AIR_S:g} s"
            )
        if not self.cuts:  # from rest, a later join onto the same revolution meets the face as
            # soon, and the axes stay at rest longer: the latest that can be reached smoothly
            latest = math.floor((theta_ref + psi_room - self.theta0) / spec.spindle_speed / period + 1e-9)
            t_lates = np.arange(latest, k, -1) * period
            # the helix there and a jerk probe later (_smooth_join's), in one call
            ends = helix(spec, cut, self.psi(theta_ref, np.concatenate([t_lates, t_lates + JERK_PROBE_S])))
            late_targets, probes = ends[:, :t_lates.size].transpose(1, 2, 0), ends[2, t_lates.size:]
            for t_late, late_target, probe in zip(t_lates.tolist(), late_targets, probes):
                late = self._air_path(late_target, t_late, t_begin, starts, crossings, x_free)
                if late is not None and self._smooth_join(t_late, late, np.stack([late_target[:, 2], probe])):
                    t_join, tried = t_late, late
                    break
        on_helix = self._on_helix(cut, theta_ref)
        for j in range(2):
            self.tracks[j] += tried[j] + [(t_join, lambda t, j=j: on_helix(t)[:, :, j])]
        t_out, retract, stop = self._exit(cut, theta_ref, t_join)
        self.tracks[0].append(moving(t_out, retract))
        self.tracks[1].append(moving(t_out, stop))
        self.cuts.append(CutTiming(cut, start, theta_ref, t_begin, t_join, t_out, retract, stop))

    def _within_ramps(self, cut: Pass) -> bool:
        """Whether z on the helix of ``cut`` stays within the ramps' limits: the premise of
        _past_out_of_reach and _may_reach (asked once per pass, for each of its starts)."""
        if cut.index not in self._within:
            self._within[cut.index] = bool(np.all(helix_peaks(self.spec, cut)[1] <= self._ramps.limits("z")))
        return self._within[cut.index]

    def _smooth_join(self, t_join: float, tried: list[list[Stretch]], after: np.ndarray) -> bool:
        """Whether the air path's jerk steps onto the helix by at most JOIN_JERK_STEP of
        each axis's limit: the compensated command leads a jerk step with a spike that
        grows with it (the ramps end at their share of the limit, a fast vibration runs
        near the limit, and they may meet with opposite signs). ``after``: the helix's
        acceleration at t_join and JERK_PROBE_S later (2 instants, x z)."""
        eps = JERK_PROBE_S
        before = np.array([t_join - 2 * eps, t_join - eps])
        for j, axis in enumerate(JOINTS):
            begin, last = tried[j][-1]  # the stretch onto the join holds both instants, if it began by then
            a = (last(before) if begin <= before[0] else sample_track(self.tracks[j] + tried[j], before))[2]
            step = (after[1, j] - after[0, j]) / eps - (a[1] - a[0]) / eps
            if abs(step) > JOIN_JERK_STEP * self.machine.axis(axis).max_jerk:
                return False
        return True

    def _air_path(self, target: np.ndarray, t_join: float, t_begin: float, starts: list[tuple[float, list[float]]],
                  crossings: Callable[[], list[Crossing]], x_free: float,
                  place: tuple[Revolution, int] | None = None) -> list[list[Stretch]] | None:
        """The first of _air_paths onto ``target`` at t_join that keeps the tool out of the
        stock from t_begin on, or None (the grid is built for the first path found: most
        candidate joins find none)."""
        grid = None
        for tried in self._air_paths(target, t_join, starts, crossings, x_free, place):
            if grid is None:
                grid = np.arange(round(t_begin / self.period), round(t_join / self.period)) * self.period
            # each track's last stretch begins at t_begin (the exit, or the cycle's start)
            if not self._cuts_stock(*(track[-1:] + extra for track, extra in zip(self.tracks, tried)), grid):
                return tried
        return None

    def _finish(self, last: CutTiming) -> float:
        """After the last pass x pulls out to the clearance radius and z runs back to the
        cycle's start, inside the compensated cycle: z straight from the helix's exit while
        x heads out as between passes and turns back down to the clearance radius as late as
        it can, where x is out of the stock before z is back over it; else x straight to the
        clearance radius and z from rest once x is out. Returns the cycle time at which both
        are at rest."""
        spec, period = self.spec, self.period
        end = [spec.origin[1] + spec.start_z, 0.0, 0.0]
        home = self._ramps.reach("z", [float(q[0]) for q in last.stop.at_time(0.0)], end)
        if home is not None:
            t_home = last.t_out + math.ceil(home.duration / period - 1e-9) * period
            down = self._plunge([self.x_clear, 0.0, 0.0], t_home, last.t_out)
            straight = moving(last.t_out, home)
            grid = np.arange(round(last.t_out / period), round(t_home / period) + 1) * period
            if down is not None and not self._cuts_stock(self.tracks[0] + [down], self.tracks[1][:-1] + [straight],
                                                         grid):
                self.tracks[0].append(down)
                self.tracks[1][-1] = straight
                last.t_done = last.t_out + last.stop.duration
                return t_home
        last.retract = self._ramps.reach("x", [float(q[0]) for q in last.retract.at_time(0.0)],
                                         [self.x_clear, 0.0, 0.0])
        self.tracks[0][-1] = moving(last.t_out, last.retract)
        t_go, z_from = self._at_rest_clear(last)
        home = self._ramps.reach("z", [z_from, 0.0, 0.0], end)
        self.tracks[1].append(moving(t_go, home))
        t_done = max(last.t_end, t_go + home.duration)
        last.t_done = min(last.t_end, t_go)  # over once z heads back, x maybe still on its way out
        return t_done

    def _cuts_stock(self, x: list[Stretch], z: list[Stretch], t: np.ndarray) -> bool:
        """Whether the tip, on the tracks x and z at instants t, is ever inside the stock over
        the thread: compiled (_stock_kernel.c) where both tracks are ruckig moves there, as
        they are on every air path; else _cuts_stock_sampled."""
        (x_moves, x_others), (z_moves, z_others) = pieces(x, t), pieces(z, t)
        if x_others or z_others or not t.size:
            return self._cuts_stock_sampled(x, z, t)
        spec = self.spec
        x0, z0 = spec.origin
        return inside_stock(z_moves, x_moves, t, z0, x0, spec.direction, spec.direction * spec.end_z, spec.radial,
                            spec.major_radius, spec.surface_slope)

    def _cuts_stock_sampled(self, x: list[Stretch], z: list[Stretch], t: np.ndarray) -> bool:
        """_cuts_stock in numpy, on the tracks sampled (x only where z is over the stock)."""
        spec, s = self.spec, self.spec.direction
        x0, z0 = spec.origin
        z_at = sample_track(z, t)[0]
        over_stock = (s * (z_at - z0) >= 0.0) & (s * (z_at - z0) <= s * spec.end_z)
        if not over_stock.any():
            return False
        depth = spec.radial * (sample_track(x, t[over_stock])[0] - x0 - spec.surface(z_at[over_stock] - z0))
        return bool(np.any(depth > 0.0))

    def _at_rest_clear(self, last: CutTiming) -> tuple[float, float]:
        """(servo instant, z) at which z has stopped past the pass ``last`` and x has
        pulled out of the stock: from then on z may run back over the thread."""
        spec, period = self.spec, self.period
        out = np.arange(math.ceil(last.retract.duration / period) + 1) * period
        depth = spec.radial * (moving(0.0, last.retract)[1](out)[0] - spec.origin[0] - spec.surface(spec.end_z))
        t_clear = last.t_out + float(out[np.flatnonzero(depth <= 0.0)[0]])
        t_go = math.ceil(max(t_clear, last.t_out + last.stop.duration) / period - 1e-9) * period
        return t_go, last.stop.at_time(last.stop.duration)[0][0]

    def _air_paths(self, target: np.ndarray, t_join: float, starts: list[tuple[float, list[float]]],
                   crossings: Callable[[], list[Crossing]], x_free: float,
                   place: tuple[Revolution, int] | None = None):
        """The x plunge and z returns that reach the helix state ``target`` (rows x, z)
        exactly at t_join, best first: z from each of ``starts`` (time, state) that can,
        stretched to the time there is; then, from the last (at rest), z turning at rest
        TURN_ROOM in front of the join, so that x plunges while z is clear of the face.
        The x plunge (a bisection over ruckig) is found only once a z return can reach the
        join: most candidate joins fail on z's fastest time alone. With the join's ``place``
        in its revolution, a later start or crossing is passed over where _may_reach rules
        it out (the first start: _past_out_of_reach did)."""
        plunged: list[Stretch | None] = []  # asked once, when a z return first reaches the join

        def plunge() -> Stretch | None:
            if not plunged:
                plunged.append(self._plunge(target[0].tolist(), t_join, x_free))
            return plunged[0]

        z_target = target[1].tolist()
        late = None
        for i, (t_go, z_state) in enumerate(starts):
            if i and place is not None and not self._may_reach(place, t_go, z_state):
                continue
            fastest = self._ramps.reach("z", z_state, z_target)
            if fastest is None or fastest.duration > t_join - t_go + 1e-12:
                continue
            t_leave = t_go  # the first approach leaves at the last servo instant it can
            if not self.cuts:
                t_leave += math.floor((t_join - t_go - fastest.duration) / self.period + 1e-9) * self.period
            back = self._ramps.reach("z", z_state, z_target, duration=t_join - t_leave)
            if back is None or abs(back.duration - (t_join - t_leave)) > 1e-9:
                continue
            if plunge() is None:
                return
            yield [[plunge()], [moving(t_leave, back)]]
            late = (t_go, z_state, fastest)
        if self.cuts:
            for z in self._through_face(crossings(), z_target, t_join, place):
                if plunge() is None:
                    return
                yield [[plunge()], z]
        if late is None or late[1][1] != 0.0:
            return
        t_go, z_state, _ = late
        for via in TURN_ROOM:  # z turns this far in front of the join, at rest, as late as it can
            z_turn = [z_target[0] - self.spec.direction * via, 0.0, 0.0]
            there, onto = self._ramps.reach("z", z_state, z_turn), self._ramps.reach("z", z_turn, z_target)
            if there is None or onto is None:
                continue
            t_turn = t_join - math.ceil(onto.duration / self.period - 1e-9) * self.period
            t_leave = t_go + math.floor((t_turn - there.duration - t_go) / self.period + 1e-9) * self.period
            if t_leave < t_go:
                continue
            there = self._ramps.reach("z", z_state, z_turn, duration=t_turn - t_leave)
            onto = self._ramps.reach("z", z_turn, z_target, duration=t_join - t_turn)
            if (there is None or onto is None or abs(there.duration - (t_turn - t_leave)) > 1e-9
                    or abs(onto.duration - (t_join - t_turn)) > 1e-9):
                continue
            if plunge() is None:
                return
            yield [[plunge()], [moving(t_leave, there), moving(t_turn, onto)]]

    def _face_crossings(self, start: tuple[float, list[float]]) -> list[Crossing]:
        """(cycle time, z state, the stretch there) at which z, from the helix's exit
        ``start``, crosses the face as soon as it can at each of THROUGH_SPEEDS outwards:
        the same for every candidate join of a pass."""
        spec = self.spec
        t_go, z_state = start
        crossings = []
        for speed in THROUGH_SPEEDS:
            face = [spec.origin[1] - spec.direction * THROUGH_FRONT, -spec.direction * speed, 0.0]
            there = self._ramps.reach("z", z_state, face)
            if there is not None:
                crossings.append((t_go + there.duration, face, moving(t_go, there)))
        return crossings

    def _through_face(self, crossings: list[Crossing], z_target: list[float],
                      t_join: float, place: tuple[Revolution, int] | None = None):
        """z returns from the helix's exit that cross the face as soon as they can
        (``crossings``) and turn in front of it onto the join at t_join: the longest z can
        spend clear of the face, for x to plunge on the deepest passes."""
        for t_face, face, there in crossings:
            if t_face >= t_join or place is not None and not self._may_reach(place, t_face, face):
                continue
            onto = self._ramps.reach("z", face, z_target, duration=t_join - t_face)
            if onto is None or abs(onto.duration - (t_join - t_face)) > 1e-9:
                continue
            yield [there, moving(t_face, onto)]

    def _plunge(self, x_target: list[float], t_join: float, x_free: float) -> Stretch | None:
        """x onto the helix state x_target at t_join. The first pass plunges from rest at
        the clearance radius; later ones turn back on the way out (the retract heads for
        spec.air_radius), at the latest servo instant from which the plunge still arrives in
        time, so that x is out of the groove as long as it can be."""
        period = self.period
        if not self.cuts:
            plunge = self._ramps.reach("x", [self.start[0], 0.0, 0.0], x_target)
            if plunge is None or t_join - plunge.duration < x_free - 1e-12:
                return None
            return moving(t_join - plunge.duration, plunge)
        last = self.cuts[-1]

        def fastest(k: int) -> float:
            move = self._ramps.reach("x", self._retracting(k), x_target)
            return math.inf if move is None else move.duration

        n = round((t_join - last.t_out) / period)  # periods from the exit to the join

        def arrives(k: int) -> bool:  # turning back after k periods still lands by t_join (asked
            # again for the hint: Ramps keeps the answer)
            return fastest(k) <= (n - k) * period + 1e-12

        # the latest turn that still arrives; the previous join's lies a step or two away
        # (where it arrives, so does every earlier turn)
        hint = self._turn_hint
        if n < 1 or not (hint is not None and 1 < hint < n and arrives(hint)) and not arrives(1):
            return None
        turn = self._turn_hint = latest(arrives, 1, n, hint)
        t_turn = last.t_out + turn * period
        plunge = self._ramps.reach("x", self._retracting(turn), x_target, duration=t_join - t_turn)
        if plunge is None or abs(plunge.duration - (t_join - t_turn)) > 1e-9:
            return None
        return moving(t_turn, plunge)

    def _retracting(self, k: int) -> list[float]:
        """x's state (p, v, a) k servo periods after the last pass's exit, on its retract:
        kept, as every candidate join of a pass asks for the same few turns."""
        retract = self.cuts[-1].retract
        if self._retract_states[0] is not retract:
            self._retract_states = (retract, {})
        states = self._retract_states[1]
        if k not in states:
            states[k] = [float(q[0]) for q in retract.at_time(min(k * self.period, retract.duration))]
        return states[k]

    def _on_helix(self, cut: Pass, theta_ref: float) -> Callable[[np.ndarray], np.ndarray]:
        """Cycle times -> helix of the pass joined at theta_ref; x and z ask for the same
        instants one after the other, so the last answer is kept (for exactly those instants:
        grids that differ by rounding only must not share it). It holds no reference to the
        cycle, whose tracks hold it: a plan is freed as soon as it is dropped, not left to
        the cyclic collector."""
        last: list[np.ndarray | None] = [None, None]  # instants, helix there
        spec, theta0, speed = self.spec, self.theta0, self.spec.spindle_speed

        def on_helix(t: np.ndarray) -> np.ndarray:
            if last[0] is None or not np.array_equal(last[0], t):
                last[:] = t.copy(), helix(spec, cut, theta0 + speed * t - theta_ref)  # self.psi(theta_ref, t)
            return last[1]

        return on_helix

    def _revolutions(self, cut: Pass, phase: float, psi_room: float, first: int, stop: int):
        """Candidate joins k in [first, stop) in order, a helix revolution at a time (the
        latest revolution joined before psi_room: one theta_ref), the helix evaluated for
        REVOLUTIONS_AT_ONCE of them in one call, at each join and JERK_PROBE_S later (for
        _smooth_join): most are rejected on ruckig's fastest time alone, whole revolutions
        at a time, and a pass joins within its first two."""
        spec, period = self.spec, self.period
        block = REVOLUTIONS_AT_ONCE * math.ceil(TWO_PI / (spec.spindle_speed * period)) + 2
        lo = first
        while lo < stop:
            ks = np.arange(lo, min(stop, lo + block))
            t_joins = ks * period
            theta_refs = phase + TWO_PI * np.ceil((self.theta0 + spec.spindle_speed * t_joins - psi_room - phase)
                                                  / TWO_PI)
            bounds = [0, *(np.flatnonzero(np.diff(theta_refs)) + 1).tolist()]
            if lo + ks.size == stop:
                bounds.append(ks.size)  # else the block's last revolution goes on in the next
            end = bounds[-1]
            ends = helix(spec, cut, np.concatenate([self.psi(theta_refs[:end], t_joins[:end]),
                                                    self.psi(theta_refs[:end], t_joins[:end] + JERK_PROBE_S)]))
            targets, probes = ends[:, :end].transpose(1, 2, 0), ends[2, end:]
            for a, b in itertools.pairwise(bounds):
                yield Revolution(ks[a:b], t_joins[a:b], float(theta_refs[a]), targets[a:b], probes[a:b])
            lo += end

    def _past_out_of_reach(self, revolutions, starts: list[tuple[float, list[float]]]):
        """The joins of ``revolutions`` from the first of each that z may reach in time from
        one of ``starts``: the joins before it fail _air_paths' first test (z's fastest time)
        from every start, and every path it tries from there takes at least that long.

        Within one revolution z's slack (the time there is, less its fastest time) never
        falls from a join to a later one, where the helix stays within the ramps' limits
        (the caller's condition): reaching the earlier join and following the helix on to
        the later one is a move within those limits, so ruckig's time-optimal move to the
        later one is no longer than that. So a revolution whose last join is out of reach is
        passed over whole, and in one that is not, the first join to try is searched from
        where the previous pass's lay in its revolution (a few joins away): a few ruckig
        queries, not one or two per servo instant of air time."""
        for revolution in revolutions:
            if self._out_of_reach(revolution[-1], starts):
                continue
            # the first join in reach: the latest one that every join before is out of reach of
            first = self._reach_hint = latest(lambda j: j == 0 or self._out_of_reach(revolution[j - 1], starts),
                                               0, len(revolution), self._reach_hint)
            yield from revolution.joins(first)

    def _may_reach(self, place: tuple[Revolution, int], t_from: float, state: list[float]) -> bool:
        """Whether z, leaving ``state`` at t_from, may reach the join at ``place`` (its
        revolution, its index there) in time: False only where z's fastest time misses it by
        MISS_MARGIN (_out_of_reach). Those joins are the revolution's first ones up to the
        first that z reaches (_past_out_of_reach's premise), found by bisection once per
        state, from the first join asked about: a few ruckig queries instead of one per
        candidate join (a deep pass's search asks each of its later starts and face
        crossings about twenty joins that miss)."""
        revolution, i = place
        key = (t_from, id(state))  # a pass asks about the same state objects for every join
        asked, first = revolution.reach.get(key, (len(revolution), 0))
        if i < asked:  # the first join z reaches from i on (len: none), as _past_out_of_reach's
            first = latest(lambda j: j == i or self._out_of_reach(revolution[j - 1], [(t_from, state)]),
                           i, len(revolution) + 1, None)
            revolution.reach[key] = (i, first)
        return i >= first

    def _out_of_reach(self, join: tuple, starts: list[tuple[float, list[float]]]) -> bool:
        """Whether z's fastest time from each of ``starts`` misses the join by MISS_MARGIN."""
        _, t_join, _, target, _ = join
        z_target = target[1].tolist()  # as _air_paths asks: Ramps keeps the answers
        for t_go, z_state in starts:
            fastest = self._ramps.reach("z", z_state, z_target)
            if fastest is None or fastest.duration <= t_join - t_go + MISS_MARGIN:
                return False
        return True

    def _exit(self, cut: Pass, theta_ref: float, t_join: float) -> tuple[float, Trajectory, Trajectory]:
        """Leave the helix at the first servo instant past end_z (the relief groove, where
        nothing is cut, whatever the vibration does): x out to the clearance
        radius, z to a time-optimal stop."""
        spec, period = self.spec, self.period
        psi_end = TWO_PI * spec.direction * (spec.end_z - spec.start_z) / spec.pitch
        t_end = (psi_end + theta_ref - self.theta0) / spec.spindle_speed
        t_out = max(math.ceil(t_end / period - 1e-9), round(t_join / period) + 1) * period
        state = self._state(cut, theta_ref, t_out)
        retract = self._ramps.reach("x", state[0].tolist(), [self.x_air, 0.0, 0.0])
        stop = z_to_speed(self.machine, state[1], 0.0)
        return t_out, retract, stop

    def ideal(self, t: np.ndarray) -> np.ndarray:
        """(3, len(t), 2): the motion itself (what the feedback should do)."""
        return np.stack([sample_track(track, t) for track in self.tracks], 2)

    def _compensate(self, drive: DriveModel) -> None:
        """The command on the servo grid (the ideal motion plus the learned correction),
        kept whole: the plan is checked and streamed on that grid."""
        n = math.ceil((self.duration + COMPENSATION_TAIL) / self.period) + 1
        motion = self.ideal(np.arange(n) * self.period)
        # settled within a fraction of an encoder count: below that it is quantisation the
        # learning picked up from the simulated encoder, not lag
        tolerance = SETTLED_COUNTS * float(np.min(drive.resolution))
        self._correction = learned_command(drive, *motion, round(LEAD_TIME / self.period) // 2,
                                           round(self.duration / self.period), self.period, COMPENSATION_BAND,
                                           tolerance)
        self._command = motion[:, :self._correction.shape[1]] + self._correction
        self.duration = (self._correction.shape[1] - 1) * self.period

    @property
    def command(self) -> np.ndarray | None:
        """(3, servo instants, 2): the compensated command from cycle time 0 (None uncompensated)."""
        return self._command

    def sample_all(self, t: np.ndarray) -> np.ndarray:
        """(3, len(t), 2): the command at cycle times t (cached: x and z ask alike); read
        from the compensated command where t lies on its servo grid (within GRID_ROUNDING),
        else the motion there plus the correction interpolated."""
        key = (t.size, float(t[0]), float(t[-1])) if t.size else (0, 0.0, 0.0)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        if self._command is None:
            out = self.ideal(t)
        else:
            k = np.rint(t / self.period)
            if t.size and 0.0 <= k[0] and k[-1] < self._command.shape[1] and np.all(
                    np.abs(t - k * self.period) <= GRID_ROUNDING):
                first = int(k[0])  # consecutive instants (a plan's grid): a view
                out = (self._command[:, first:first + t.size] if np.all(np.diff(k) == 1.0)
                       else self._command[:, k.astype(np.intp)])
            else:
                out = self.ideal(t)
                grid = np.arange(self._correction.shape[1]) * self.period
                for i in range(3):
                    for j in range(2):
                        out[i, :, j] += np.interp(t, grid, self._correction[i, :, j], right=0.0)
        self._cache = (key, out)
        return out

    def sampler(self, joint: int):
        def sample(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            out = self.sample_all(t)
            return out[0][:, joint], out[1][:, joint], out[2][:, joint]

        return sample
