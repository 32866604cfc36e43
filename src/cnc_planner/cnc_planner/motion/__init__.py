"""The shared motion core: what every job kind builds its plan with.

- ``moves``: jerk-limited point-to-point and straight moves from ruckig, limits, shared sampling;
- ``jerk_profile``: fast bulk sampling of ruckig trajectories;
- ``timeline``, ``builder``: per-joint timelines of pieces and the builder that appends to them;
- ``compensation``: the drive model run ahead of the commands (learn a correction, settle);
- ``derating``: a plan retried inside lowered limits until the plan check passes;
- ``plan_check``: the contract with the bridge, checked before a plan is accepted.
"""

SERVO_PERIOD = 1e-3  # s: the bridge's servo period; drive compensation and the plan check use it
