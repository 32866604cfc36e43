"""What a job kind is to the schema: its block of a job document, its cross-field rules, the
keys it has no use for, and what its spindle and tool must be.

``cnc_msgs_py.job`` builds the job schema and its checks from the registered kinds
(``cnc_msgs_py.kinds.KIND_SCHEMAS``) and never switches on a kind's name.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

from ..units import to_mm

MAX_LIST = 100_000  # holes, moves, outline points: beyond this a job is refused
# The smallest feed that makes sense on a machine tool. Smaller positive feeds would plan moves
# lasting years (or not at all: ruckig gives up), so they are refused by name.
MIN_FEED = 1.0  # mm/min

# The vibration keys only a thread uses: every other kind refuses them by name.
THREAD_ONLY_VIBRATION = {
    "vibration.phase_shift": "only a thread shifts the vibration phase from pass to pass",
    "vibration.D_step": "only a thread raises D from pass to pass",
}


@dataclass(frozen=True)
class KindSchema:
    """One job kind's part of the ``cnc_job/1`` schema.

    Attributes:
        name: the kind as a job's ``kind`` names it; its block is the job's key of that name.
        block: the spec of that block (``cnc_msgs_py.schema``), checked field by field.
        check: cross-field rules on the whole job (SI) once every field is valid and the
            common rules hold; it may spell values out for the planner (arcs into chords,
            per-hole planes).
        unused: dotted keys a job of this kind has no use for, with why: given anyway, they
            are refused by name, never ignored.
        check_given: rules on keys the raw document gives that the job's own values leave
            without use (checked last).
        needs_spindle: its jobs need the spindle turning (spindle_rpm > 0).
        lathe_tool: its tool may have diameter 0 (D0 in lathe tool tables).
    """

    name: str
    block: Any
    check: Callable[[SimpleNamespace], None]
    unused: dict[str, str] = field(default_factory=dict)
    check_given: Callable[[dict, SimpleNamespace], None] | None = None
    needs_spindle: bool = False
    lathe_tool: bool = False


def mm_text(value_m: float) -> str:
    """A length (m) as a reason quotes it, in mm."""
    return f"{to_mm(value_m):.4g} mm"
