"""report.json from a recording alone: what cnc-run writes and cnc-analyze recomputes.

The job document travels on job_goal and is recorded, so the job's kind (its report
section, cnc_planner.kinds) re-derives what it needs (hole positions, R plane, stock) from
it with the planner's own code and has the recorded feedback judged by cnc_analysis. Each
section carries a verdict (cnc_analysis.verdict); ``drives`` (cnc_planner.replay) sets the
feedback the description predicts beside the recorded one, and ``plant`` names the drives
the bridge emulated, as its diagnostics said (None if the recording does not say).
"""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.job import parse_job
from cnc_msgs_py.machine import SPINDLE, Machine, MachineError, load_machine
from cnc_msgs_py.plant import Plant
from cnc_msgs_py.schema import JobError

from cnc_analysis import summary
from cnc_analysis.recording import Run

from cnc_planner.baselines import beside, drop_pending
from cnc_planner.executive import event_doc
from cnc_planner.kinds import KINDS
from cnc_planner.motion.timeline import Event, Plan
from cnc_planner.prediction import simulated_feedback
from cnc_planner.replay import drives_section
from cnc_planner.vibration.report import aircut_section


FINAL = ("rejected", "succeeded", "aborted", "canceled")


def final_status(run: Run, job_id: str | None = None) -> dict:
    """The last final status of the job (or of the last job in the run)."""
    finals = [s for s in run.statuses if s["state"] in FINAL]
    if job_id is not None:
        finals = [s for s in finals if s["job_id"] == job_id]
    return finals[-1] if finals else {"job_id": job_id or "", "state": "unknown", "reason": "no final status recorded"}


def last_job(run: Run) -> tuple[str | None, SimpleNamespace | None]:
    if not run.goals:
        return None, None
    try:
        doc = json.loads(run.goals[-1])
    except json.JSONDecodeError:
        return None, None
    job_id = doc.get("job_id") if isinstance(doc, dict) else None
    try:
        return job_id, parse_job(doc)
    except JobError:
        return job_id, None


def build_report(run: Run, machine: Machine | None = None) -> dict:
    """The figures of a run's last job, judged on feedback; ``machine``: the description
    it ran on, if not the one the job names in config (a drawn one, in tests). Baselines
    still being computed that the report did not ask for (a rejected job's) are stopped."""
    try:
        return _judged(run, machine)
    finally:
        drop_pending()


def _judged(run: Run, machine: Machine | None) -> dict:
    job_id, job = last_job(run)
    status = final_status(run, job_id)
    axes = tuple(j for j in run.joints if j != SPINDLE)
    report = {
        "job_id": status["job_id"],
        "state": status["state"],
        "reason": status.get("reason", ""),
        "cycle_time_s": summary.cycle_time(run, axes),
        "planned_time_s": status.get("cycle_time_s"),
        "max_following_error": summary.following_error(run),
        "setpoints": int(len(run.command_t)),
        "chunks": len(run.chunks),
        "chunks_lost": summary.chunks_lost(run),
        "feedback_samples": int(len(run.feedback_t)),
        "alarms": sorted(set(run.alarms)),
        "plant": run.plant,
    }
    if job is None or status["state"] == "rejected" or len(run.feedback_t) == 0:
        return report
    try:
        machine = machine or load_machine(job.machine)
    except MachineError:
        return report
    window = job_window(run, status["job_id"])
    section = KINDS[job.kind].report
    # The section's baselines are planned on the other core while the run is judged.
    beside(section, job, machine, run.feedback_at(window))
    report["drives"] = drives_section(run, machine)
    if section is not None and (judged := section.judge(run, job, machine, window)) is not None:
        report[section.key] = judged  # (None: nothing of the kind's to judge, as a move job at one rpm)
    if job.vibration is not None and not (section is not None and section.judges_chips):
        report["aircut"] = aircut_section(run)
    return report


def job_window(run: Run, job_id: str) -> np.ndarray:
    """Feedback samples from the job's first setpoint to the end of the recording."""
    starts = [e["stamp_ns"] for e in run.events if e.get("job_id") == job_id and e["name"] == "job_start"]
    t0 = (starts[-1] / 1e9) if starts else run.feedback_t[0]
    return run.feedback_t >= t0 - 1e-9


def predicted_run(doc: dict, plan: Plan, machine: Machine, period: float = 1e-3, plant: Plant | None = None) -> Run:
    """A run as the bridge would record it, predicted offline: the plan's setpoints, the
    drive model's feedback to them (on ``plant``'s drives where given) and the plan's
    events, so that build_report judges a prediction with the very code that judges
    recordings. A prediction, not a recording: no DDS, no timing, no lost samples."""
    t, feedback = simulated_feedback(plan, machine, period, plant)
    p, v, a = plan.sample(t)
    job_id = str(doc.get("job_id", ""))
    final = {"job_id": job_id, "state": "succeeded", "reason": "", "cycle_time_s": plan.duration}
    events = [event_doc(job_id, 0, e) for e in plan.events]
    if not any(e.name == "job_start" for e in plan.events):
        events.insert(0, event_doc(job_id, 0, Event(0.0, "job_start")))
    return Run(joints=plan.joints, feedback_t=t, feedback=feedback, feedback_velocity=np.zeros_like(feedback),
               command_t=t, command=p, command_velocity=v, command_acceleration=a, goals=[json.dumps(doc)],
               statuses=[final],
               events=events)
