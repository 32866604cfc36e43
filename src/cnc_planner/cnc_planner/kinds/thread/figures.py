"""The thread figures: depth and chip length per pass, and the groove's cross-section on
feedback."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import SPINDLE, Machine

from cnc_analysis.recording import Run
from cnc_analysis.threads import cross_section

from cnc_planner.drawing import plt
from cnc_planner.kinematics import Kinematics


SECTION_REVS = 3.0  # revolutions of groove shown pass against pass in the thread cross-section
CAPTIONS = {  # figure file stem -> what the report page says under it
    "thread_passes": "Thread passes: depth of cut per pass along the flank, with the vibration on each pass.",
    "thread_section": "Groove cross-section per pass on feedback: the tool tip sliding along the flank with its "
                      "vibration, and each pass's depth along the groove against the pass before it (its returns above "
                      "the previous turning points are where the chip breaks).",
}


def _thread_passes(thread: dict, job_id: str) -> plt.Figure:
    """Per pass, from the feedback: the depth reached and each pass's depth of cut (which
    must never grow), and the longest chip in spindle revolutions against the one-rev line."""
    passes = thread["passes"]
    index = np.array([p["index"] for p in passes])
    depth = np.array([p["depth_mm"] for p in passes])
    doc = np.array([p["doc_mm"] for p in passes])
    chip = np.array([p["max_chip_revs"] for p in passes])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    top.bar(index - 0.2, depth, width=0.4, color="tab:blue", label="depth reached (mm)")
    top.bar(index + 0.2, doc, width=0.4, color="tab:orange", label="depth of cut (mm)")
    top.set_ylabel("mm")
    top.set_title(f"{job_id}: thread passes on feedback")
    top.legend(loc="upper left", fontsize=8)
    top.grid(alpha=0.3)
    bottom.bar(index, chip, width=0.5, color=np.where(chip <= 1.0, "tab:green", "tab:red"))
    bottom.axhline(1.0, color="k", ls="--", lw=1, label="one spindle revolution")
    bottom.set_ylabel("longest chip (rev)")
    bottom.set_xlabel("pass")
    bottom.set_xticks(index)
    bottom.legend(loc="upper left", fontsize=8)
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _thread_section(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray,
                    job_id: str) -> plt.Figure:
    """The groove's cross-section on feedback (thread_analysis.cross_section, in program
    coordinates as the report judges it): per pass the tool tip's path in the plane of the
    thread form, sliding along the flank with its vibration; and the depth along the first
    revolutions of the groove, each pass against the one before it (where a pass's return
    rises above the previous pass's turning point the tool is in air and the chip breaks)."""
    thread = json.loads(run.goals[-1])["thread"]
    kin = Kinematics(machine, job.setup, job.tool)
    t, q = run.feedback_t[window], run.feedback[window]
    radius, z = kin.tip_radius_z(q[:, run.column("x")], q[:, run.column("z")])
    passes = cross_section(t, radius, z, q[:, run.column(SPINDLE)], thread)
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, max(len(passes), 1)))
    fig, (section, along) = plt.subplots(1, 2, figsize=(12, 5.5), gridspec_kw={"width_ratios": [1, 1.6]})
    for p, colour in zip(passes, colours):
        label = f"pass {p['index'] + 1}"
        section.plot(p["offset_mm"], p["depth_mm"], color=colour, lw=0.8, label=label)
        shown = p["groove_revs"] <= SECTION_REVS
        along.plot(p["groove_revs"][shown], p["depth_mm"][shown], color=colour, lw=1.0, label=label)
    deepest = max((float(np.max(p["depth_mm"])) for p in passes), default=0.0)
    flank = np.array([0.0, deepest])
    section.plot(flank * math.tan(math.radians(thread.get("infeed_angle", 29.5))), flank, "k--", lw=1,
                 label="infeed line")
    section.set_xlabel("axial offset from the nominal helix along the feed (mm)")
    section.set_ylabel("depth below the surface (mm)")
    section.set_title(f"{job_id}: groove cross-section on feedback")
    along.set_xlabel("along the groove from the face (spindle revolutions)")
    along.set_ylabel("depth below the surface (mm)")
    along.set_title(f"depth per pass, first {SECTION_REVS:g} revolutions")
    for ax in (section, along):
        ax.invert_yaxis()
        ax.grid(alpha=0.3)
    along.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


def draw(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray, report: dict) -> list[tuple]:
    """The thread job's figures: (figure, file name) pairs."""
    return [(_thread_passes(report["thread"], report["job_id"]), "thread_passes.png"),
            (_thread_section(run, job, machine, window, report["job_id"]), "thread_section.png")]
