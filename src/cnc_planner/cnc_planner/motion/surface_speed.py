"""Constant surface speed (G96 D S): the spindle speed that keeps the cutting speed v at the
tool's radius r, n = v / (2 pi r), never above the job's cap (D) nor the spindle's limit.

Where the speed changes, and why there:

- **Air moves.** Before the rapids that lead to a cut the spindle starts ramping to the
  speed the cut begins at, while the axes travel; the cut waits until it is reached (as it
  waits for any spindle change). This is Fanuc's rule for G96: a rapid's rpm is computed for
  its end point, so that the spindle does not hunt up and down during a traverse and is at
  speed when the cut begins (LinuxCNC follows X during rapids too, which a retract and
  re-approach costs two ramps). A pass along Z at one radius, most of a roughing cycle, then
  cuts at one exact rpm.
- **Feeds that change radius** (a face, a chamfer, a taper, the contour pass). A real control
  re-computes the rpm from X every servo cycle during the feed. Our feed moves are ruckig
  profiles at one path speed from rest to rest, and their feed per revolution must hold at
  the spindle's actual speed; so such a feed is cut in pieces over each of which the rpm the
  surface speed asks for changes by a ratio of at most (1 + TOLERANCE) / (1 - TOLERANCE):
  each piece turns at the harmonic mean of its ends' rpm, within TOLERANCE of the request
  along all of it, and the spindle ramps (jerk-limited, within its limits) between pieces
  while the axes stand. Where the spindle already holds TOLERANCE over the next piece it is
  not touched, so a contour of short chords does not ramp at every chord.

Below the radius where v / (2 pi r) reaches the cap the spindle turns at the cap: the
cutting speed falls towards the axis, as on every lathe. The cap is planned CAP_HEADROOM
below D (or the spindle's limit): the spindle's velocity loop overshoots the end of a ramp
by its lag times the ramp's acceleration (6 rpm, 0.2 %, at the lathe's 300 rad/s^2 on
feedback; more on a slower drive inside the description's tolerance), and D is a limit the
measured speed must keep, not only the command.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.schema import JobError

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder

TOLERANCE = 0.01  # share of the requested surface speed a feed piece may be off, each way
CAP_HEADROOM = 0.01  # share of the cap the planned speed stays below it (the drive's overshoot)
LATHES = ("lathe", "lathe_y")


@dataclass(frozen=True)
class SurfaceSpeed:
    """A cutting speed (m/s) held at the tool's radius, the spindle never above ``cap`` (rad/s)."""

    speed: float
    cap: float

    def rate(self, radius: float) -> float:
        """The spindle speed (rad/s) the surface speed asks for at ``radius`` (m), capped."""
        r = abs(radius)
        return self.cap if r * self.cap <= self.speed else self.speed / r

    def holds(self, spindle: float, radii: tuple[float, ...]) -> bool:
        """Whether ``spindle`` (rad/s) is within TOLERANCE of the request at every radius."""
        return spindle <= self.cap * (1.0 + 1e-12) and all(
            abs(spindle / self.rate(r) - 1.0) <= TOLERANCE for r in radii)

    def pieces(self, r0: float, r1: float) -> list[tuple[float, float]]:
        """A feed from signed radius r0 to r1 (x, which a face cut may take past the axis) as
        pieces (share of the feed where each ends, rad/s): the rpm asked for changes by at
        most (1 + TOLERANCE) / (1 - TOLERANCE) in each."""
        if r0 * r1 < 0.0:  # through the axis: down to it, then out on the other side
            at = r0 / (r0 - r1)
            return ([(at * share, w) for share, w in self.pieces(r0, 0.0)]
                    + [(at + (1.0 - at) * share, w) for share, w in self.pieces(0.0, r1)])
        w0, w1 = self.rate(r0), self.rate(r1)
        step = math.log((1.0 + TOLERANCE) / (1.0 - TOLERANCE))
        n = max(1, math.ceil(abs(math.log(w1 / w0)) / step - 1e-9))
        rates = w0 * (w1 / w0) ** (np.arange(n + 1) / n)
        out = []
        for k in range(1, n + 1):
            a, b = rates[k - 1], rates[k]
            if k == n:
                share = 1.0
            elif abs(r1 - r0) <= 1e-15:
                share = k / n
            else:  # where the request reaches rates[k]: its radius along the straight feed
                share = min(max((self.speed / b - abs(r0)) / (abs(r1) - abs(r0)), 0.0), 1.0)
            out.append((share, 2.0 * a * b / (a + b)))
        return out


def surface_speed_of(job: SimpleNamespace, machine: Machine) -> SurfaceSpeed | None:
    """The job's surface speed in SI with its cap (D, and the machine's spindle), if it gives one."""
    css = job.surface_speed
    if css is None:
        return None
    if machine.layout not in LATHES:
        raise JobError("surface_speed", f"needs a lathe: the speed follows the tool's radius (x); "
                                        f"{machine.name} is a {machine.layout}")
    limit = machine.axes[SPINDLE].max_velocity
    cap = limit if css.max_rpm is None else min(css.max_rpm, limit)
    return SurfaceSpeed(css.m_min, cap * (1.0 - CAP_HEADROOM))


def radius_of(kin: Kinematics, axes: dict[str, float], at: dict[str, float]) -> float:
    """The tool tip's radius (m) with the axes at ``axes`` (joints not named stay ``at``),
    signed as the tip's x: a face cut past the axis turns negative."""
    tips, _ = kin.fk_many({**at, **axes})
    return math.copysign(math.hypot(tips[0, 0], tips[0, 1]), tips[0, 0])


def ramp_to_radius(builder: PlanBuilder, css: SurfaceSpeed, radius: float) -> None:
    """Before the air moves that lead to ``radius`` (a cut's start, a rapid's end point): the
    spindle starts ramping to the speed there as they begin, unless it already holds the
    surface speed there."""
    if not css.holds(abs(builder.timelines[SPINDLE].end_velocity), (radius,)):
        builder.spindle_after(css.rate(radius))


def css_feeds(builder: PlanBuilder, css: SurfaceSpeed, start: dict[str, float], target: dict[str, float],
              r0: float, r1: float) -> Iterator[dict[str, float]]:
    """The pieces of a straight feed from ``start`` to ``target`` (axes, m; tip radii r0 to r1):
    each piece's axis target, yielded once the spindle turns at its speed (ramped while the
    axes stand, unless the speed it has holds the surface speed over the piece)."""
    before = 0.0
    for share, speed in css.pieces(r0, r1):
        ends = tuple(r0 + s * (r1 - r0) for s in (before, share))
        if not css.holds(abs(builder.timelines[SPINDLE].end_velocity), ends):
            builder.spindle_after(speed)
        yield {j: start[j] + share * (target[j] - start[j]) for j in target}
        before = share
