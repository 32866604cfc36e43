"""The drives section of report.json: the feedback the description predicts for the recorded
commands, beside the recorded feedback, per axis.

The planner pre-compensates its commands with the drives of the machine description, so
every figure it promises (hole depths, the helix, the tip on a path, overlap safety) holds
as far as the real drives follow like their description. Replaying the very setpoints the
bridge executed through the description's drive model (the bridge's own DriveModel), from
where the recorded feedback stood when they began, gives the feedback the planner expected
at every instant; the residual (predicted minus recorded) says which axis is not its
description. An axis beyond RESIDUAL_LIMIT is named with what to do: identify the drives
from this recording (cnc-identify) and plan with the fitted description. This is advice,
not a verdict: the kinds' verdicts judge what the feedback did; this says why it may differ
from the plan, and it never fails a run by itself.

The replay takes the reference as the bridge's buffer gives it (linear between setpoints,
the first point held before them, the last reference held at rest after them or across a
gap in them), steps the drives once per servo period and reads the encoders before each
step, as the bridge publishes them. The servo period is the finer of the feedback's and the
setpoints' sample periods (the bridge publishes every servo period by default). An alarm's
stop is the bridge's own, no recorded setpoint: past it the replay and the recording part,
and the section says so.
"""
from __future__ import annotations

import math

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_analysis.recording import Run

from cnc_servo_bridge.drive import DriveModel

# Residual beyond which an axis counts as following differently from its description: 5 um on
# a linear axis (the accuracy an identified description gives back: holes and threads within
# 5 um), 0.01 deg on a rotary axis or the spindle (9 um at 50 mm from the axis).
RESIDUAL_LIMIT_MM = 0.005
RESIDUAL_LIMIT_DEG = 0.01
GAP = 1.5  # setpoints further apart than this many periods are not interpolated: the bridge holds
BLOCK = 1 << 16  # servo periods replayed at once: a long recording's references are never all held
ADVICE = "run cnc-identify on this bag and plan with the fitted description (CNC_MACHINE_PATH)"


def references(run: Run, acceleration: np.ndarray, period: float,
               t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration references (rows: times t) as the bridge's setpoint
    buffer gives them from the run's setpoints (sent every ``period``): linear between
    consecutive setpoints, a setpoint itself at its time, otherwise (before, after, or in a
    gap) the nearest earlier position held at rest."""
    ct = run.command_t
    k = np.searchsorted(ct, t, side="right") - 1
    lo, hi = np.clip(k, 0, len(ct) - 1), np.clip(k + 1, 0, len(ct) - 1)
    span = ct[hi] - ct[lo]
    between = (k >= 0) & (hi > lo) & (span <= GAP * period)
    w = np.where(between, (t - ct[lo]) / np.where(span > 0, span, 1.0), 0.0)[:, None]
    moving = (between | ((k >= 0) & (t == ct[lo])))[:, None]
    p = run.command[lo] + w * (run.command[hi] - run.command[lo])
    v, a = (np.where(moving, x[lo] + w * (x[hi] - x[lo]), 0.0) for x in (run.command_velocity, acceleration))
    return p, v, a


def predicted_feedback(run: Run, machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """The recorded feedback's samples from the setpoints' start on (a mask over feedback_t)
    and what the description's drives would have read at each of them (rows, run.joints)."""
    fb_t = run.feedback_t
    command_period = float(np.median(np.diff(run.command_t)))
    period = min(float(np.median(np.diff(fb_t))), command_period)
    acceleration = run.command_acceleration
    if acceleration.shape != run.command.shape:  # a run built without them: from the velocities
        acceleration = np.gradient(run.command_velocity, run.command_t, axis=0)
    at_start = np.flatnonzero(fb_t <= run.command_t[0] + 1e-9)
    first = int(at_start[-1]) if len(at_start) else 0
    steps = int(np.rint((fb_t[-1] - fb_t[first]) / period)) + 1
    drives = DriveModel(machine, period, run.joints)
    drives.reset(run.feedback[first])
    measured = np.empty((steps, len(run.joints)))
    for lo in range(0, steps, BLOCK):
        grid = fb_t[first] + np.arange(lo, min(lo + BLOCK, steps)) * period
        measured[lo:lo + len(grid)] = drives.run(*references(run, acceleration, command_period, grid))[0]
    compared = np.zeros(len(fb_t), dtype=bool)
    compared[first:] = True
    rows = np.clip(np.rint((fb_t[first:] - fb_t[first]) / period).astype(int), 0, steps - 1)
    return compared, measured[rows]


def drives_section(run: Run, machine: Machine) -> dict | None:
    """Per axis, the residual of the recorded feedback against the description's prediction
    (max and RMS) and the following error recorded beside the predicted one, in mm (deg on
    rotary axes and the spindle); the axes beyond the limit and what to do. None without
    setpoints and feedback to compare, or for joints the machine does not have."""
    if len(run.command_t) < 2 or len(run.feedback_t) < 2 or any(j not in machine.drives for j in run.joints):
        return None
    compared, predicted = predicted_feedback(run, machine)
    t, recorded = run.feedback_t[compared], run.feedback[compared]
    commanded = (t >= run.command_t[0]) & (t <= run.command_t[-1])
    axes, differs = {}, []
    for i, joint in enumerate(run.joints):
        linear = machine.axes[joint].type == "linear"
        scale, limit = (1e3, RESIDUAL_LIMIT_MM) if linear else (math.degrees(1.0), RESIDUAL_LIMIT_DEG)
        residual = (predicted[:, i] - recorded[:, i]) * scale
        command = np.interp(t[commanded], run.command_t, run.command[:, i])
        axes[joint] = {
            "unit": "mm" if linear else "deg",
            "max_residual": float(np.max(np.abs(residual))),
            "rms_residual": float(np.sqrt(np.mean(residual ** 2))),
            "max_following_error": float(np.max(np.abs(command - recorded[commanded, i]), initial=0.0)) * scale,
            "predicted_max_following_error": float(np.max(np.abs(command - predicted[commanded, i]),
                                                          initial=0.0)) * scale,
        }
        if axes[joint]["max_residual"] > limit:
            differs.append(joint)
    clauses = [f"{j} follows differently from its description (residual {axes[j]['max_residual']:.4f} "
               f"{axes[j]['unit']})" for j in differs]
    says = ("; ".join(clauses) + f": {ADVICE}" if differs else
            f"every axis follows its description within {RESIDUAL_LIMIT_MM:g} mm ({RESIDUAL_LIMIT_DEG:g} deg rotary)")
    if run.alarms:  # the bridge's stop is no setpoint of the recording: the replay cannot follow it
        says += "; the bridge raised an alarm and stopped the axes on its own, which the replay does not predict"
    return {"residual_limit_mm": RESIDUAL_LIMIT_MM, "residual_limit_deg": RESIDUAL_LIMIT_DEG,
            "as_described": not differs, "differs": differs, "says": says, "axes": axes}
