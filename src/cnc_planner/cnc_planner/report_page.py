"""DIR/report.html: one self-contained page a machinist reads at a glance.

The page holds the job summary, a verdict per question a machinist asks (did it finish,
was it safe, did the chips break, is there stock left or a gouge, how long did it take
against the conventional cycle and the lower bound, how well did the axes follow, were
setpoints lost), the per-hole / per-pass tables, and every plot with a caption. Plots are
embedded as base64 data URIs and the CSS is inline: no network, no JavaScript, so the file
can be mailed or opened from a bag archive as it is. This module works out what the page
says; templates/report.html.j2 (jinja2, every value escaped) lays it out.
"""
from __future__ import annotations

import base64
import math
from pathlib import Path

from jinja2 import Environment, PackageLoader

# Limits the verdicts are judged against (the same ones the integration tests use).
CHIP_MAX_REVS = 1.0  # a chip longer than one spindle revolution is not broken
GOUGE_LIMIT_MM = 0.01  # feedback into the finished part beyond this is a gouge
ROTARY = ("spindle", "a", "b", "c")  # joints in rad on the topics (shown in mrad)
PAGES = Environment(loader=PackageLoader("cnc_planner"), autoescape=True, trim_blocks=True, lstrip_blocks=True,
                    keep_trailing_newline=True)

CAPTIONS = {
    "following_error": "Command vs feedback per axis, and the following error (command - feedback) over the job.",
    "drill_xz": "Tool tip over the part: the air path from hole to hole on feedback, with the R plane, "
                "the surface and the drilled depth; overlapping X and Z moves turn the R -> R' -> R path into an arc.",
    "drill_timing": "Phases per hole on feedback: S1 X/Y positioning, S2 Z approach and feed, S3 retract. "
                    "Overlap shows as bars of one hole running side by side.",
    "turn_passes": "Roughing passes over the stock outline and the final profile (X radius over Z), on feedback.",
    "aircut": "The vibrating feed: feed progress over time, command vs feedback, with the air-cut intervals.",
    "aircut_map": "Air-cut map: feed progress unrolled over the spindle angle, one revolution after the other; "
                  "marked intervals are where the tool is in the air and the chip breaks.",
    "thread_passes": "Thread passes: depth of cut per pass along the flank, with the vibration on each pass.",
    "thread_depths": "Thread pass depths: cumulative depth and depth of cut per pass.",
    "thread_section": "Groove cross-section per pass on feedback: the tool tip sliding along the flank with "
                      "its vibration, and each pass's depth along the groove against the pass before it "
                      "(its returns above the previous turning points are where the chip breaks).",
}


