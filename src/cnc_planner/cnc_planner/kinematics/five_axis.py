"""What the 5-axis layouts share: a tilt joint and C orient the tool, found from the tool axis.

A tool axis has two joint solutions, (tilt, c) and (-tilt, c + pi); each pose takes the
one within the limits closest to the pose before it, C is unwound to the shortest way,
and on the singular vertical axis C keeps its previous value (a run of vertical poses at
the start of an array takes the C of the first tilted pose after it). A layout module
gives the tilt joint, the azimuth of a tool axis and where the linear axes put the tip.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from cnc_msgs_py.machine import Axis

from .chain import LIMIT_SLACK, SINGULAR, TWO_PI, Chain, Unreachable, choose, excess, reach_reason, within


class FiveAxis(Chain):
    tilt_joint: ClassVar[str]
    orients_tool = True

    def azimuth(self, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
        """C that turns a tool axis (kx, ky, kz) of positive tilt into the tilt joint's plane."""
        raise NotImplementedError

    def place(self, tips: np.ndarray, tilt: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Linear axes (n, 3) that put the tool tip on table point ``tips`` at rotaries (tilt, c)."""
        raise NotImplementedError

    def inverse(self, tips: np.ndarray, axes: np.ndarray | None, previous: dict[str, float]
                ) -> dict[str, np.ndarray]:
        """Tilt from the tool axis's angle to +z, C from its azimuth (the API gives the
        program's +z when the job names no tool axis)."""
        kx, ky, kz = axes.T
        spread = np.hypot(kx, ky)
        tilt1 = np.arctan2(spread, kz)
        c1 = self.azimuth(kx, ky)
        singular = spread < SINGULAR
        tilt = np.stack([tilt1, np.where(singular, tilt1, -tilt1)])
        angle = np.stack([c1, c1 + np.pi])
        tilt_axis = self.machine.axes[self.tilt_joint]
        feasible = np.ones((2, len(tips)), dtype=bool)
        places = [self.place(tips, tilt[k], angle[k]) for k in (0, 1)]
        for k in (0, 1):
            feasible[k] = within(tilt_axis, tilt[k])
            for i, name in enumerate("xyz"):
                feasible[k] &= singular | within(self.machine.axes[name], places[k][:, i])
        stuck = ~feasible.any(axis=0)
        if stuck.any():
            i = int(np.argmax(stuck))
            k = int(np.argmin([excess(tilt_axis, t) for t in tilt[:, i]]))
            bad = [(tilt_axis, tilt[k, i])] + [(self.machine.axes[a], places[k][i, j]) for j, a in enumerate("xyz")]
            raise Unreachable(i, next(reach_reason(ax, v) for ax, v in bad if excess(ax, v) > LIMIT_SLACK))
        tilt, c = choose(tilt, angle, feasible, singular, previous.get(self.tilt_joint, 0.0), previous.get("c", 0.0))
        c = self._fit_turns(self.machine.axes["c"], c)
        xyz = self.place(tips, tilt, c)
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], self.tilt_joint: tilt, "c": c}

    def turn_in_place(self, end: dict[str, float], start: dict[str, float], tip: np.ndarray,
                      tolerance: float) -> dict[str, np.ndarray]:
        """C from ``end`` to ``start`` with the vertical tool's tip at table point ``tip``,
        in steps whose chord sagitta r (1 - cos(step / 2)) stays within tolerance."""
        radius = float(np.hypot(*(tip[0, :2] - self.pivot[:2])))
        step = 2.0 * np.arccos(max(1.0 - 0.9 * tolerance / radius, -1.0)) if radius > 0 else np.pi
        count = max(1, int(np.ceil(abs(start["c"] - end["c"]) / min(step, np.pi))))
        c = end["c"] + (start["c"] - end["c"]) * np.arange(1, count + 1) / count
        tilt = np.full(count, start[self.tilt_joint])
        xyz = self.place(np.repeat(tip, count, axis=0), tilt, c)
        return {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], self.tilt_joint: tilt, "c": c}

    @staticmethod
    def _fit_turns(axis: Axis, c: np.ndarray) -> np.ndarray:
        """A C axis with end stops: shift the whole unwound run by whole turns if that fits it."""
        if within(axis, c).all():
            return c
        for turns in (1, -1, 2, -2):
            if within(axis, c + turns * TWO_PI).all():
                return c + turns * TWO_PI
        return c
