"""The surface_speed section of a move job's report: at a constant surface speed (G96 around
a face cut), how well the feedback held it (cnc_analysis.surface_speed) at the feeds its
linear moves ask for. A move job at one rpm has no section: it returns None."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_analysis.recording import Run
from cnc_analysis.surface_speed import CRITERION, surface_speed_on
from cnc_analysis.verdict import verdict

from cnc_planner.kinematics import Kinematics


def surface_speed_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict | None:
    """The surface speed on feedback and its verdict, or None at one rpm."""
    if job.surface_speed is None:
        return None
    feedback = run.feedback[window]
    radius, _ = Kinematics(machine, job.setup, job.tool).tip_radius_z(feedback[:, run.column("x")],
                                                                      feedback[:, run.column("z")])
    per_rev = tuple(sorted({m.feed_per_rev for m in job.move if m.feed_per_rev is not None}))
    per_minute = tuple(sorted({m.feed for m in job.move if m.feed is not None}))
    section = surface_speed_on(run, window, radius, job.surface_speed, machine.axes[SPINDLE].max_velocity,
                               per_rev, per_minute)
    off = section.get("max_deviation_pct")
    section["verdict"] = verdict(CRITERION, section.pop("failures"), f"surface speed at most {off:g} % off"
                                 if off is not None else "no cut to judge: the rpm never above the cap")
    return section
