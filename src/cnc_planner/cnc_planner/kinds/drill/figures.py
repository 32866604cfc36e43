"""The drill figures: the tool path in X-Z with the air arcs between holes, and the
S1/S2/S3 timing per hole on feedback."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from matplotlib.patches import Rectangle

from cnc_msgs_py.machine import Machine

from cnc_analysis.recording import Run

from cnc_planner.drawing import COMMAND, FEEDBACK, MM, envelope, plt, recording_note, stride
from cnc_planner.kinds.drill.block import drill_cycle
from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinematics import Kinematics


MOVING = 1e-4  # m/s: below this an axis counts as standing (end of the last retract)


PHASES = {"S1": ("S1  X/Y to hole", "tab:blue"), "S2": ("S2  Z down + feed", "tab:red"),
          "S3": ("S3  Z retract", "tab:green")}
CAPTIONS = {  # figure file stem -> what the report page says under it
    "drill_xz": "Tool tip over the part: the air path from hole to hole on feedback, with the R plane, the "
                "surface and the drilled depth; overlapping X and Z moves turn the R -> R' -> R path into an arc.",
    "drill_timing": "Phases per hole on feedback: S1 X/Y positioning, S2 Z approach and feed, S3 retract. Overlap "
                    "shows as bars of one hole running side by side.",
}


def _cycle(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> DrillCycle:
    """The drill cycle as planned from where the job started (its hole order and X/Y plane)."""
    first = run.feedback[window][0]
    return drill_cycle(job, machine, Kinematics(machine, job.setup, job.tool),
                       (float(first[run.column("x")]), float(first[run.column("y")])))


def _drill_xz(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> plt.Figure:
    """The tool path in X-Z: feed below R inside the holes, air arcs above R between them,
    and the obstacles (clamps) the arcs pass over."""
    cx, cz = run.column("x"), run.column("z")
    cycle = _cycle(run, job, machine, window)
    every = stride(int(window.sum()))
    x, z = run.feedback[window][every, cx] * MM, run.feedback[window][every, cz] * MM
    cmd = (run.command_t >= run.feedback_t[window][0]) & (run.command_t <= run.feedback_t[window][-1])
    command = run.command[cmd][stride(int(cmd.sum()))] * MM
    r_z, surface, bottom = cycle.r_z * MM, cycle.surface_z * MM, cycle.bottom_z * MM
    holes_x = np.array([h[0] for h in cycle.holes]) * MM
    width = (job.tool.diameter or 0.0) * MM

    fig, ax = plt.subplots(figsize=(11, 5))
    depth = surface - bottom
    ax.axhspan(bottom - 0.6 * depth, surface, color="tan", alpha=0.35, lw=0, label="workpiece")
    planes = np.array([cycle.planes(i) for i in range(len(holes_x))]) * MM  # surface, R, bottom per hole
    for i, (hx, (top, _, low)) in enumerate(zip(holes_x, planes)):
        ax.add_patch(Rectangle((hx - width / 2, low), width, top - low, color="white", ec="0.5", lw=0.6))
        ax.text(hx, bottom - 0.25 * depth, f"hole {cycle.order[i] if cycle.order else i}", ha="center", va="top",
                fontsize=8)
    ax.plot(holes_x, planes[:, 2], "k^", ms=6, label=f"hole bottom z={bottom:.2f}" if np.ptp(planes[:, 2]) == 0
            else "hole bottoms")
    for k, (x0, _, x1, _, top) in enumerate(job.drill.obstacles or []):  # program = axis on a plain setup
        ax.add_patch(Rectangle((x0 * MM, surface), (x1 - x0) * MM, top * MM - surface, color="0.55", alpha=0.6,
                               hatch="//", label="obstacle (clamp)" if k == 0 else None))
    ax.axhline(surface, color="saddlebrown", lw=1.2, label=f"surface z={surface:.2f}")
    ax.axhline(r_z, color="tab:orange", lw=1.2, ls="--", label=f"R plane z={r_z:.2f}")
    ax.plot(command[:, cx], command[:, cz], color=COMMAND, lw=0.7, ls=":", label="command")
    ax.plot(x, np.where(z >= r_z, z, np.nan), color="tab:blue", lw=2, label="feedback in air (above R)")
    ax.plot(x, np.where(z <= r_z, z, np.nan), color=FEEDBACK, lw=2, label="feedback below R")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Z (mm)")
    ax.set_ylim(bottom - 0.6 * depth, max(z.max(), r_z) + 0.15 * depth)
    ax.grid(alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    ax.set_title(f"{job.job_id}: tool path in X-Z on feedback (air arcs between holes){recording_note(run)}",
                 fontsize=11)
    fig.tight_layout()
    return fig


def _phase_bars(run: Run, job_id: str, holes: list[dict], z_stop: float) -> dict[str, list[tuple[int, float, float]]]:
    """(hole, start, end) per phase from the recorded events (s of ROS time).

    S1 ends when X/Y is in position on feedback (report), S2 when the retract starts, S3 at
    the top of the next air arc (the next hole's S2), the last one when Z stops on feedback.
    Phases of no length (X/Y already at the hole, feedback lost before Z stopped) get no bar.
    """
    marks: dict[tuple[str, int], float] = {}
    for e in run.events:
        if e.get("job_id") == job_id and e["name"] in ("S1", "S2", "S3", "R_down"):
            marks[(e["name"], e["hole"])] = e["stamp_ns"] / 1e9
    drilled = sorted((h for name, h in marks if name == "S1"), key=lambda h: marks[("S1", h)])
    in_position = {h["index"]: h["in_position_s"] for h in holes}
    bars: dict[str, list[tuple[int, float, float]]] = {name: [] for name in PHASES}
    for rank, h in enumerate(drilled):
        bars["S1"].append((h, marks[("S1", h)], in_position.get(h) or marks.get(("R_down", h), 0.0)))
        if ("S3", h) in marks:
            following = drilled[rank + 1] if rank + 1 < len(drilled) else None
            bars["S2"].append((h, marks[("S2", h)], marks[("S3", h)]))
            bars["S3"].append((h, marks[("S3", h)], marks.get(("S2", following), z_stop)))
    return {name: [bar for bar in spans if bar[2] > bar[1]] for name, spans in bars.items()}


def _drill_timing(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray,
                  report: dict) -> plt.Figure:
    """X and Z position and velocity over time with the S1/S2/S3 chart: where the phases overlap."""
    cycle = _cycle(run, job, machine, window)
    t = run.feedback_t[window]
    t0 = t[0]
    fb, vel = run.feedback[window], run.feedback_velocity[window]
    cz = run.column("z")
    moving = np.flatnonzero(np.abs(vel[:, cz]) > MOVING)
    z_stop = t[moving[-1]] if len(moving) else t[-1]
    holes = report["drill"]["holes"]
    bars = _phase_bars(run, report["job_id"], holes, z_stop)

    fig, (pos, speed, chart) = plt.subplots(3, 1, figsize=(11, 8.2), sharex=True,
                                            gridspec_kw={"height_ratios": (3, 3, 2)})
    for name, color in (("x", "tab:blue"), ("z", "tab:red")):
        j = run.column(name)
        pos.plot(*envelope(t - t0, fb[:, j] * MM), color=color, lw=1.5, label=f"{name.upper()}")
        speed.plot(*envelope(t - t0, vel[:, j] * MM), color=color, lw=1.2, label=f"{name.upper()}")
    pos.axhline(cycle.r_z * MM, color="tab:orange", ls="--", lw=1, label="R plane")
    pos.axhline(cycle.surface_z * MM, color="saddlebrown", lw=1, label="surface")
    speed.axhline(-cycle.feed * MM, color="tab:red", ls=":", lw=1,
                  label=f"Z feed {cycle.feed * MM * 60:.0f} mm/min\n(= -{cycle.feed * MM:.0f} mm/s)")
    for h in holes:
        if h["r_down_s"] is not None:
            for ax in (pos, speed):
                ax.axvspan(h["r_down_s"] - t0, h["r_up_s"] - t0, color="0.85", lw=0)
    pos.set_ylabel("position (mm)")
    speed.set_ylabel("velocity (mm/s)")
    pos.set_title(f"{job.job_id}: overlapped drilling on feedback (grey: tip below R){recording_note(run)}",
                  fontsize=11)
    for ax in (pos, speed):
        ax.grid(alpha=0.3)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)

    for lane, (phase, (label, color)) in enumerate(reversed(PHASES.items())):
        spans = bars[phase]
        chart.broken_barh([(a - t0, b - a) for _, a, b in spans], (lane - 0.35, 0.7), color=color, alpha=0.75)
        for h, a, b in spans:
            chart.text((a + b) / 2 - t0, lane, str(h), ha="center", va="center", fontsize=8, color="white",
                       fontweight="bold")
    chart.set_yticks(range(len(PHASES)), [label for label, _ in reversed(PHASES.values())], fontsize=8)
    chart.set_ylim(-0.6, len(PHASES) - 0.4)
    chart.set_xlabel("time from job start (s)")
    chart.set_title("phases per hole (number = hole index); bars one above the other overlap in time",
                    fontsize=9)
    chart.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def draw(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray, report: dict) -> list[tuple]:
    """The drill job's figures: (figure, file name) pairs."""
    return [(_drill_xz(run, job, machine, window), "drill_xz.png"),
            (_drill_timing(run, job, machine, window, report), "drill_timing.png")]


def first_hole_aircut(report: dict) -> dict | None:
    """A drill job judges its air-cuts per hole: the air-cut figures summarise its first hole."""
    holes = report.get("drill", {}).get("holes", [])
    return holes[0].get("aircut") if holes else None
