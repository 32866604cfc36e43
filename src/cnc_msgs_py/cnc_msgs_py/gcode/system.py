"""The read-only parameters a program reads from the interpreter's state, as LinuxCNC 2.9
documents them: ``#<_x>``, ``#<_metric>``, ``#<_motion_mode>`` ..., ``#5220``, ``#5400``-``#5413``
and ``#5420``-``#5428``. Lengths are in the program's units (inches under G20), positions in
program coordinates (X a radius, as LinuxCNC keeps it internally); axes the front end has
no word for (A B C U V W) read 0, as they do on a machine without them.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .expressions import ExprError
from .offsets import SYSTEMS
from .parameters import HOMES, OFFSETS

if TYPE_CHECKING:
    from .translate import Translator

POSITION_AXES = "xyzabcuvw"


def _position(tr: "Translator", axis: str, word: str) -> float:
    if axis not in "xyz":
        return 0.0
    s = tr.state
    if axis not in s.position:
        raise ExprError(word, f"the {axis.upper()} position is unknown here (move {axis.upper()} first "
                              "or give program.start)", True)
    value = s.position[axis]
    return value / 25.4 if s.inch else value


def named(tr: "Translator", name: str) -> float:
    """The value of system parameter ``#<name>`` (a name of parameters.SYSTEM_NAMES)."""
    s = tr.state
    word = f"#<{name}>"
    if len(name) == 2 and name[1] in POSITION_AXES:
        return _position(tr, name[1], word)
    selected = -1.0 if s.next_tool is None else float(s.next_tool)
    values = {
        "_vmajor": 2.0, "_vminor": 9.0, "_line": float(tr.line),
        "_motion_mode": 800.0 if s.motion is None else s.motion * 10.0,
        "_plane": s.plane * 10.0, "_ccomp": 400.0,
        "_metric": float(not s.inch), "_imperial": float(s.inch),
        "_absolute": float(not s.incremental), "_incremental": float(s.incremental),
        "_inverse_time": 0.0, "_units_per_minute": float(not s.per_rev), "_units_per_rev": float(s.per_rev),
        "_coord_system": float(s.work_offset[1:].replace(".", "")) * (1.0 if "." in s.work_offset else 10.0),
        "_tool_offset": float(s.length_offset), "_retract_r_plane": float(not s.retract_initial),
        "_retract_old_z": float(s.retract_initial), "_spindle_rpm_mode": 1.0, "_spindle_css_mode": 0.0,
        "_ijk_absolute_mode": float(s.arc_absolute), "_lathe_diameter_mode": float(s.diameter),
        "_lathe_radius_mode": float(not s.diameter), "_spindle_on": float(s.spindle_on),
        "_spindle_cw": float(s.spindle_on), "_mist": float(s.mist), "_flood": float(s.flood),
        "_speed_override": 1.0, "_feed_override": 1.0, "_adaptive_feed": 0.0, "_feed_hold": 0.0,
        "_feed": s.feed or 0.0, "_rpm": s.speed, "_current_tool": float(s.tool), "_current_pocket": float(s.tool),
        "_selected_tool": selected, "_selected_pocket": selected, "_call_level": float(tr.params.level),
        "_remap_level": 0.0, "_task": 1.0,
    }
    return values[name]


def numbered(tr: "Translator", n: int) -> float:
    """#5161-#5189 (G28 and G30, homes.Homes.read), #5210-#5390 (G92 and the coordinate
    systems, offsets.Offsets.read), #5220 and #5400 and up: the system in force, the tool,
    the position."""
    s = tr.state
    tool = tr.tool_entry(s.tool)
    scale = 1.0 / 25.4 if s.inch else 1.0
    if n == 5220:
        return float(SYSTEMS.index(s.work_offset) + 1)
    if n in OFFSETS:
        return tr.offsets.read(n)
    if n in HOMES:
        return tr.homes.read(n)
    if n == 5400:
        return float(s.tool)
    if n == 5403:
        return tr.applied_length() * scale
    if 5401 <= n <= 5409:
        return 0.0
    if n == 5410:
        return (tool.get("diameter") or 0.0) * scale
    if 5411 <= n <= 5413:
        return 0.0
    if 5420 <= n <= 5428:
        return _position(tr, POSITION_AXES[n - 5420], f"#{n}")
    raise ExprError(f"#{n}", "is not a parameter this front end provides (LinuxCNC's #5414-#5419, #5429 and up)")