def write_report_page(report: dict, plots: list[Path], out: Path, *, job: dict | None = None) -> Path:
    """Write the run's report page to ``out`` (a file, e.g. DIR/report.html); returns it.

    Args:
        report: report.json's document (report.build_report, or the rejected report).
        plots: the PNG files to embed (plots.write_plots' list), in page order.
        out: the HTML file to write.
        job: the job document as submitted, for kind, machine and job file details.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render(report, plots, job=job), encoding="utf-8")
    return out


def render(report: dict, plots: list[Path], *, job: dict | None = None) -> str:
    """The page as a string (see write_report_page)."""
    job = job or {}
    state = report.get("state", "unknown")
    subtitle = " · ".join(str(x) for x in (job.get("kind"), f"machine {job['machine']}" if job.get("machine") else None,
                                           f"{job['spindle_rpm']} rpm" if job.get("spindle_rpm") else None) if x)
    # The method's own figures first, the following error (every job has it) last.
    figures = [_figure(p) for p in sorted(map(Path, plots), key=lambda p: p.stem == "following_error")]
    return PAGES.get_template("report.html.j2").render(
        title=f"CNC run {report.get('job_id', '')}", state=state, state_class=_state_class(state), subtitle=subtitle,
        reason=report.get("reason"), cards=verdicts(report), tables=tables(report), figures=figures)


def verdicts(report: dict) -> list[tuple[str, str, str, str]]:
    """(title, value, detail, class) per verdict card; class is ok | bad | warn | info."""
    cards = []
    state = report.get("state", "unknown")
    cards.append(("Job", state, report.get("reason") or _job_detail(report), _state_class(state)))
    if state == "rejected":
        return cards
    drill, turn, thread, aircut = (report.get(k) for k in ("drill", "turn", "thread", "aircut"))
    if drill is not None:
        n = drill.get("safety_violations", 0)
        cards.append(("Safety", "safe" if n == 0 else f"{n} violations",
                      f"X/Y moved while the tip was below R: {n} times, on feedback, over "
                      f"{len(drill.get('holes', []))} holes", "ok" if n == 0 else "bad"))
    if aircut is not None:
        revs, broken = aircut.get("revolutions", 0), aircut.get("revolutions_with_aircut", 0)
        chip = aircut.get("max_chip_revs", math.inf)
        good = revs > 0 and broken == revs and chip <= CHIP_MAX_REVS
        cards.append(("Chip breaking", "broken" if good else "long chips",
                      f"air-cut in {broken} of {revs} revolutions; longest chip {chip:.2f} rev "
                      f"(commanded {aircut.get('commanded', {}).get('max_chip_revs', float('nan')):.2f})",
                      "ok" if good else "bad"))
    if thread is not None:
        chip = thread.get("max_chip_revs", math.inf)
        cards.append(("Chip breaking", "broken" if thread.get("chips_broken") else "long chips",
                      f"longest chip {chip:.2f} rev over {thread.get('cutting_passes', '?')} cutting passes",
                      "ok" if thread.get("chips_broken") else "warn"))
        full = thread.get("full_depth")
        cards.append(("Thread depth", "full depth" if full else "not at depth",
                      f"depth error {_mm(thread.get('depth_error_mm'))}, overcut {_mm(thread.get('overcut_mm'))}, "
                      f"helix residual {_mm(thread.get('helix_residual_mm'))}; depth of cut "
                      f"{'never grows' if thread.get('doc_never_grows') else 'grows between passes'}",
                      "ok" if full else "bad"))
    if turn is not None:
        gouge = turn.get("max_gouge_part_mm", 0.0)
        left = turn.get("stock_left_mm")
        value = "no gouge" if gouge <= GOUGE_LIMIT_MM else f"gouge {gouge:.3f} mm"
        detail = (f"into the part {_mm(gouge)} on feedback, into the allowance {_mm(turn.get('max_gouge_mm'))}, "
                  f"commanded {_mm(turn.get('max_gouge_commanded_mm'))}")
        if left is not None:
            detail = f"stock left {_mm(left)}; " + detail
        cards.append(("Stock left / gouge", value, detail, "ok" if gouge <= GOUGE_LIMIT_MM else "bad"))
        cards.append(("Air moves", f"{turn.get('air_feed_mm', 0):.1f} mm",
                      f"air cut at feed, vs {turn.get('naive_air_feed_mm', 0):.1f} mm for passes started at the "
                      f"virtual cylinder; path {turn.get('path_mm', 0):.0f} mm vs {turn.get('naive_path_mm', 0):.0f} mm "
                      f"in {turn.get('passes', '?')} passes", "info"))
    cards.append(_cycle_card(report))
    cards.append(_following_card(report.get("max_following_error") or {}))
    lost, chunks = report.get("chunks_lost", 0), report.get("chunks", 0)
    alarms = report.get("alarms") or []
    cards.append(("Setpoints", f"{lost} chunks lost",
                  f"{report.get('setpoints', 0)} setpoints in {chunks} chunks"
                  + (f"; alarms: {', '.join(map(str, alarms))}" if alarms else "; no alarms"),
                  "ok" if lost == 0 and not alarms else "bad"))
    return cards


def _job_detail(report: dict) -> str:
    planned = report.get("planned_time_s")
    return f"planned {planned:.2f} s" if isinstance(planned, (int, float)) else ""


def _cycle_card(report: dict) -> tuple[str, str, str, str]:
    section = next((report[k] for k in ("drill", "turn") if isinstance(report.get(k), dict)
                    and "cycle_time_s" in report[k]), None)
    cycle = (section or report).get("cycle_time_s", 0.0)
    notes, cls = [], "info"
    conventional = (section or {}).get("conventional_cycle_time_s")
    if conventional:
        saved = 1.0 - cycle / conventional
        notes.append(f"{100 * saved:.1f} % faster than conventional {conventional:.2f} s" if saved > 0
                     else f"{-100 * saved:.1f} % slower than conventional {conventional:.2f} s")
        cls = "ok" if saved > 0 else "warn"
    bound = (section or {}).get("lower_bound_s")
    if bound:
        notes.append(f"{cycle / bound:.2f} x the lower bound {bound:.2f} s")
    whole = report.get("cycle_time_s")
    if section is not None and whole is not None and abs(whole - cycle) > 5e-3:
        notes.append(f"whole job {whole:.2f} s on feedback")
    if report.get("planned_time_s") is not None:
        notes.append(f"planned {report['planned_time_s']:.2f} s")
    return "Cycle time", f"{cycle:.2f} s", "; ".join(notes), cls


def _following_card(errors: dict) -> tuple[str, str, str, str]:
    if not errors:
        return "Following error", "n/a", "no feedback recorded", "info"
    linear = {k: v for k, v in errors.items() if k not in ROTARY}
    worst = max(linear.values(), default=0.0) * 1e3
    detail = ", ".join(f"{k} {v * 1e3:.4f} {'mrad' if k in ROTARY else 'mm'}" for k, v in errors.items())
    return "Following error (max)", f"{worst:.3f} mm", detail, "info"


def tables(report: dict) -> list[tuple[str, list[str], list[list]]]:
    """(heading, column names, rows) per table of the page: following error, holes, thread passes."""
    out = []
    errors = report.get("max_following_error") or {}
    if errors:
        rows = [[k, f"{v * 1e3:.4f}", "mrad" if k in ROTARY else "mm"] for k, v in errors.items()]
        out.append(("Following error per axis", ["axis", "max |command - feedback|", "unit"], rows))
    holes = (report.get("drill") or {}).get("holes") or []
    if holes:
        rows = [[h.get("index"), _f(h.get("x_mm"), 3), _f(h.get("y_mm"), 3), h.get("mode"), _f(h.get("depth_mm"), 4),
                 _f(h.get("overlap_down_s"), 3), _f(h.get("overlap_up_s"), 3), _f(h.get("cycle_time_s"), 3)]
                for h in holes]
        out.append(("Holes", ["hole", "X mm", "Y mm", "retract mode", "depth mm", "overlap down s", "overlap up s",
                              "time s"], rows))
    passes = (report.get("thread") or {}).get("passes") or []
    if passes:
        rows = [[p.get("index"), _f(p.get("depth_mm"), 3), _f(p.get("doc_mm"), 3), _f(p.get("max_chip_revs"), 2),
                 _f(100 * p["aircut_share"] if p.get("aircut_share") is not None else None, 1),
                 _f(p.get("vibration_per_rev"), 2), _f(p.get("vibration_phase_deg"), 1),
                 _f(p.get("vibration_amplitude_mm"), 3)] for p in passes]
        out.append(("Thread passes", ["pass", "depth mm", "depth of cut mm", "longest chip rev", "air-cut %",
                                      "vibration /rev", "phase deg", "amplitude mm"], rows))
    return out


def _figure(path: Path) -> dict:
    """One plot for the page: its PNG inlined as base64, so the page needs no other file."""
    return {"stem": path.stem, "name": path.name, "data": base64.b64encode(path.read_bytes()).decode("ascii"),
            "caption": CAPTIONS.get(path.stem, path.stem.replace("_", " ").capitalize() + ".")}


def _state_class(state: str) -> str:
    return {"succeeded": "ok", "rejected": "bad", "aborted": "bad", "canceled": "warn"}.get(state, "info")


def _mm(value) -> str:
    return "n/a" if value is None else f"{value:.4f} mm"


def _f(value, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"

