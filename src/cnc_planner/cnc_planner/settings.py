"""The executive's settings (cnc_planner.executive): how setpoints are cut into chunks and
how far they run ahead. Their defaults are the planner node's parameter defaults
(cnc_planner.planner_main); this module is plain Python so that the node's --help lists
them without importing the planner.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Settings:
    period_ns: int = 1_000_000  # interpolation period
    chunk_points: int = 100
    lookahead_ns: int = 300_000_000  # how far setpoints run ahead of the feedback; also
    # the longest a cancel waits: a stop begins where the setpoints sent so far end
    planning_lookahead_ns: int = 2_000_000_000  # the same while a goal (or the running job's
    # next segment) is being planned beside the stream: planning holds the GIL, and under CPU load the stream's thread then
    # waits for it each time it asks (0.3 s of setpoints ran dry in real time; 1 s did in 3 of
    # 150 make stress runs, where a sleeping thread of an idle process woke up to 0.4 s late)
    start_delay_ns: int = 600_000_000  # from the feedback that starts a job to its first setpoint:
    # the idle bridge's time runs on meanwhile, so this must cover a tick slowed by a loaded CPU
    status_period_ns: int = 500_000_000  # progress updates on job_status
    min_lead_ns: int = 500_000_000  # a job's first chunk reaching the bridge's clock with less
    # lead than this (a start delayed by planning, a loaded CPU or DDS) is re-timed, not sent stale;
    # at 0.1 s a first chunk still arrived 42 ms late beside two busy processes (load average 9),
    # at 0.3 s 50 and 67 ms late in a fresh-clone suite (a bridge just restarted; three machines
    # starting at once on 2 CPUs): in simulation the planner reads the bridge's clock from
    # /clock, itself late under load
