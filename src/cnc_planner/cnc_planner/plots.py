"""PNG figures of a recorded run, for machinists: what the axes really did, in mm, s and deg.

Every figure is drawn from the recorded feedback of the run's last job (the commands only
where they are compared with it), over the window report.json judges. Every job gets the
following error; its kind (cnc_planner.kinds) draws its method's figures from the same
geometry its report section judged against, and any vibrated feed gets the air-cut figures.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cnc_msgs_py.machine import SPINDLE, load_machine

from cnc_analysis.recording import Run

from cnc_planner.drawing import COMMAND, FEEDBACK, MM, envelope, plt, recording_note, save_all
from cnc_planner.kinds import KINDS
from cnc_planner.report import job_window, last_job
from cnc_planner.vibration.figures import aircut_figure, aircut_map, first_vibrating_feed


def write_plots(run: Run, report: dict, out_dir: Path) -> list[Path]:
    """Write the figures the run's job calls for into out_dir; returns the paths written.

    Every job gets following_error.png; a kind with a report section in the report draws
    its own figures, and a vibrated feed's air-cut summary gets aircut.png and
    aircut_map.png. Nothing is drawn without feedback and commands to compare.
    """
    if len(run.feedback_t) < 2 or len(run.command_t) < 2:
        return []
    window = job_window(run, report["job_id"])
    if window.sum() < 2:
        return []
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    drawn = [(_following_error(run, window, report), "following_error.png")]
    _, job = last_job(run)
    kind = KINDS.get(job.kind) if job is not None else None
    figures = kind.figures if kind is not None and kind.report is not None and kind.report.key in report else None
    if figures is not None:
        drawn += figures.draw(run, job, load_machine(job.machine), window, report)
    summary = report.get("aircut") or (figures.aircut(report) if figures is not None and figures.aircut else None)
    if summary and summary.get("feedback"):
        feed = first_vibrating_feed(run, report["job_id"])
        if feed is not None:
            drawn += [(aircut_figure(feed, summary), "aircut.png"), (aircut_map(feed), "aircut_map.png")]
    return save_all([(fig, out_dir / name) for fig, name in drawn])


def _following_error(run: Run, window: np.ndarray, report: dict) -> plt.Figure:
    """Command and feedback per linear axis, and their difference at the same instants."""
    axes = [j for j in run.joints if j != SPINDLE]
    inside = window & (run.feedback_t >= run.command_t[0]) & (run.feedback_t <= run.command_t[-1])
    t = run.feedback_t[inside]
    t0 = t[0]
    fig, grid = plt.subplots(2, len(axes), figsize=(4.2 * len(axes), 5.6), sharex=True, squeeze=False,
                             gridspec_kw={"height_ratios": (3, 2)})
    for column, name in enumerate(axes):
        j = run.column(name)
        command = np.interp(t, run.command_t, run.command[:, j]) * MM
        feedback = run.feedback[inside, j] * MM
        top, bottom = grid[0, column], grid[1, column]
        top.plot(*envelope(t - t0, feedback), color=FEEDBACK, lw=2.2, alpha=0.6, label="feedback")
        top.plot(*envelope(t - t0, command), color=COMMAND, lw=0.8, label="command")
        error = command - feedback
        bottom.plot(*envelope(t - t0, error), color="tab:purple", lw=0.8)
        bottom.axhline(0.0, color="0.6", lw=0.6)
        top.set_title(f"{name.upper()} axis   max |error| {np.max(np.abs(error)):.3f} mm", fontsize=10)
        top.set_ylabel(f"{name.upper()} position (mm)")
        bottom.set_ylabel("following error (mm)")
        bottom.set_xlabel("time from job start (s)")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    grid[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(f"{report['job_id']}: following error = command - feedback{recording_note(run)}", fontsize=11)
    fig.tight_layout()
    return fig
