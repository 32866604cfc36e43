"""What the bridge's drives would report for a plan, predicted offline with the same drive model."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.plant import Plant

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.motion.timeline import Plan


def simulated_feedback(plan: Plan, machine: Machine, period: float = 1e-3,
                       plant: Plant | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What the bridge's drives would report for a plan, offline (same drive model); on
    ``plant``'s drives where given (the bridge's --plant), else on the description's."""
    t = np.arange(int(np.ceil(plan.duration / period)) + 1) * period
    p, v, a = plan.sample(t)
    model = DriveModel(machine, period, plan.joints, drives=plant.drives if plant else None,
                       seed=plant.seed if plant else 0)
    fb, _ = model.simulate(p, v, a)
    return t, fb
