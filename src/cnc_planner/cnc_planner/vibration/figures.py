"""The air-cut figures of a vibrated feed: progress against spindle angle revolution by
revolution, and the map of where the tool cut air."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from matplotlib.patches import Patch

from cnc_msgs_py.machine import SPINDLE

from cnc_analysis.aircut import analyze_aircut
from cnc_analysis.aircut import AircutReport
from cnc_analysis.recording import Run

from cnc_planner.drawing import MM, TWO_PI, plt


PHASE_BINS = 360  # 1 deg columns of the air-cut map
CAPTIONS = {  # figure file stem -> what the report page says under it
    "aircut": "The vibrating feed: feed progress over time, command vs feedback, with the air-cut intervals.",
    "aircut_map": "Air-cut map: feed progress unrolled over the spindle angle, one revolution after the other; "
                  "marked intervals are where the tool is in the air and the chip breaks.",
}


def first_vibrating_feed(run: Run, job_id: str) -> SimpleNamespace | None:
    """Spindle angle and feed progress of the job's first vibrating feed, commanded and on
    feedback (with its air-cut analysis); its feed per revolution F; the revolution the feed
    starts in and n, the middle analysed one (absolute revolutions of the spindle).
    None if the feedback holds no revolution to judge.
    """
    events = [e for e in run.events if e.get("job_id") == job_id]
    start = next((e for e in events if e["name"] == "vibration_feed"), None)
    if start is None:
        return None
    end = next((e for e in events if e["name"] == "vibration_end" and e["stamp_ns"] >= start["stamp_ns"]), None)
    if end is None:
        return None
    cols = [run.column(j) for j in start["joints"]]
    spindle = run.column(SPINDLE)

    def along(times: np.ndarray, positions: np.ndarray) -> SimpleNamespace:
        inside = (times >= start["stamp_ns"] / 1e9) & (times <= end["stamp_ns"] / 1e9)
        progress = (positions[inside][:, cols] - np.array(start["start"])) @ np.array(start["direction"])
        return SimpleNamespace(theta=positions[inside, spindle], progress=progress)

    command, feedback = along(run.command_t, run.command), along(run.feedback_t, run.feedback)
    if len(feedback.theta) < 2:
        return None
    feedback.aircut = analyze_aircut(feedback.theta, feedback.progress)
    revs = _analysed_revolutions(feedback.theta, feedback.aircut)
    if not revs:
        return None
    theta_start = float(np.interp(start["stamp_ns"] / 1e9, run.command_t, run.command[:, spindle]))
    return SimpleNamespace(F=float(start["feed_per_rev"]), theta_start=theta_start, command=command,
                           feedback=feedback, first_rev=math.floor(theta_start / TWO_PI),
                           n=revs[max(0, (len(revs) - 3) // 2)])


def _analysed_revolutions(theta: np.ndarray, aircut: AircutReport) -> range:
    """The absolute revolution numbers analyze_aircut's intervals belong to: the complete ones
    at the end of the feed (the first revolutions have no earlier surface)."""
    last = math.floor((theta[-1] + 1e-9) / TWO_PI) - 1
    return range(last - aircut.revolutions + 1, last + 1)


def aircut_figure(feed: SimpleNamespace, summary: dict) -> plt.Figure:
    """Feed position against spindle phase for revolutions n, n+1, n+2, as cut.

    y is the feed progress minus the nominal feed line F*theta/2pi, plus k*F for revolution
    n+k: every revolution sits F above the one before, so the tool cuts air wherever a
    curve dips below the curves under it (the surface the earlier revolutions left).
    """
    revs = _analysed_revolutions(feed.feedback.theta, feed.feedback.aircut)
    shown = [k for k in (feed.n, feed.n + 1, feed.n + 2) if k in revs]
    colors = ("tab:blue", "tab:orange", "tab:green")

    fig, ax = plt.subplots(figsize=(10, 5.6))
    for offset, (k, color) in enumerate(zip(shown, colors)):
        for source, lw, alpha in ((feed.command, 0.9, 1.0), (feed.feedback, 2.6, 0.55)):
            inside = (source.theta >= TWO_PI * k - 0.02) & (source.theta <= TWO_PI * (k + 1) + 0.02)
            theta = source.theta[inside]
            y = source.progress[inside] / feed.F - (theta - feed.theta_start) / TWO_PI + offset
            ax.plot(np.degrees(theta - TWO_PI * k), y, color=color, lw=lw, alpha=alpha)
        if offset:  # rev n cuts air against rev n-1, which is not drawn
            for a, b in feed.feedback.aircut.intervals[k - revs[0]]:
                ax.axvspan(math.degrees(a), math.degrees(b), color=color, alpha=0.18, lw=0)
        ax.axhline(offset, color=color, lw=0.7, ls=":")
    handles = [plt.Line2D([], [], color=color, lw=2.2, label=f"rev n+{offset}" if offset else "rev n")
               for offset, color in enumerate(colors[:len(shown)])]
    handles += [plt.Line2D([], [], color="0.3", lw=0.9, label="command (thin)"),
                plt.Line2D([], [], color="0.3", lw=2.6, alpha=0.55, label="feedback (thick)"),
                Patch(color="0.5", alpha=0.25, label="air-cut on feedback\n(colour of its rev)"),
                plt.Line2D([], [], color="0.3", lw=0.7, ls=":", label="nominal feed line")]
    ax.legend(handles=handles, loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    ax.set_xlim(0, 360)
    ax.set_xticks(range(0, 361, 45))
    ax.set_xlabel("spindle phase (deg)")
    ax.set_ylabel(f"feed position - nominal feed line, in F (F = {feed.F * MM:.3f} mm/rev)\n"
                  "revolution n+k plotted k F higher, as cut")
    ax.grid(alpha=0.3)
    fb = summary["feedback"]
    scope = "first hole below the surface" if "aircut_fraction" in fb else "whole job"
    ax.set_title(f"chip breaking, first vibrating feed, n = rev {feed.n - feed.first_rev} of the feed\n"
                 f"{scope} on feedback: air-cut in {fb['revolutions_with_aircut']}/{fb['revolutions']} revs, "
                 f"longest chip {fb['max_chip_revs']:.2f} rev", fontsize=10)
    fig.tight_layout()
    return fig


def aircut_map(feed: SimpleNamespace) -> plt.Figure:
    """Depth of cut below the earlier surface, revolution after revolution, over the phase.

    The surface at a phase is the furthest any earlier revolution got there (as in
    analyze_aircut); air-cut cells are those inside its intervals.
    """
    fb = feed.feedback
    first, last = math.floor(fb.theta[0] / TWO_PI), math.floor(fb.theta[-1] / TWO_PI)
    revs = np.arange(first, last + 1)
    phases = (np.arange(PHASE_BINS) + 0.5) / PHASE_BINS
    grid = np.interp(TWO_PI * (revs[:, None] + phases[None]), fb.theta, fb.progress, left=np.nan, right=np.nan)
    depth = np.full(grid.shape, np.nan)
    depth[1:] = (grid[1:] - np.fmax.accumulate(grid, axis=0)[:-1]) * MM
    analysed = _analysed_revolutions(fb.theta, fb.aircut)
    judged = np.isin(revs, list(analysed))
    depth[~judged] = np.nan
    air = np.zeros(grid.shape, dtype=bool)
    for k, intervals in zip(analysed, fb.aircut.intervals):
        for a, b in intervals:
            air[k - first] |= (phases * TWO_PI >= a) & (phases * TWO_PI <= b)
    extent = (0, 360, first - feed.first_rev - 0.5, last - feed.first_rev + 0.5)

    fig, ax = plt.subplots(figsize=(10, 6))
    cmap = plt.get_cmap("viridis").with_extremes(bad="white")
    image = ax.imshow(np.ma.masked_where(air | np.isnan(depth), depth), aspect="auto", origin="lower",
                      extent=extent, cmap=cmap, vmin=0.0, interpolation="nearest")
    overlay = np.zeros(grid.shape + (4,))
    overlay[air] = (0.85, 0.1, 0.1, 1.0)
    ax.imshow(overlay, aspect="auto", origin="lower", extent=extent, interpolation="nearest")
    fig.colorbar(image, ax=ax, label="depth of cut below earlier surface (mm)")
    n = feed.n - feed.first_rev
    for edge in (n - 0.5, n + 2.5):
        ax.axhline(edge, color="black", lw=1.2, ls="--")
    ax.legend(handles=[Patch(color=(0.85, 0.1, 0.1), label="air-cut (chip breaks)"),
                       Patch(fc="white", ec="0.5", label="not judged (no earlier surface)"),
                       plt.Line2D([], [], color="k", ls="--", label="revs n..n+2 of aircut.png")],
              loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8)
    ax.set_xticks(range(0, 361, 45))
    ax.set_xlabel("spindle phase (deg)")
    ax.set_ylabel("revolution of the feed")
    ax.set_title(f"air-cut map on feedback, first vibrating feed (F = {feed.F * MM:.3f} mm/rev)", fontsize=11)
    fig.tight_layout()
    return fig
