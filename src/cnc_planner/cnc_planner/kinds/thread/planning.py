"""Planning a thread job: the multi-pass thread cycle placed on the axes, its axis the
spindle's, whatever the setup and tool length."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine
from cnc_msgs_py.schema import JobError

from cnc_planner.kinematics import Kinematics
from cnc_planner.kinds.thread.cutting import ThreadSpec, plan_thread
from cnc_planner.motion.builder import PlanBuilder


THREAD_PROBE = 0.01  # m: program radius and z steps at which the thread's axis map is probed


THREAD_AXIS_TOL = 1e-9  # m: the probed axis positions agree with a translation within this


def thread_origin(kin: Kinematics) -> tuple[float, float]:
    """Axis (x, z) of the tip on the spindle axis at the program's face z=0.

    The thread planner works in program radius and z and adds this, so the map from them
    to axis x and z must be that translation at every angle around the part: the program
    Z is the spindle axis (a setup turned about Z only turns the part on the spindle).
    """
    reason = "a thread's axis must be the spindle axis: turn the setup about Z only, its origin on that axis"
    quarters = [(float(np.cos(a)), float(np.sin(a))) for a in np.arange(4) * (np.pi / 2)]
    try:  # a tool axis tilted out of the plane normal to the spindle, or a lathe tip off y = 0
        probes = [(kin.to_axes({"x": r * c, "y": r * s, "z": z}, [c, s, 0.0]), r, z)
                  for c, s in quarters for r, z in ((0.0, 0.0), (THREAD_PROBE, 0.0), (0.0, THREAD_PROBE))]
    except JobError as err:
        raise JobError("setup", reason) from err
    x0, z0 = probes[0][0]["x"], probes[0][0]["z"]  # the face, at angle 0
    if any(abs(axes[j] - {"x": x0 + r, "z": z0 + z}.get(j, 0.0)) > THREAD_AXIS_TOL
           for axes, r, z in probes for j in axes):
        raise JobError("setup", reason)
    return x0, z0


def plan_thread_job(job: SimpleNamespace, machine: Machine, builder: PlanBuilder, kin: Kinematics) -> None:
    """Multi-pass thread on the lathe, with vibration along the infeed if given, placed on
    the axes by the setup and tool length."""
    origin = thread_origin(kin)
    plan_thread(builder, ThreadSpec.from_job(job, origin))
