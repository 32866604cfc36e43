"""How long the drives take to settle after the commands come to rest, from the drive model."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE

from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.moves import shared_samples


def settle_time(builder: PlanBuilder, kin: Kinematics, t0: float, tol: float, period: float,
                 horizon: float = 2.0) -> float:
    """How long after ``t0`` (all axes commanded at rest) the drive model's feedback puts
    the tip within ``tol`` of the commanded tip, in whole servo periods."""
    joints = tuple(j for j in builder.machine.joint_names if j != SPINDLE)
    ts = np.arange(int(np.ceil((t0 + horizon) / period)) + 1) * period
    with shared_samples():
        p, v, a = (np.stack(q, axis=1) for q in zip(*[builder.timelines[j].sample(ts) for j in joints]))
    feedback, _ = DriveModel(builder.machine, period, joints).simulate(p, v, a)
    commanded, _ = kin.fk_many(dict(zip(joints, p.T)))
    actual, _ = kin.fk_many(dict(zip(joints, feedback.T)))
    far = np.nonzero((np.linalg.norm(actual - commanded, axis=1) > tol) & (ts >= t0))[0]
    return 0.0 if len(far) == 0 else float(ts[far[-1]] + period - t0)
