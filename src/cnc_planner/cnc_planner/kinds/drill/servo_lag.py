"""Timing the cycle against servo lag: the gaps that keep X/Y on the hole, on feedback,
whenever the tip is below R.

X/Y feedback settles some tens of ms after its command ends, Z feedback trails its command.
The planner runs the bridge's drive model on its own commands and moves the Z descent /
the next X/Y start by whole servo periods until the feedback never shows the tip below R
with X/Y off the hole; both gaps start at the smallest value that keeps the commands
themselves safe (their floors), so the cycle loses only what the feedback demands.

A real machine is not its description: the margins are those of the worst plant, the
described drives and every corner of their tolerance (cnc_msgs_py.plant.tolerance_corners),
X/Y and Z each at a corner of its own. The axes do not interact, and with X/Y off the hole
a sample is unsafe on some Z drive exactly when the lowest of the Z drives' tips is below
the plane: so each X/Y drive's margins are measured beside that lowest Z. The cycle is then
safe on every plant inside the tolerance (test_drill_tolerance.py draws them).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from cnc_msgs_py.machine import Drive, Machine
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinds.drill._lag_kernel import margins as lag_scan
from cnc_planner.kinds.drill.cycle import DrillCycle, DrillError
from cnc_planner.kinds.drill.z_axis import ZAxis
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.compensation import tolerance_drives
from cnc_planner.motion.timeline import Plan

SAFETY_ROUNDS = 40  # drive-model rounds before giving up on a safe timing
LAG_BLOCK_S = 5.0  # s of the cycle simulated at a time (see _feedback)

# A cycle written into a builder for given gaps (e_down, e_up) and air accelerations
# (overlap.py, conventional.py); the last argument asks for each air move's energy.
Emit = Callable[[PlanBuilder, float, np.ndarray, np.ndarray, np.ndarray, bool], list[dict]]


def _feedback(machine: Machine, plan: Plan, ts: np.ndarray, period: float, joints: tuple[str, ...],
              drives: list[Drive]) -> np.ndarray:
    """Feedback (len(ts), plants, len(joints)) of each drive (one for every joint listed), in
    an order of its own, from rest at the plan's position at ts[0], all in one model (a column
    per joint and drive, those of one delay side by side, each reading its joint's reference:
    DriveModel.run_shared); the plan sampled LAG_BLOCK_S at a time (the same values as in one
    piece), so that a block stays in the cache (30 s blocks copied more than they simulated)."""
    drives = sorted(drives, key=lambda d: d.delay)
    model = DriveModel.columns(machine, period, [(j, d) for d in drives for j in joints])
    source = np.tile(np.arange(len(joints)), len(drives))
    out = np.empty((len(ts), len(drives) * len(joints)))
    block = max(2, int(LAG_BLOCK_S / period))
    for lo in range(0, len(ts), block):
        p, v, a = plan.sample(ts[lo:lo + block], joints)
        if lo == 0:
            model.reset(p[0][source])
        out[lo:lo + block] = model.run_shared(p, v, a, source)[0]
    return out.reshape(len(ts), len(drives), len(joints))


class ServoLag:
    """The drive model's verdict on a cycle planned from ``start``: its lag margins, and
    the gaps that leave none."""

    def __init__(self, machine: Machine, cycle: DrillCycle, start: dict[str, float], z: ZAxis):
        self.machine = machine
        self.cycle = cycle
        self.start = start
        self.z = z
        self.n = len(cycle.holes)
        # X and Y move together: one drive for both (their descriptions' corners, if they differ, each)
        self.xy_drives = tolerance_drives(machine, "x") if machine.drives["x"] == machine.drives["y"] else None
        self.z_drives = tolerance_drives(machine, "z")

    def lag_margins(self, plan: Plan, infos: list[dict], t0: float) -> tuple[np.ndarray, np.ndarray]:
        """Per hole, in servo periods, from the drive model's feedback: how late X/Y settles
        after the tip went below the plane of the move into the hole (down) and how early X/Y
        leaves before the tip is back above the plane of the move out of it (up). Positive =
        unsafe by that many samples, negative = slack. The worst over every plant checked."""
        c = self.cycle
        period = c.servo_period
        k0 = math.floor(t0 / period + 1e-9)
        ts = (k0 + np.arange(math.ceil((plan.duration - t0) / period) + 50)) * period
        starts = np.searchsorted(ts, [info["s1"] for info in infos] + [ts[-1] + 1.0, ts[-1] + 1.0])
        planes = (np.array([c.air_plane(i) for i in range(self.n)]), np.array([c.air_plane(i + 1) for i in range(self.n)]))
        holes = (np.array([info["x"] for info in infos]), np.array([info["y"] for info in infos]))
        feedback = np.empty((len(ts), 3))  # X/Y of one drive beside the lowest Z of all
        feedback[:, 2] = _feedback(self.machine, plan, ts, period, ("z",), self.z_drives)[:, :, 0].min(axis=1)
        worst_down, worst_up = np.full(self.n, -np.inf), np.full(self.n, -np.inf)
        for x, y in self._xy_feedback(plan, ts, period):
            feedback[:, 0], feedback[:, 1] = x, y
            down, up = np.zeros(self.n), np.zeros(self.n)
            lag_scan(feedback, starts.astype(np.intp), *planes, *holes, c.xy_tolerance, down, up)
            np.maximum(worst_down, down, out=worst_down)
            np.maximum(worst_up, up, out=worst_up)
        return worst_down, worst_up

    def _xy_feedback(self, plan: Plan, ts: np.ndarray, period: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """X and Y feedback (len(ts) each) of every X/Y drive pairing checked."""
        if self.xy_drives is not None:
            both = _feedback(self.machine, plan, ts, period, ("x", "y"), self.xy_drives)
            return [(both[:, i, 0], both[:, i, 1]) for i in range(both.shape[1])]
        # X and Y described differently: each at each of its own corners
        xs = _feedback(self.machine, plan, ts, period, ("x",), tolerance_drives(self.machine, "x"))[:, :, 0]
        ys = _feedback(self.machine, plan, ts, period, ("y",), tolerance_drives(self.machine, "y"))[:, :, 0]
        return [(xs[:, i], ys[:, k]) for i in range(xs.shape[1]) for k in range(ys.shape[1])]

    def safe_gaps(self, emit: Emit, t0: float, e_down: np.ndarray, e_up: np.ndarray,
                  floor_down: np.ndarray, floor_up: np.ndarray, rounds: int = SAFETY_ROUNDS
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Move each gap by whole servo periods until the feedback is safe with no slack left.

        With rounds=1 it returns after one correction, to learn the lag margins. A gap that
        has moved once (grown, or shrunk by its slack) is never shrunk again, so the search
        cannot oscillate nor creep; no gap goes below its floor, where the commands
        themselves stop being safe.
        """
        period = self.cycle.servo_period
        full = np.full(self.n, self.z.rapid.acceleration)
        moved_down = np.zeros(self.n, bool)
        moved_up = np.zeros(self.n, bool)
        for _ in range(rounds):
            down, up = self.margins(emit, t0, e_down, e_up, full)
            up = np.roll(up, 1)  # hole i's exit constrains the start of S1 for hole i+1
            up[0] = 0.0
            # A gap that has moved keeps its slack: where the lag margin does not follow the
            # gap (another constraint binds), taking the same slack again would never end.
            new_down = np.where(moved_down & (down <= 0), e_down, np.maximum(e_down + down * period, floor_down))
            new_up = np.where(moved_up & (up <= 0), e_up, np.maximum(e_up + up * period, floor_up))
            if np.all(down <= 0) and np.all(up <= 0) and np.allclose(new_down, e_down) and np.allclose(new_up, e_up):
                return e_down, e_up
            moved_down |= ~np.isclose(new_down, e_down)
            moved_up |= ~np.isclose(new_up, e_up)
            e_down, e_up = new_down, new_up
        if rounds > 1:
            drive = self.machine.drives["z"]
            raise DrillError("drill.overlap" if self.cycle.overlap else "drill",
                             f"no timing found in {rounds} drive-model rounds that keeps X/Y on the hole while "
                             f"the tip is below R against the servo lag (z: kp {drive.kp:g}/s, velocity_lag "
                             f"{drive.velocity_lag * 1e3:.3g} ms)" + ("; overlap: off drills conventionally"
                                                                      if self.cycle.overlap else ""))
        return e_down, e_up

    def margins(self, emit: Emit, t0: float, e_down: np.ndarray, e_up: np.ndarray,
                accel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plan the cycle on a scratch builder and measure its lag margins on feedback."""
        builder = PlanBuilder(self.machine, self.start, events=False)
        infos = emit(builder, t0, e_down, e_up, accel, False)
        return self.lag_margins(builder.build(), infos, t0)
