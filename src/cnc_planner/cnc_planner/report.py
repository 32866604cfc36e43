"""report.json from a recording alone: what cnc-run writes and cnc-analyze recomputes."""
from __future__ import annotations

import json

from cnc_msgs_py.machine import SPINDLE
from cnc_servo_bridge import analysis
from cnc_servo_bridge.recording import Run


def final_status(run: Run, job_id: str | None = None) -> dict:
    """The last final status of the job (or of the last job in the run)."""
    finals = [s for s in run.statuses if s["state"] in ("rejected", "succeeded", "aborted", "canceled")]
    if job_id is not None:
        finals = [s for s in finals if s["job_id"] == job_id]
    return finals[-1] if finals else {"job_id": job_id or "", "state": "unknown", "reason": "no final status recorded"}


def build_report(run: Run) -> dict:
    """The figures of a run's last job, judged on feedback."""
    job_id = None
    if run.goals:
        try:
            job_id = json.loads(run.goals[-1]).get("job_id")
        except (json.JSONDecodeError, AttributeError):
            job_id = None
    status = final_status(run, job_id)
    axes = tuple(j for j in run.joints if j != SPINDLE)
    return {
        "job_id": status["job_id"],
        "state": status["state"],
        "reason": status.get("reason", ""),
        "cycle_time_s": analysis.cycle_time(run, axes),
        "planned_time_s": status.get("cycle_time_s"),
        "max_following_error": analysis.following_error(run),
        "setpoints": int(len(run.command_t)),
        "chunks": len(run.chunks),
        "chunks_lost": analysis.chunks_lost(run),
        "feedback_samples": int(len(run.feedback_t)),
        "alarms": sorted(set(run.alarms)),
    }
