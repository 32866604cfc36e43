"""What the bridge's drives would report for a plan, predicted offline with the same drive model."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion.timeline import Plan


def simulated_feedback(plan: Plan, machine: Machine, period: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """What the bridge's drives would report for a plan, offline (same drive model)."""
    t = np.arange(int(np.ceil(plan.duration / period)) + 1) * period
    p, v, a = plan.sample(t)
    fb, _ = DriveModel(machine, period, plan.joints).simulate(p, v, a)
    return t, fb
