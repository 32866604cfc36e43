"""The ``kinematics`` section of report.json for path jobs: how far the tool tip left
the programmed polyline, by forward kinematics of the feedback and of the commands.

The programmed path is the job's points in program coordinates; each tip is measured
to the nearest programmed segment. ``servo_lag_mm`` is the largest distance between
FK(feedback) and FK(command) at the same instant: since the distance to a polyline
moves by at most as much as the point does, the feedback deviation never exceeds the
commanded deviation plus this lag. The planner compensates the drives' lag (kinds.path.exact),
so the command leads the line: its deviation is the lead, not a miss.

The verdict is the tip on feedback against the job's chord tolerance: ``within_tolerance``
is true only for a completed path whose feedback tip stayed within ``chord_tolerance_mm``;
``verdict`` says so for every reader (cnc-run exits non-zero on a failed verdict).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.units import to_mm

from cnc_analysis.recording import Run
from cnc_analysis.verdict import verdict as section_verdict

from cnc_planner.kinematics import Kinematics
from cnc_planner.kinds.path.polyline import distance_to_polyline


SETTLE_S = 0.5  # s of feedback after path_end still judged: the drives settle on the end point


def tip_deviations(kin: Kinematics, joints: dict[str, np.ndarray], vertices: np.ndarray) -> np.ndarray:
    """Distance of the FK tip of each joint sample to the programmed polyline (m)."""
    tips, _ = kin.fk_many(joints)
    return distance_to_polyline(tips, vertices)


def path_figures(kin: Kinematics, vertices: np.ndarray, command_t: np.ndarray, command: np.ndarray,
                 commanded: np.ndarray, feedback_t: np.ndarray, feedback: np.ndarray,
                 chord_tolerance: float) -> dict:
    """The section from arrays (rows of joint positions, columns = kin.joints): every
    command (for the lag), the mask of those on the path, and the feedback on the path;
    lengths in mm as machinists read them."""
    as_joints = lambda rows: {j: rows[:, i] for i, j in enumerate(kin.joints)}  # noqa: E731
    on_path = command[commanded]
    commanded = tip_deviations(kin, as_joints(on_path), vertices) if len(on_path) else np.zeros(1)
    fb = as_joints(feedback)
    deviation = tip_deviations(kin, fb, vertices) if len(feedback) else np.zeros(1)
    lag = 0.0
    if len(feedback) and len(command):
        at_fb = {j: np.interp(feedback_t, command_t, command[:, i]) for i, j in enumerate(kin.joints)}
        lag = float(np.max(np.linalg.norm(kin.fk_many(fb)[0] - kin.fk_many(at_fb)[0], axis=1)))
    return {
        "max_tip_deviation_mm": to_mm(float(deviation.max())),
        "commanded_max_tip_deviation_mm": to_mm(float(commanded.max())),
        "chord_tolerance_mm": to_mm(chord_tolerance),
        "servo_lag_mm": to_mm(lag),
        "feedback_samples": int(len(feedback)),
    }


def path_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """Tip deviation of a path job from path_start to path_end (plus SETTLE_S of feedback)."""
    kin = Kinematics(machine, job.setup, job.tool)
    events = [e for e in run.events if e.get("job_id") == job.job_id] or _inside(run, window)
    starts = [e["stamp_ns"] / 1e9 for e in events if e["name"] == "path_start"]
    ends = [e["stamp_ns"] / 1e9 for e in events if e["name"] == "path_end"]
    if not starts:
        return {"chord_tolerance_mm": to_mm(job.path.chord_tolerance), "max_tip_deviation_mm": None,
                "commanded_max_tip_deviation_mm": None, "servo_lag_mm": None, "feedback_samples": 0,
                "completed": False, "path_time_s": None,
                **verdict({"max_tip_deviation_mm": None, "chord_tolerance_mm": to_mm(job.path.chord_tolerance)}, False)}
    t0 = starts[-1]
    t1 = ends[-1] if ends and ends[-1] >= t0 else (float(run.command_t[-1]) if len(run.command_t) else t0)
    cols = [run.column(j) for j in kin.joints]
    fb_in = window & (run.feedback_t >= t0 - 1e-9) & (run.feedback_t <= t1 + SETTLE_S)
    cmd_in = (run.command_t >= t0 - 1e-9) & (run.command_t <= t1 + 1e-9)
    figures = path_figures(kin, np.asarray(job.path.points, float), run.command_t, run.command[:, cols], cmd_in,
                           run.feedback_t[fb_in], run.feedback[fb_in][:, cols], job.path.chord_tolerance)
    completed = bool(ends and ends[-1] >= t0)
    return {**figures, "completed": completed, "path_time_s": t1 - t0, **verdict(figures, completed)}


def _inside(run: Run, window: np.ndarray) -> list[dict]:
    """The events stamped within the window's feedback: a program's path operation (G64 P)
    carries the program's job id, and its share of the recording is the window."""
    if not window.any():
        return []
    t = run.feedback_t[window]
    return [e for e in run.events if "stamp_ns" in e and t[0] - 1e-9 <= e["stamp_ns"] / 1e9 <= t[-1] + 1e-9]


def verdict(figures: dict, completed: bool) -> dict:
    """The tip on feedback judged against the chord tolerance (mm as in the figures)."""
    deviation, limit = figures.get("max_tip_deviation_mm"), figures["chord_tolerance_mm"]
    within = bool(completed and deviation is not None and deviation <= limit)
    if not completed:
        said = "the path did not complete"
    else:
        said = (f"tip on feedback {deviation:.4f} mm from the programmed lines, "
                f"{'within' if within else 'beyond'} the chord tolerance {limit:g} mm")
    return {"within_tolerance": within,
            "verdict": section_verdict("tip on feedback within chord_tolerance", [] if within else [said], said)}
