"""PNG figures of a recorded run, for machinists: what the axes really did, in mm, s and deg.

Every figure is drawn from the recorded feedback of the run's last job (the commands only
where they are compared with it), over the window report.json judges. The job geometry
(planes and holes, stock and profile, the vibrating feed's line) is re-derived from the
recorded job document with the planner's own code, as the report does, so the lines drawn
are the ones the figures were judged against. Long runs are thinned for drawing only.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend is chosen first)
import numpy as np  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from cnc_msgs_py.machine import SPINDLE, Machine, load_machine  # noqa: E402
from cnc_msgs_py.units import to_mm
from cnc_servo_bridge.aircut import AircutReport, analyze_aircut  # noqa: E402
from cnc_servo_bridge.recording import Run  # noqa: E402
from cnc_servo_bridge.thread_analysis import cross_section  # noqa: E402

from .drilling import DrillCycle  # noqa: E402
from .jobs import drill_cycle  # noqa: E402
from .kinematics import Kinematics  # noqa: E402
from .report import job_window, last_job  # noqa: E402
from .turning import offset_outline, plan_roughing  # noqa: E402

DPI = 110
MM = to_mm(1.0)  # m -> mm, as a scale for plot axes
LINE_POINTS = 4000  # min/max buckets per time trace: peaks survive, drawing stays fast
PATH_POINTS = 20000  # samples per drawn tool path (1 kHz feedback of a smooth path)
PHASE_BINS = 360  # 1 deg columns of the air-cut map
SECTION_REVS = 3.0  # revolutions of groove shown pass against pass in the thread cross-section
TWO_PI = 2.0 * math.pi
MOVING = 1e-4  # m/s: below this an axis counts as standing (end of the last retract)
LOOKAHEAD_MOVES = 3  # planned moves a feedback sample may be matched to: lag cuts short moves
LOST_TAIL_S = 0.1  # s: feedback ending this much before the commands did is flagged
FEEDBACK, COMMAND = "tab:red", "0.25"
PHASES = {"S1": ("S1  X/Y to hole", "tab:blue"), "S2": ("S2  Z down + feed", "tab:red"),
          "S3": ("S3  Z retract", "tab:green")}


def write_plots(run: Run, report: dict, out_dir: Path) -> list[Path]:
    """Write the figures the run's job calls for into out_dir; returns the paths written.

    Every job gets following_error.png; drill, turn and vibration jobs (report sections
    drill, turn, aircut) get their method's figures. Nothing is drawn without feedback and
    commands to compare.
    """
    if len(run.feedback_t) < 2 or len(run.command_t) < 2:
        return []
    window = job_window(run, report["job_id"])
    if window.sum() < 2:
        return []
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [_save(_following_error(run, window, report), out_dir / "following_error.png")]
    if "thread" in report:
        written.append(_save(_thread_passes(report["thread"], report["job_id"]), out_dir / "thread_passes.png"))
    if not {"drill", "turn", "aircut", "thread"} & report.keys():
        return written
    _, job = last_job(run)
    machine = load_machine(job.machine)
    if "thread" in report:
        written.append(_save(_thread_section(run, job, machine, window, report["job_id"]),
                             out_dir / "thread_section.png"))
    if "drill" in report:
        written.append(_save(_drill_xz(run, job, machine, window), out_dir / "drill_xz.png"))
        written.append(_save(_drill_timing(run, job, machine, window, report), out_dir / "drill_timing.png"))
    if "turn" in report:
        written.append(_save(_turn_passes(run, job, machine, window), out_dir / "turn_passes.png"))
    # a drill job judges its air-cuts per hole: the figure summarises its first hole
    holes = report.get("drill", {}).get("holes", [])
    summary = report.get("aircut") or (holes[0].get("aircut") if holes else None)
    if summary and summary.get("feedback"):
        feed = _first_vibrating_feed(run, report["job_id"])
        if feed is not None:
            written.append(_save(_aircut(feed, summary), out_dir / "aircut.png"))
            written.append(_save(_aircut_map(feed), out_dir / "aircut_map.png"))
    return written


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


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _recording_note(run: Run) -> str:
    """A title line warning that the recorded feedback stops before the commands do: whatever
    the figure lacks at its end was not recorded, not left undone."""
    lost = run.command_t[-1] - run.feedback_t[-1]
    return f"\nfeedback recording ends {lost:.1f} s before the last command" if lost > LOST_TAIL_S else ""


def _envelope(t: np.ndarray, y: np.ndarray, points: int = LINE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Min and max per time bucket, so a thinned trace still shows every peak."""
    if len(t) <= points:
        return t, y
    starts = np.linspace(0, len(t), points // 2, endpoint=False).astype(int)
    lo, hi = np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)
    return np.repeat(t[starts], 2), np.stack([lo, hi], axis=1).ravel()


