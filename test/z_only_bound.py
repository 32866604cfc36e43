"""An independent Z-only lower bound for a thread job, and its cycle time read from a bag.

Nothing from this project is imported: the bound is worked out from the job document (mm,
rpm) and the machine description's Z limits (config/machines/<machine>.yaml, read as plain
YAML) with ruckig at the full limits, and the cycle is read from the recorded feedback.

Whatever a thread cycle does, its Z axis must
* go from rest at the machine's home (where a job starts) onto the helix at the face, moving
  at the lead speed (pitch x rpm / 60);
* on every pass (cutting and spring), run the whole thread from the face to end_z at the
  lead speed: the synchronised stroke;
* between passes, go from end_z at the lead speed back onto the helix at the face at the
  lead speed: the shortest Z return;
* after the last pass, come to rest back at start_z, where the cycle began.
Each of these is time-optimal for Z alone (jerk-limited, from ruckig); X, the spindle and
the helix phase (the next pass may only join once the spindle has come round) cost nothing
here, so no cycle can be faster.

The cycle over topics is the time from the first to the last motion of x or z on
/cnc/joint_states (a step above MOTION_STEP_M between samples), as a stopwatch on the
machine would take it: the rapid to the start and the return are in it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from ruckig import InputParameter, Result, Ruckig, Trajectory

MACHINES = Path(__file__).resolve().parents[1] / "config" / "machines"
MOTION_STEP_M = 1e-7


def z_time(limits: dict, start: tuple[float, float], target: tuple[float, float]) -> float:
    """Time-optimal Z move (s) between (position m, velocity m/s) states, acceleration 0."""
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [start[0]], [start[1]], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [target[0]], [target[1]], [0.0]
    inp.max_velocity = [limits["max_velocity"]]
    inp.max_acceleration = [limits["max_acceleration"]]
    inp.max_jerk = [limits["max_jerk"]]
    trajectory = Trajectory(1)
    result = Ruckig(1).calculate(inp, trajectory)
    if result not in (Result.Working, Result.Finished):
        raise ValueError(f"ruckig: {result}")
    return trajectory.duration


def z_only_bound(job: dict, machine: dict | None = None) -> dict:
    """The bound's parts (s) for a single-start thread job document (mm, rpm)."""
    machine = machine or yaml.safe_load((MACHINES / f"{job['machine']}.yaml").read_text())
    limits = machine["axes"]["z"]
    th = job["thread"]
    face, start_z, end_z = 0.0, th["start_z"] * 1e-3, th["end_z"] * 1e-3
    setup_z = job.get("setup", {}).get("origin", [0, 0, 0])[2] * 1e-3
    s = 1.0 if end_z > start_z else -1.0
    lead_speed = s * th["pitch"] * 1e-3 * job["spindle_rpm"] / 60.0
    passes = (len(th["depths"]) if "depths" in th else th["passes"]) + th.get("spring_passes", 1)
    home = machine.get("home", {}).get("z", 0.0) - setup_z
    approach = z_time(limits, (home, 0.0), (face, lead_speed))
    stroke = (end_z - face) / lead_speed
    back = z_time(limits, (end_z, lead_speed), (face, lead_speed))
    final = z_time(limits, (end_z, lead_speed), (start_z, 0.0))
    total = approach + passes * stroke + (passes - 1) * back + final
    return {"passes": passes, "approach_s": approach, "stroke_s": stroke, "return_s": back,
            "final_s": final, "bound_s": total}


def cycle_time(t: np.ndarray, x: np.ndarray, z: np.ndarray) -> float:
    """First to last motion of x or z (s) in feedback samples in time order."""
    steps = np.maximum(np.abs(np.diff(x)), np.abs(np.diff(z)))
    moving = np.flatnonzero(steps > MOTION_STEP_M)
    return float(t[moving[-1] + 1] - t[moving[0]]) if moving.size else 0.0
