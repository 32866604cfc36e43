"""DIR/report.html: one self-contained page a machinist reads at a glance.

The page holds the job summary, a verdict per question a machinist asks (did it finish,
did the feedback pass every section's verdict, was it safe, did the chips break, is there
stock left or a gouge, how long did it take against the conventional cycle and the lower
bound, how well did the axes follow, did they follow as the description predicts, were
setpoints lost), the per-hole / per-pass tables, and every plot with a caption. Plots are
embedded as base64 data URIs and the CSS is inline: no network, no JavaScript, so the file
can be mailed or opened from a bag archive as it is. This module works out what the page
says; templates/report.html.j2 (jinja2, every value escaped) lays it out.
"""
from __future__ import annotations

import base64
from pathlib import Path

from jinja2 import Environment, PackageLoader

from cnc_planner.kinds import KINDS
from cnc_planner.kinds.kind import Card, ReportSection, Table
from cnc_planner.vibration import page as aircut_page
from cnc_planner.vibration.figures import CAPTIONS as AIRCUT_CAPTIONS

ROTARY = ("spindle", "a", "b", "c")  # joints in rad on the topics (shown in mrad)
PAGES = Environment(loader=PackageLoader("cnc_planner"), autoescape=True, trim_blocks=True, lstrip_blocks=True,
                    keep_trailing_newline=True)
CAPTIONS = {  # figure file stem -> caption: every job's figure, the air-cut figures and each kind's own
    "following_error": "Command vs feedback per axis, and the following error (command - feedback) over the job.",
    **AIRCUT_CAPTIONS,
    **{stem: text for kind in KINDS.values() if kind.figures for stem, text in kind.figures.captions.items()},
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


FOLD_ROWS = 20  # a longer table (a plate's 300 holes) shows its first SHOWN_ROWS rows, the rest folded
SHOWN_ROWS = 10


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
        reason=report.get("reason"), cards=verdicts(report), tables=tables(report), figures=figures,
        fold_rows=FOLD_ROWS, shown_rows=SHOWN_ROWS)


def _sections(report: dict) -> list[tuple[ReportSection, dict]]:
    """The kinds' sections present in the report, with what they hold."""
    return [(kind.report, report[kind.report.key]) for kind in KINDS.values()
            if kind.report is not None and isinstance(report.get(kind.report.key), dict)]


def verdicts(report: dict) -> list[Card]:
    """(title, value, detail, class) per verdict card; class is ok | bad | warn | info."""
    cards = []
    state = report.get("state", "unknown")
    cards.append(("Job", state, report.get("reason") or _job_detail(report), _state_class(state)))
    if state == "rejected":
        return cards
    judged = {key: found["verdict"] for key, found in report.items()
              if isinstance(found, dict) and isinstance(found.get("verdict"), dict)}
    if judged:
        cards.append(_verdict_card(judged))
    if report.get("aircut") is not None:
        cards += aircut_page.cards(report["aircut"])
    for section, found in _sections(report):
        if section.cards is not None:
            cards += section.cards(found)
    cards.append(_cycle_card(report))
    cards.append(_following_card(report.get("max_following_error") or {}))
    if report.get("drives"):
        cards.append(_drives_card(report["drives"], report.get("plant")))
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


def _cycle_card(report: dict) -> Card:
    section = next((found for section, found in _sections(report) if section.times_cycle and "cycle_time_s" in found),
                   None)
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


def _verdict_card(judged: dict[str, dict]) -> Card:
    """Every section's verdict at once: the run fails (cnc-run exits 4) if any does."""
    failed = [key for key, verdict in judged.items() if not verdict.get("passed")]
    detail = "; ".join(f"{key}: {verdict.get('says', '')}" for key, verdict in judged.items()
                       if not failed or key in failed)
    return ("Verdict on feedback", f"failed: {', '.join(failed)}" if failed else "passed", detail,
            "bad" if failed else "ok")


def _drives_card(drives: dict, plant: str | None) -> Card:
    """The feedback against the description's prediction: advice, never a failed run."""
    differs = drives["differs"]
    value = "as described" if not differs else f"{', '.join(differs)} differ{'s' if len(differs) == 1 else ''}"
    detail = (f"plant {plant}; " if plant else "") + drives["says"]
    return "Drives vs description", value, detail, "warn" if differs else "ok"


def _following_card(errors: dict) -> Card:
    if not errors:
        return "Following error", "n/a", "no feedback recorded", "info"
    linear = {k: v for k, v in errors.items() if k not in ROTARY}
    worst = max(linear.values(), default=0.0) * 1e3
    detail = ", ".join(f"{k} {v * 1e3:.4f} {'mrad' if k in ROTARY else 'mm'}" for k, v in errors.items())
    return "Following error (max)", f"{worst:.3f} mm", detail, "info"


def tables(report: dict) -> list[Table]:
    """(heading, column names, rows) per table of the page: following error, then the kind's (holes, passes)."""
    out = []
    errors = report.get("max_following_error") or {}
    if errors:
        rows = [[k, f"{v * 1e3:.4f}", "mrad" if k in ROTARY else "mm"] for k, v in errors.items()]
        out.append(("Following error per axis", ["axis", "max |command - feedback|", "unit"], rows))
    drives = (report.get("drives") or {}).get("axes") or {}
    if drives:
        rows = [[k, f"{a['max_residual']:.4f}", f"{a['rms_residual']:.4f}", f"{a['max_following_error']:.4f}",
                 f"{a['predicted_max_following_error']:.4f}", a["unit"]] for k, a in drives.items()]
        out.append(("Feedback against the description's prediction",
                    ["axis", "max residual", "RMS residual", "following error recorded", "following error predicted",
                     "unit"], rows))
    for section, found in _sections(report):
        if section.tables is not None:
            out += section.tables(found)
    return out


def _figure(path: Path) -> dict:
    """One plot for the page: its PNG inlined as base64, so the page needs no other file."""
    return {"stem": path.stem, "name": path.name, "data": base64.b64encode(path.read_bytes()).decode("ascii"),
            "caption": CAPTIONS.get(path.stem, path.stem.replace("_", " ").capitalize() + ".")}


def _state_class(state: str) -> str:
    return {"succeeded": "ok", "rejected": "bad", "aborted": "bad", "canceled": "warn"}.get(state, "info")
