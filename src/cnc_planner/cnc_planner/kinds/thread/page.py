"""The thread section on the report page: chips and depth, and a row per pass."""
from __future__ import annotations

import math

from cnc_msgs_py.units import to_mm

from cnc_analysis.verdict import OVERCUT_LIMIT

from cnc_planner.kinds.kind import Card, Table
from cnc_planner.page_format import fixed, mm


def cards(thread: dict) -> list[Card]:
    """Chips, and the depth as the verdict holds it: within the analyser's full_depth and
    never deeper than OVERCUT_LIMIT."""
    chip = thread.get("max_chip_revs", math.inf)
    over = thread.get("overcut_mm") is not None and thread["overcut_mm"] > to_mm(OVERCUT_LIMIT)
    full = bool(thread.get("full_depth")) and not over
    return [("Chip breaking", "broken" if thread.get("chips_broken") else "long chips",
             f"longest chip {chip:.2f} rev over {thread.get('cutting_passes', '?')} cutting passes",
             "ok" if thread.get("chips_broken") else "warn"),
            ("Thread depth", "full depth" if full else "too deep" if over else "not at depth",
             f"depth error {mm(thread.get('depth_error_mm'))}, overcut {mm(thread.get('overcut_mm'))}, "
             f"helix residual {mm(thread.get('helix_residual_mm'))}; depth of cut "
             f"{'never grows' if thread.get('doc_never_grows') else 'grows between passes'}",
             "ok" if full else "bad")]


def tables(thread: dict) -> list[Table]:
    passes = thread.get("passes") or []
    if not passes:
        return []
    rows = [[p.get("index"), fixed(p.get("depth_mm"), 3), fixed(p.get("doc_mm"), 3), fixed(p.get("max_chip_revs"), 2),
             fixed(100 * p["aircut_share"] if p.get("aircut_share") is not None else None, 1),
             fixed(p.get("vibration_per_rev"), 2), fixed(p.get("vibration_phase_deg"), 1),
             fixed(p.get("vibration_amplitude_mm"), 3)] for p in passes]
    return [("Thread passes", ["pass", "depth mm", "depth of cut mm", "longest chip rev", "air-cut %",
                               "vibration /rev", "phase deg", "amplitude mm"], rows)]
