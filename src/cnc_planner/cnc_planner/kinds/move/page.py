"""The surface speed card on the report page, of a move job's surface_speed section and of a
turn section's (cnc_planner.kinds.turn.page)."""
from __future__ import annotations

from cnc_analysis.surface_speed import CAP_MARGIN, TOLERANCE

from cnc_planner.kinds.kind import Card


def surface_speed_cards(css: dict | None) -> list[Card]:
    """The surface speed held while cutting, on feedback (cnc_analysis.surface_speed)."""
    if css is None:
        return []
    off = css.get("max_deviation_pct")
    held = off is None or off <= 100.0 * TOLERANCE
    within_cap = css["max_rpm"] <= css["cap_rpm"] * (1.0 + CAP_MARGIN)
    return [("Surface speed", "no cut" if not css["cutting_s"] else
             f"{off:.2f} % off" if off is not None else "all at the cap",
             f"{css['requested_m_min']:g} m/min over {css['held_s']:.1f} s of cutting, {css['capped_s']:.1f} s at "
             f"the {css['cap_rpm']:g} rpm cap; at most {css['max_rpm']:g} rpm", "ok" if held and within_cap else "bad")]
