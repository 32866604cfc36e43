"""How long the drives take to settle after the commands come to rest, from the drive model:
on the described drives and on every corner of their tolerance, as the plan that follows
assumes of all of them (a drill's timing search starts from the drives at rest)."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE
from cnc_servo_bridge.drive import DriveModel

from cnc_planner.kinematics import Kinematics
from cnc_planner.motion.builder import PlanBuilder
from cnc_planner.motion.compensation import corner_plants
from cnc_planner.motion.moves import shared_samples

LEAD_S = 1.0  # simulated before t0, from rest on the command there: the error of that start
# dies out over 20 and more of the slowest tolerated drive's time constants (1/kp, lag)


def settle_time(builder: PlanBuilder, kin: Kinematics, t0: float, tol: float, period: float,
                horizon: float = 2.0) -> float:
    """How long after ``t0`` (all axes commanded at rest) the drive model's feedback puts
    the tip within ``tol`` of the commanded tip, in whole servo periods: the longest of the
    described drives and of the k-th corner of every joint's tolerance together.

    Only LEAD_S before ``t0`` is simulated, not the whole plan: a program settles before
    each of its drill operations, which from its start would cost the square of its length."""
    joints = [j for j in builder.machine.joint_names if j != SPINDLE]
    first = max(0, int(np.floor((t0 - LEAD_S) / period)))
    ts = np.arange(first, int(np.ceil((t0 + horizon) / period)) + 1) * period
    with shared_samples():
        p, v, a = (np.stack(q, axis=1) for q in zip(*[builder.timelines[j].sample(ts) for j in joints]))
    plants = corner_plants(builder.machine, joints)
    model = DriveModel.columns(builder.machine, period, [(j, plant[j]) for plant in plants for j in joints])
    source = np.tile(np.arange(len(joints)), len(plants))
    model.reset(p[0][source])
    feedback = model.run_shared(p, v, a, source)[0]
    commanded, _ = kin.fk_many(dict(zip(joints, p.T)))
    far = np.zeros(len(ts), bool)
    for k in range(0, feedback.shape[1], len(joints)):
        actual, _ = kin.fk_many(dict(zip(joints, feedback[:, k:k + len(joints)].T)))
        far |= np.linalg.norm(actual - commanded, axis=1) > tol
    far = np.nonzero(far & (ts >= t0))[0]
    return 0.0 if len(far) == 0 else float(ts[far[-1]] + period - t0)
