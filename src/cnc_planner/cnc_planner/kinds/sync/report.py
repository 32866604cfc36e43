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
from cnc_analysis.spindle_sync import LOCK_TOLERANCE, SyncPass, Tap, judge_passes, judge_taps
from cnc_analysis.verdict import verdict

from cnc_planner.kinds.kind import Card
from cnc_planner.kinds.move.planning import move_targets
from cnc_planner.kinds.sync.planning import pass_runs
from cnc_planner.kinematics import Kinematics

CRITERION = (f"on feedback: every synchronised move and tap within {to_mm(LOCK_TOLERANCE):g} mm of its lead per "
             f"spindle revolution from the index, the passes of a thread within {to_mm(LOCK_TOLERANCE):g} mm of one "
             f"groove, a tap's bottom within {to_mm(LOCK_TOLERANCE):g} mm of its depth")


def job_passes(job: SimpleNamespace, machine: Machine,
               start: dict[str, float]) -> tuple[list[str], list[SyncPass], list[Tap]]:
    """The job's passes and taps in axis coordinates (the linear axes, in order), from the
    machine at ``start``."""
    joints = list(machine.linear_axes)
    targets = move_targets(job, machine, Kinematics(machine, job.setup, job.tool), start, "sync")
    here = np.array([start.get(j, 0.0) for j in joints])
    before: list[np.ndarray] = []
    for move, target in zip(job.sync, targets):  # where each move starts (a tap ends there too)
        before.append(here)
        here = here if target is None or move.tap is not None else np.array([target[j] for j in joints])
    passes = [SyncPass(before[i], [np.array([targets[k][j] for j in joints]) for k in range(i, last)],
                       [job.sync[k].lead for k in range(i, last)]) for i, last in pass_runs(job.sync).items()]
    taps = [Tap(before[i], np.array([targets[i][j] for j in joints]), move.lead)
            for i, move in enumerate(job.sync) if move.tap is not None]
    return joints, passes, taps


def sync_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> dict:
    """The passes and taps on feedback and the verdict."""
    joints, passes, taps = job_passes(job, machine, run.feedback_at(window))
    feedback = run.feedback[window]
    samples = (run.feedback_t[window], feedback[:, [run.column(j) for j in joints]], feedback[:, run.column(SPINDLE)])
    section = judge_passes(*samples, passes)
    tapped = judge_taps(*samples, taps)
    section["taps"] = tapped["taps"]
    section["max_lock_error_mm"] = max([section["max_lock_error_mm"]] + [k["lock_error_mm"] for k in tapped["taps"]])
    section["verdict"] = verdict(CRITERION, section.pop("failures") + tapped["failures"], (
        f"{len(section['passes'])} passes and {len(section['taps'])} taps, each within "
        f"{section['max_lock_error_mm']:.4f} mm of its lock, one groove within {section['groove_spread_mm']:.4f} mm "
        "on feedback"))
    return section


def cards(section: dict) -> list[Card]:
    """The lock and the groove on the report page."""
    return [("Spindle sync", f"{section['max_lock_error_mm']:.4f} mm", section["verdict"]["says"],
             "ok" if section["verdict"]["passed"] else "bad")]
