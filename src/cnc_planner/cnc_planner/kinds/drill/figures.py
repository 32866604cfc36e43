"""The drill figures: the tool path in X-Z with the air arcs between holes, the S1/S2/S3
timing per hole on feedback and, for a job of more holes than that timing shows, a map of
every hole. A plate of 300 holes drew 300 holes' phases on top of one another (legible to
no one, and 4 of the 8 s its figures took)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.patches import Rectangle

from cnc_msgs_py.machine import Machine

from cnc_analysis.recording import Run

from cnc_planner.drawing import COMMAND, FEEDBACK, MM, envelope, plt, recording_note, stride
from cnc_planner.kinds.drill.block import drill_cycle
from cnc_planner.kinds.drill.cycle import DrillCycle
from cnc_planner.kinematics import Kinematics


MOVING = 1e-4  # m/s: below this an axis counts as standing (end of the last retract)
DETAIL_HOLES = 5  # holes the timing figure shows in detail: the first ones drilled
LABELLED_HOLES = 20  # the X-Z figure names each hole up to this many


PHASES = {"S1": ("S1  X/Y to hole", "tab:blue"), "S2": ("S2  Z down + feed", "tab:red"),
          "S3": ("S3  Z retract", "tab:green")}
CAPTIONS = {  # figure file stem -> what the report page says under it
    "drill_xz": "Tool tip over the part: the air path from hole to hole on feedback, with the R plane, the "
                "surface and the drilled depth; overlapping X and Z moves turn the R -> R' -> R path into an arc.",
    "drill_timing": "Phases per hole on feedback: S1 X/Y positioning, S2 Z approach and feed, S3 retract. Overlap "
                    f"shows as bars of one hole running side by side. A job of more than {DETAIL_HOLES} holes shows "
                    f"its first {DETAIL_HOLES}.",
    "drill_map": "Every hole where it lies, coloured by its time (from the end of the previous hole's retract) and "
                 "by the lowest the tip was above the R plane on the way to it while X/Y was off the hole by more "
                 "than the tolerance, on feedback: below 0 would be X/Y motion below R.",
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
    left, right, low, top = holes_x - width / 2, holes_x + width / 2, planes[:, 2], planes[:, 0]
    corners = np.stack([np.column_stack(c) for c in ((left, low), (right, low), (right, top), (left, top))], axis=1)
    ax.add_collection(PolyCollection(corners, facecolors="white", edgecolors="0.5", linewidths=0.6))  # one artist
    for i, hx in enumerate(holes_x if len(holes_x) <= LABELLED_HOLES else []):
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
    detail = ""
    if len(holes) > DETAIL_HOLES:  # the first holes drilled, and the feedback until they are done
        began: dict[int, float] = {}
        for h, a, _ in (bar for spans in bars.values() for bar in spans):
            began[h] = min(a, began.get(h, a))
        shown = set(sorted(began, key=began.get)[:DETAIL_HOLES])
        bars = {phase: [bar for bar in spans if bar[0] in shown] for phase, spans in bars.items()}
        end = max((b for spans in bars.values() for _, _, b in spans), default=t[-1])
        until = t <= end
        t, fb, vel = t[until], fb[until], vel[until]
        holes = [h for h in holes if h["index"] in shown]
        detail = f": the first {len(shown)} of {len(report['drill']['holes'])} holes"

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
    pos.set_title(f"{job.job_id}: overlapped drilling on feedback{detail} (grey: tip below R){recording_note(run)}",
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


def _lowest_above_r(run: Run, cycle: DrillCycle, window: np.ndarray, holes: list[dict]) -> np.ndarray:
    """Per hole of the report (mm): the lowest the tip was above its R plane on the way to
    it while X/Y was still off the hole by more than the tolerance, on feedback, as the
    judge (cnc_analysis.drilling) counts a violation: below 0 would be one; nan where X/Y
    was on the hole all along."""
    t, fb = run.feedback_t[window], run.feedback[window]
    cx, cy, cz = run.column("x"), run.column("y"), run.column("z")
    at = {(cycle.order[i] if cycle.order else i): i for i in range(len(cycle.holes))}  # job index -> drilled
    down = sorted((h["r_down_s"], k) for k, h in enumerate(holes) if h["r_down_s"] is not None and h["index"] in at)
    towards = np.searchsorted(np.array([d for d, _ in down]), t)  # the next hole the tip goes below R at
    left = np.array([-np.inf] + [holes[k]["r_up_s"] or np.inf for _, k in down])  # the previous hole's R up
    going = (towards < len(down)) & (t >= left[towards])
    drilled = np.array([at[holes[k]["index"]] for _, k in down], dtype=int)
    goal = np.array([cycle.holes[i] for i in drilled]).reshape(-1, 2)
    r_z = np.array([cycle.planes(i)[1] for i in drilled])
    to = towards[going]
    off = np.hypot(fb[going, cx] - goal[to, 0], fb[going, cy] - goal[to, 1]) > cycle.xy_tolerance
    lowest = np.full(len(down), np.inf)
    np.minimum.at(lowest, to[off], fb[going, cz][off] - r_z[to[off]])
    out = np.full(len(holes), np.nan)
    out[[k for _, k in down]] = np.where(np.isfinite(lowest), lowest * MM, np.nan)
    return out


def _drill_map(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray, report: dict) -> plt.Figure:
    """Every hole at its X/Y, coloured by its time and by its lowest height above R while X/Y moved."""
    holes = report["drill"]["holes"]
    x, y = np.array([h["x_mm"] for h in holes]), np.array([h["y_mm"] for h in holes])
    times = np.array([h["cycle_time_s"] if h["cycle_time_s"] is not None else np.nan for h in holes])
    lowest = _lowest_above_r(run, _cycle(run, job, machine, window), window, holes)
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.4), sharex=True)
    for ax, values, label in ((axes[0], times, "time per hole (s)"),
                              (axes[1], lowest, "lowest above R\nwhile X/Y off the hole (mm)")):
        top = np.nanpercentile(values, 95) if np.isfinite(values).any() else None  # a first hole from far away
        dots = ax.scatter(x, y, c=values, cmap="viridis", vmax=top, s=max(8.0, 3000.0 / len(holes)),
                          edgecolors="none", plotnonfinite=True)
        fig.colorbar(dots, ax=ax, label=label, pad=0.01)
        ax.set_ylabel("Y (mm)")
        ax.grid(alpha=0.3)
    axes[1].set_xlabel("X (mm)")
    axes[0].set_title(f"{job.job_id}: {len(holes)} holes on feedback; time per hole", fontsize=10)
    axes[1].set_title(f"lowest tip above R while X/Y was off the hole: {np.nanmin(lowest):.2f} mm"
                      if np.isfinite(lowest).any() else "X/Y was never off a hole below R+", fontsize=10)
    fig.tight_layout()
    return fig


def draw(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray, report: dict) -> list[tuple]:
    """The drill job's figures: (figure, file name) pairs; a map of every hole when the
    timing figure shows only the first DETAIL_HOLES."""
    figures = [(_drill_xz(run, job, machine, window), "drill_xz.png"),
               (_drill_timing(run, job, machine, window, report), "drill_timing.png")]
    if len(report["drill"]["holes"]) > DETAIL_HOLES:
        figures.append((_drill_map(run, job, machine, window, report), "drill_map.png"))
    return figures


def first_hole_aircut(report: dict) -> dict | None:
    """A drill job judges its air-cuts per hole: the air-cut figures summarise its first hole."""
    holes = report.get("drill", {}).get("holes", [])
    return holes[0].get("aircut") if holes else None
