"""Air-cuts of every vibrated feed of a run, judged on the commands and on the feedback; the
verdict fails a feed whose longest chip on feedback exceeds its waveform's window
(cnc_analysis.aircut.chip_limit_revs: one revolution, or E for one vibration every E)."""
from __future__ import annotations

import numpy as np

from cnc_msgs_py.machine import SPINDLE

from cnc_analysis.aircut import CHIP_LIMIT_REVS, analyze_aircut, chip_limit_revs
from cnc_analysis.recording import Run
from cnc_analysis.verdict import verdict


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


def chip_failures(judged: list[tuple[dict, dict | None]]) -> list[str]:
    """The feeds (start event, feed_aircut on feedback or None) whose longest chip exceeds
    their waveform's limit: one phrase for all of them, naming the worst."""
    over = []
    for start, found in judged:
        limit = chip_limit_revs(start.get("vibration"))
        if found is not None and found["max_chip_revs"] > limit:
            over.append((found["max_chip_revs"], limit, start))
    if not over:
        return []
    chip, limit, start = max(over, key=lambda o: o[0] / o[1])
    where = f" ({start['field']})" if start.get("field") else ""
    return [f"{len(over)} of {len(judged)} vibrated feeds left chips longer than their window on feedback, the worst "
            f"{chip:.2f} rev where {limit:g} rev break it{where}"]


CHIP_CRITERION = (f"on feedback: every vibrated feed's longest chip within {CHIP_LIMIT_REVS:g} revolution per "
                  f"vibration window (E revolutions for one vibration every E)")


def aircut_section(run: Run) -> dict:
    """Air-cuts of every vibrating feed, on the commands and on the feedback, and the verdict
    on the feedback's chips."""
    out = {}
    judged: list[tuple[dict, dict | None]] = []
    for source, times, positions in (("commanded", run.command_t, run.command),
                                     ("feedback", run.feedback_t, run.feedback)):
        totals = {"revolutions": 0, "revolutions_with_aircut": 0, "max_chip_revs": 0.0}
        for start, end in feeds(run):
            report = feed_aircut(run, times, positions, start, end)
            if source == "feedback":
                judged.append((start, report))
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
        "verdict": verdict(CHIP_CRITERION, chip_failures(judged),
                           f"longest chip {out['feedback']['max_chip_revs']:.2f} rev on feedback, "
                           f"air-cut in {out['feedback']['revolutions_with_aircut']} of "
                           f"{out['feedback']['revolutions']} revolutions"),
    }
