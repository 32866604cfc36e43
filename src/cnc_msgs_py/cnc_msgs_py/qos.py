"""QoS profiles of the CNC topics (needs rclpy; the rest of the package does not)."""
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy

from . import topics


def _reliable(depth: int, latched: bool = False, lease_s: float | None = None) -> QoSProfile:
    liveliness = {} if lease_s is None else {"liveliness": LivelinessPolicy.AUTOMATIC,
                                             "liveliness_lease_duration": Duration(seconds=lease_s)}
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        **liveliness,
    )


# Goals, cancels and statuses are never dropped for depth: a cell controller may queue a
# burst of jobs while the planner's executor is busy with 1 kHz feedback (twelve goals in
# one burst lost two of them at depth 10). 100 in flight is far beyond a real cell's queue.
JOB_GOAL = _reliable(100)
JOB_CANCEL = _reliable(100)
JOB_RESUME = _reliable(100)
# The planner's statuses also carry its liveliness (DDS's own, asserted by the planner's
# participant): a cell controller on another host is told by DDS when no word came from the
# planner for PLANNER_LEASE_S (its host down, a cable pulled) and again when it is back.
# A reader must request a lease too to be told; one that requests none still matches.
PLANNER_LEASE_S = 2.0
JOB_STATUS = _reliable(100, latched=True, lease_s=PLANNER_LEASE_S)
JOB_EVENTS = _reliable(100)
JOINT_TRAJECTORY = _reliable(topics.TRAJECTORY_DEPTH)
# Feedback: a deep history so that a recorder falling behind during fast simulation
# catches up from the queue instead of losing samples.
JOINT_STATES = _reliable(topics.FEEDBACK_DEPTH)
# Readers that only need the latest state (the planner's clock and position): best
# effort, as for sensor data. A reliable reader delivers in order, so one lost sample
# holds back every newer one until the writer repairs it or drops it from its 20000-deep
# history; the soak caught the planner blind for 20 s that way, mid-job.
LATEST = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
DIAGNOSTICS = _reliable(10)
INJECT_FAULT = _reliable(10)
ALARM_RESET = _reliable(10)
CLOCK = _reliable(topics.FEEDBACK_DEPTH)
# Only the newest matters (the bridge keeps the largest), and it must not be lost. Not depth 1:
# a reliable writer that keeps one sample took 230-375 us a publish in the recorder's loop
# against 160-180 us with 10, and a 100-hole plate over topics ran 7.4-7.7 s wall against
# 10.6-11.9 s (bench/load.py's simulation, load 4-5).
RECORDED_UNTIL = _reliable(10)
