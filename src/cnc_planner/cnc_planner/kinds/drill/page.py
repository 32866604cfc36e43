"""The drill section on the report page: safety on feedback, and a row per hole."""
from __future__ import annotations

from cnc_planner.kinds.kind import Card, Table
from cnc_planner.page_format import fixed


def cards(drill: dict) -> list[Card]:
    n = drill.get("safety_violations", 0)
    return [("Safety", "safe" if n == 0 else f"{n} violations",
             f"X/Y moved while the tip was below R: {n} times, on feedback, over "
             f"{len(drill.get('holes', []))} holes", "ok" if n == 0 else "bad")]


def tables(drill: dict) -> list[Table]:
    holes = drill.get("holes") or []
    if not holes:
        return []
    rows = [[h.get("index"), fixed(h.get("x_mm"), 3), fixed(h.get("y_mm"), 3), h.get("mode"),
             fixed(h.get("depth_mm"), 4), fixed(h.get("overlap_down_s"), 3), fixed(h.get("overlap_up_s"), 3),
             fixed(h.get("cycle_time_s"), 3)] for h in holes]
    return [("Holes", ["hole", "X mm", "Y mm", "retract mode", "depth mm", "overlap down s", "overlap up s",
                       "time s"], rows)]
