"""The turn section on the report page: gouges and stock left on feedback, the air moves and,
at a constant surface speed, how well the feedback held it."""
from __future__ import annotations

from cnc_analysis.verdict import OVERCUT_LIMIT
from cnc_msgs_py.units import to_mm

from cnc_planner.kinds.kind import Card
from cnc_planner.kinds.move.page import surface_speed_cards
from cnc_planner.page_format import mm


def cards(turn: dict) -> list[Card]:
    """The section's verdict (a gouge into the part, kinds.turn.report), its air moves and its
    surface speed if it has one."""
    gouge = turn.get("max_gouge_part_mm", 0.0)
    left = turn.get("stock_left_mm")
    passed = gouge <= to_mm(OVERCUT_LIMIT)
    value = "no gouge" if passed else f"gouge {gouge:.3f} mm"
    detail = (f"into the part {mm(gouge)} on feedback, into the allowance {mm(turn.get('max_gouge_mm'))}, "
              f"commanded {mm(turn.get('max_gouge_commanded_mm'))}")
    if left is not None:
        detail = f"stock left {mm(left)}; " + detail
    return [("Stock left / gouge", value, detail, "ok" if passed else "bad"),
            ("Air moves", f"{turn.get('air_feed_mm', 0):.1f} mm",
             f"air cut at feed, vs {turn.get('naive_air_feed_mm', 0):.1f} mm for passes started at the "
             f"virtual cylinder; path {turn.get('path_mm', 0):.0f} mm vs {turn.get('naive_path_mm', 0):.0f} mm "
             f"in {turn.get('passes', '?')} passes", "info")] + surface_speed_cards(turn.get("surface_speed"))

