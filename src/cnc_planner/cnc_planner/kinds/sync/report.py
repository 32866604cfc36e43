"""The spindle_sync section of report.json: each pass locked to the spindle judged on
feedback (cnc_analysis.spindle_sync): every move at its lead per revolution from the
spindle's index, and the passes of one thread in one groove. The passes are the job's own
moves, placed on the axes by the setup and tool; nothing of the plan is read."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine
from cnc_msgs_py.units import to_mm

from cnc_analysis.recording import Run
from cnc_analysis.spindle_sync import LOCK_TOLERANCE, SyncPass, judge_passes
from cnc_analysis.verdict import verdict

from cnc_planner.kinds.kind import Card
from cnc_planner.kinds.move.planning import move_targets
from cnc_planner.kinds.sync.planning import pass_runs
from cnc_planner.kinematics import Kinematics

CRITERION = (f"on feedback: every synchronised move within {to_mm(LOCK_TOLERANCE):g} mm of its lead per spindle "
             f"revolution from the index, the passes of a thread within {to_mm(LOCK_TOLERANCE):g} mm of one groove")


def job_passes(job: SimpleNamespace, machine: Machine, start: dict[str, float]) -> tuple[list[str], list[SyncPass]]:
    """The job's passes in axis coordinates (the linear axes, in order), from the machine at ``start``."""
    joints = list(machine.linear_axes)
    targets = move_targets(job, machine, Kinematics(machine, job.setup, job.tool), start, "sync")
    here = np.array([start.get(j, 0.0) for j in joints])
    before: list[np.ndarray] = []
    for target in targets:  # where each move starts: the last target before it
        before.append(here)
        here = here if target is None else np.array([target[j] for j in joints])
    passes = [SyncPass(before[i], [np.array([targets[k][j] for j in joints]) for k in range(i, last)],
                       [job.sync[k].lead for k in range(i, last)]) for i, last in pass_runs(job.sync).items()]
    return joints, passes


def sync_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """The passes on feedback and the verdict."""
    joints, passes = job_passes(job, machine, run.feedback_at(window))
    feedback = run.feedback[window]
    section = judge_passes(run.feedback_t[window], feedback[:, [run.column(j) for j in joints]],
                           feedback[:, run.column(SPINDLE)], passes)
    section["verdict"] = verdict(CRITERION, section.pop("failures"), (
        f"{len(section['passes'])} passes, each move within {section['max_lock_error_mm']:.4f} mm of its lock, "
        f"one groove within {section['groove_spread_mm']:.4f} mm on feedback"))
    return section


def cards(section: dict) -> list[Card]:
    """The lock and the groove on the report page."""
    return [("Spindle sync", f"{section['max_lock_error_mm']:.4f} mm", section["verdict"]["says"],
             "ok" if section["verdict"]["passed"] else "bad")]
