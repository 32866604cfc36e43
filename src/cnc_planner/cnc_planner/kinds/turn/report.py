"""The turn section of report.json: the roughing plan's figures beside a naive one's, and
how far the tip went into the allowances and the part on feedback; its verdict fails a
gouge into the final part on feedback (deeper than cnc_analysis.verdict.OVERCUT_LIMIT)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.kinds.turn import frame_of
from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import to_mm

from cnc_analysis import summary
from cnc_analysis.recording import Run
from cnc_analysis.surface_speed import CRITERION, surface_speed_on
from cnc_analysis.verdict import OVERCUT_LIMIT, verdict

from cnc_planner.kinds.turn.judge import max_gouge
from cnc_planner.kinds.turn.roughing import plan_of
from cnc_planner.kinematics import Kinematics


def turn_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    t = job.turn
    frame, profile = frame_of(t), [tuple(p) for p in t.profile]
    ours, naive = plan_of(t), plan_of(t, naive=True)
    kin = Kinematics(machine, job.setup, job.tool)
    beyond_axis = min(min(p[1] for p in t.stock), min(p[1] for p in profile)) < 0.0

    def tips(positions: np.ndarray) -> np.ndarray:
        joints = {"x": positions[:, run.column("x")], "z": positions[:, run.column("z")]}
        radius, z = kin.tip_radius_z(joints["x"], joints["z"])
        if beyond_axis:  # a job that crosses the spindle axis is judged with x's sign (the tip's side)
            radius = np.copysign(radius, kin.fk_many(joints)[0][:, 0])
        return np.stack([z, radius], axis=1)

    tip_zx = tips(run.feedback[window])
    commanded = tips(run.command[run.command_t >= run.feedback_t[window][0]])
    gouge = max_gouge(tip_zx, profile, 0.0, 0.0, frame)
    failures = [f"gouge: the tip went {to_mm(gouge):.4f} mm into the final profile"] if gouge > OVERCUT_LIMIT else []
    criterion = f"on feedback: the tip no deeper than {to_mm(OVERCUT_LIMIT):g} mm into the final profile"
    passed = f"the tip stayed out of the final profile ({to_mm(gouge):.4f} mm into it) on feedback"
    css = {}
    if job.surface_speed is not None:
        css = {"surface_speed": surface_speed_on(run, window, tip_zx[:, 1], job.surface_speed,
                                                 machine.axes[SPINDLE].max_velocity, (t.feed,))}
        failures += css["surface_speed"].pop("failures")
        criterion += "; " + CRITERION.removeprefix("on feedback: ")
        passed += f"; surface speed at most {css['surface_speed'].get('max_deviation_pct', 0.0):g} % off"
    return {
        **ours.to_dict(),
        "naive_path_mm": to_mm(naive.path_length),
        "naive_air_feed_mm": to_mm(naive.air_feed_length),
        "path_feedback_mm": to_mm(float(np.sum(np.linalg.norm(np.diff(tip_zx, axis=0), axis=1)))),
        # How far the tip went into the finishing allowances (radial and axial) on feedback, into
        # the final profile itself on feedback (must be 0), and into the allowances in the setpoints.
        "max_gouge_mm": to_mm(max_gouge(tip_zx, profile, t.finish_allowance, t.finish_allowance_z, frame)),
        "max_gouge_part_mm": to_mm(gouge),
        "max_gouge_commanded_mm": to_mm(max_gouge(commanded, profile, t.finish_allowance, t.finish_allowance_z,
                                                  frame)),
        "cycle_time_s": summary.cycle_time(run, ("x", "z")),
        **css,
        "verdict": verdict(criterion, failures, passed),
    }

