"""Topic names (relative, so they live under the node's namespace, default ``/cnc``)."""

NAMESPACE = "/cnc"
JOB_GOAL = "job_goal"
JOB_CANCEL = "job_cancel"
JOB_RESUME = "job_resume"  # std_msgs/String: the job_id of a held program (M0/M1) to go on
JOB_STATUS = "job_status"
JOB_EVENTS = "job_events"
JOINT_TRAJECTORY = "joint_trajectory"
JOINT_STATES = "joint_states"
DIAGNOSTICS = "/diagnostics"
INJECT_FAULT = "inject_fault"  # bridge fault injection (std_msgs/String, JSON)
ALARM_RESET = "alarm_reset"  # acknowledges a latched bridge alarm (std_msgs/String: who/why)
CLOCK = "/clock"
PLANNER_NODE = "cnc_planner"  # the planner node's name under its namespace
BRIDGE_NODE = "cnc_servo_bridge"  # its lifecycle services: <namespace>/cnc_servo_bridge/change_state, get_state
PID_KEY = "pid"  # in both nodes' diagnostics: the process, so a run can tell its own nodes from others
PLANT_KEY = "plant"  # in the bridge's diagnostics: the plant it emulates ("description": the description itself)
PLANT_OUTSIDE_KEY = "plant_outside_tolerance"  # ... and where that plant leaves the description's tolerance
DRIVES_KEY = "drives"  # in the bridge's diagnostics: DRIVES_ON (lifecycle active) or DRIVES_OFF
DRIVES_ON, DRIVES_OFF = "enabled", "disabled"
READY_KEY = "ready"  # in the planner's diagnostics: READY once it has heard the bridge (where the
# axes stand, whether it is alarmed): a job submitted then starts as soon as it is planned
READY, NOT_READY = "yes", "no"
RECORDED_UNTIL = "recorded_until"  # recorder -> simulated bridge: stamp of the last joint_states
# it has written (builtin_interfaces/Time), so the bridge's clock waits for a slow recorder

# Depths: a chunk is ~0.1 s of setpoints; keep a few seconds of them queued.
TRAJECTORY_DEPTH = 100
FEEDBACK_DEPTH = 20000  # 20 s of 1 kHz joint_states
