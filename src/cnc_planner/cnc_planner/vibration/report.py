"""Air-cuts of every vibrated feed of a run, judged on the commands and on the feedback."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE

from cnc_analysis.aircut import analyze_aircut
from cnc_analysis.recording import Run


def feeds(run: Run) -> list[tuple[dict, float]]:
    """Every vibrated feed of the run: its start event and its end time (s)."""
    starts = [e for e in run.events if e.get("name") == "vibration_feed"]
    ends = [e["stamp_ns"] / 1e9 for e in run.events if e.get("name") == "vibration_end"]
    return list(zip(starts, ends))


def feed_aircut(run: Run, times: np.ndarray, positions: np.ndarray, start: dict, end: float,
                 below: float | None = None) -> dict | None:
    """analyze_aircut of one vibrated feed (from where its progress first passes ``below``,
    m along the feed, if given), or None if not even one revolution was recorded."""
    inside = (times >= start["stamp_ns"] / 1e9) & (times <= end)
    cols = [run.column(j) for j in start["joints"]]
    progress = (positions[:, cols] - np.array(start["start"])) @ np.array(start["direction"])
    if below is not None:
        cut = inside & (progress > below)
        inside &= np.arange(len(times)) >= (int(np.argmax(cut)) if cut.any() else len(times))
    spindle = positions[inside, run.column(SPINDLE)]
    if len(spindle) < 2 or abs(spindle[-1] - spindle[0]) < 2 * np.pi:
        return None  # not even one revolution recorded: nothing to judge
    return analyze_aircut(spindle, progress[inside]).to_dict()


def aircut_section(run: Run) -> dict:
    """Air-cuts of every vibrating feed, on the commands and on the feedback."""
    out = {}
    for source, times, positions in (("commanded", run.command_t, run.command),
                                     ("feedback", run.feedback_t, run.feedback)):
        totals = {"revolutions": 0, "revolutions_with_aircut": 0, "max_chip_revs": 0.0}
        for start, end in feeds(run):
            report = feed_aircut(run, times, positions, start, end)
            if report is None:
                continue
            totals["revolutions"] += report["revolutions"]
            totals["revolutions_with_aircut"] += report["revolutions_with_aircut"]
            totals["max_chip_revs"] = max(totals["max_chip_revs"], report["max_chip_revs"])
        out[source] = totals
    return {
        "revolutions": out["feedback"]["revolutions"],
        "revolutions_with_aircut": out["feedback"]["revolutions_with_aircut"],
        "max_chip_revs": out["feedback"]["max_chip_revs"],
        "commanded": out["commanded"],
        "feedback": out["feedback"],
    }
