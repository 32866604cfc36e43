"""The air-cut section on the report page: did the vibrated feeds break their chips."""
from __future__ import annotations

import math

from cnc_analysis.aircut import CHIP_LIMIT_REVS

from cnc_planner.kinds.kind import Card


def cards(aircut: dict) -> list[Card]:
    revs, broken = aircut.get("revolutions", 0), aircut.get("revolutions_with_aircut", 0)
    chip = aircut.get("max_chip_revs", math.inf)
    good = revs > 0 and broken == revs and chip <= CHIP_LIMIT_REVS
    return [("Chip breaking", "broken" if good else "long chips",
             f"air-cut in {broken} of {revs} revolutions; longest chip {chip:.2f} rev "
             f"(commanded {aircut.get('commanded', {}).get('max_chip_revs', float('nan')):.2f})",
             "ok" if good else "bad")]
