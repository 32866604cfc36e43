"""The air-cut section on the report page: did the vibrated feeds break their chips."""
from __future__ import annotations

import math

from cnc_planner.kinds.kind import Card


def cards(aircut: dict) -> list[Card]:
    """The section's verdict (each feed's longest chip within its waveform's window,
    vibration.report) as the machinist reads it; nothing to judge without one revolution."""
    revs, broken = aircut.get("revolutions", 0), aircut.get("revolutions_with_aircut", 0)
    chip = aircut.get("max_chip_revs", math.inf)
    passed = aircut["verdict"]["passed"]
    value, cls = ("long chips", "bad") if not passed else ("broken", "ok") if revs > 0 else ("not judged", "info")
    return [("Chip breaking", value,
             f"air-cut in {broken} of {revs} revolutions; longest chip {chip:.2f} rev "
             f"(commanded {aircut.get('commanded', {}).get('max_chip_revs', float('nan')):.2f})",
             cls)]