def _stride(n: int) -> slice:
    """Every k-th sample of a tool path, at most PATH_POINTS of them."""
    return slice(None, None, max(1, math.ceil(n / PATH_POINTS)))


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
        top.plot(*_envelope(t - t0, feedback), color=FEEDBACK, lw=2.2, alpha=0.6, label="feedback")
        top.plot(*_envelope(t - t0, command), color=COMMAND, lw=0.8, label="command")
        error = command - feedback
        bottom.plot(*_envelope(t - t0, error), color="tab:purple", lw=0.8)
        bottom.axhline(0.0, color="0.6", lw=0.6)
        top.set_title(f"{name.upper()} axis   max |error| {np.max(np.abs(error)):.3f} mm", fontsize=10)
        top.set_ylabel(f"{name.upper()} position (mm)")
        bottom.set_ylabel("following error (mm)")
        bottom.set_xlabel("time from job start (s)")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    grid[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(f"{report['job_id']}: following error = command - feedback{_recording_note(run)}", fontsize=11)
    fig.tight_layout()
    return fig


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
    every = _stride(int(window.sum()))
    x, z = run.feedback[window][every, cx] * MM, run.feedback[window][every, cz] * MM
    cmd = (run.command_t >= run.feedback_t[window][0]) & (run.command_t <= run.feedback_t[window][-1])
    command = run.command[cmd][_stride(int(cmd.sum()))] * MM
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
    ax.set_title(f"{job.job_id}: tool path in X-Z on feedback (air arcs between holes){_recording_note(run)}",
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
        pos.plot(*_envelope(t - t0, fb[:, j] * MM), color=color, lw=1.5, label=f"{name.upper()}")
        speed.plot(*_envelope(t - t0, vel[:, j] * MM), color=color, lw=1.2, label=f"{name.upper()}")
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
    pos.set_title(f"{job.job_id}: overlapped drilling on feedback (grey: tip below R){_recording_note(run)}",
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


def _turn_passes(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> plt.Figure:
    """Stock, part and the tool tip on feedback, true to scale: each feedback sample takes the
    kind (feed or rapid) of the planned move it executes, so cutting and air moves read apart."""
    tj = job.turn
    stock, profile = [tuple(p) for p in tj.stock], [tuple(p) for p in tj.profile]
    plan = plan_roughing(stock, profile, tj.depth_of_cut, tj.clearance, tuple(tj.origin),
                         tj.finish_allowance, tj.finishing_pass, tj.finish_allowance_z)
    kin = Kinematics(machine, job.setup, job.tool)
    fb = run.feedback[window][_stride(int(window.sum()))]
    radius, axial = kin.tip_radius_z(fb[:, run.column("x")], fb[:, run.column("z")])
    tip = np.stack([axial, radius], axis=1)
    # the rapid from wherever the job found the tool to the cycle's start point comes first
    starts = np.array([tip[0]] + [a for a, _ in plan.segments()])
    ends = np.array([plan.origin] + [m.end for _, m in plan.segments()])
    feed = np.array([False] + [m.kind == "feed" for _, m in plan.segments()])
    feed_of_sample = feed[_follow_moves(tip, starts, ends)]
    z, r = tip[:, 0] * MM, tip[:, 1] * MM
    z_span = max(z.max(), stock[0][0] * MM) - min(z.min(), stock[-1][0] * MM)
    r_span = max(r.max(), max(p[1] for p in stock) * MM)

    def area(outline: list[tuple[float, float]]) -> np.ndarray:
        zr = np.array(outline) * MM
        return np.vstack([[zr[0, 0], 0.0], zr, [zr[-1, 0], 0.0]])

    fig, ax = plt.subplots(figsize=(12, float(np.clip(8.5 * r_span / z_span + 1.4, 3.8, 9.0))))
    ax.fill(*area(stock).T, color="tan", alpha=0.45, lw=1, ec="saddlebrown", label="stock before roughing")
    ax.fill(*area(profile).T, color="0.7", lw=1, ec="0.3", label="final profile")
    allowance = np.array(offset_outline(profile, tj.finish_allowance, tj.finish_allowance_z)) * MM
    ax.plot(allowance[:, 0], allowance[:, 1], color="0.2", ls="--", lw=0.9,
            label=f"profile + allowance {tj.finish_allowance * MM:.2f} mm (X), {tj.finish_allowance_z * MM:.2f} mm (Z)")
    ax.plot(z, np.where(~feed_of_sample, r, np.nan), color="tab:blue", lw=0.9, ls="--", label="rapid (air)")
    ax.plot(z, np.where(feed_of_sample, r, np.nan), color=FEEDBACK, lw=1.8, label="cutting feed")
    ax.plot(*(np.array(tj.origin) * MM), "ko", ms=5, label="start point")
    ax.axhline(0.0, color="0.4", lw=0.8, ls="-.")
    ax.set_aspect("equal")
    ax.set_xlabel("Z (mm)")
    ax.set_ylabel("X radius (mm)")
    ax.grid(alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    ax.set_title(f"{job.job_id}: roughing passes on feedback, {plan.passes} planned{_recording_note(run)}",
                 fontsize=11)
    fig.tight_layout()
    return fig


def _follow_moves(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Index of the planned move each sample (in time order) executes: the nearest of the
    current move and the next ones, never going back, so that a rapid crossing an earlier
    pass line stays a rapid."""
    distance = _segment_distance(points, starts, ends)
    index = np.empty(len(points), dtype=int)
    k = 0
    for i, row in enumerate(distance):
        k += int(np.argmin(row[k:k + LOOKAHEAD_MOVES]))
        index[i] = k
    return index


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 2) to each segment a[k]-b[k]: shape (n, m)."""
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=1), 1e-24)
    share = np.clip(np.einsum("nmk,mk->nm", points[:, None, :] - a[None], ab) / length2, 0.0, 1.0)
    nearest = a[None] + share[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2)


def _first_vibrating_feed(run: Run, job_id: str) -> SimpleNamespace | None:
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


def _aircut(feed: SimpleNamespace, summary: dict) -> plt.Figure:
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


def _aircut_map(feed: SimpleNamespace) -> plt.Figure:
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
