"""The path section on the report page: the tip on feedback against the chord tolerance."""
from __future__ import annotations

from cnc_planner.kinds.kind import Card
from cnc_planner.page_format import mm


def cards(path: dict) -> list[Card]:
    within = bool(path.get("within_tolerance"))
    value = "within tolerance" if within else ("not completed" if not path.get("completed") else "beyond tolerance")
    return [("Tool tip on the path", value,
             f"tip on feedback {mm(path.get('max_tip_deviation_mm'))} from the programmed lines, chord tolerance "
             f"{mm(path.get('chord_tolerance_mm'))}; commanded {mm(path.get('commanded_max_tip_deviation_mm'))}, "
             f"command to feedback {mm(path.get('servo_lag_mm'))}",
             "ok" if within else "bad")]
