"""Modal groups and the interpreter's modal state (LinuxCNC 2.9 meaning).

Two words of one modal group in one line are a conflict and refused; a G or M code this
front end does not implement is refused with why, never ignored.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .lexer import Block, GcodeError, word_text

ROUGHING_CYCLES = (71.0, 71.1, 71.2, 72.0, 72.1, 72.2)  # G71/G72 and their .1/.2 variants (gcode/lathe.py)
MOTION = {0.0, 1.0, 2.0, 3.0, 5.1, 33.0, 33.1, 70.0, *ROUGHING_CYCLES, 73.0, 76.0, 80.0, 81.0, 82.0, 83.0}
DRILL_CYCLES = {73.0, 81.0, 82.0, 83.0}
# A cycle, a locked move or a feed per revolution with the spindle stopped is the program's
# refusal; a program written for a simulator never starts it, as an operator's MDI did first.
START_SPINDLE = "give S and M3 before it, or start it ahead (program.start.spindle_rpm, --spindle RPM)"
G_GROUPS: dict[float, str] = {
    **{g: "motion" for g in MOTION},
    4.0: "non-modal", 10.0: "non-modal", 52.0: "non-modal", 53.0: "non-modal",
    28.0: "non-modal", 28.1: "non-modal", 30.0: "non-modal", 30.1: "non-modal",
    92.0: "non-modal", 92.1: "non-modal", 92.2: "non-modal", 92.3: "non-modal",
    17.0: "plane", 18.0: "plane", 19.0: "plane",
    7.0: "lathe diameter", 8.0: "lathe diameter",
    20.0: "units", 21.0: "units",
    40.0: "cutter compensation", 41.0: "cutter compensation", 42.0: "cutter compensation",
    41.1: "cutter compensation", 42.1: "cutter compensation",
    43.0: "tool length", 49.0: "tool length",
    54.0: "work offset", 55.0: "work offset", 56.0: "work offset", 57.0: "work offset", 58.0: "work offset",
    59.0: "work offset", 59.1: "work offset", 59.2: "work offset", 59.3: "work offset",
    61.0: "path control", 61.1: "path control", 64.0: "path control",
    90.0: "distance", 91.0: "distance",
    90.1: "arc distance", 91.1: "arc distance",
    94.0: "feed mode", 95.0: "feed mode",
    96.0: "spindle speed mode", 97.0: "spindle speed mode",
    98.0: "canned cycle return", 99.0: "canned cycle return",
}
G_REFUSED: dict[float, str] = {
    84.0: "tapping is not a cycle of ours: G33.1 taps rigidly, one hole at a time",
    93.0: "inverse time feed is not supported",
}
# probing moves stop on a probe's signal: our machine descriptions (and the bridge's drives)
# have no probe input, so they are the machine's to refuse
PROBING = (38.2, 38.3, 38.4, 38.5)
# digital and analog I/O (M62-M65 outputs, M66 wait on an input, M67/M68 analog outputs): likewise
IO = (62.0, 63.0, 64.0, 65.0, 66.0, 67.0, 68.0)
M_GROUPS: dict[float, str] = {0.0: "stop", 1.0: "stop", 2.0: "stop", 30.0: "stop",
                              3.0: "spindle", 4.0: "spindle", 5.0: "spindle",
                              6.0: "tool change", 61.0: "tool change", 7.0: "mist", 8.0: "flood", 9.0: "coolant",
                              **{code: "modal state" for code in (70.0, 71.0, 72.0, 73.0)}}
M_REFUSED: dict[float, str] = {
    4.0: "our operations turn the spindle forward (M3)",
}


def check_groups(block: Block, machine: str = "") -> None:
    """Refuse unknown codes, two codes of one modal group in a line, and axis words beside
    X, Y and Z: for a machine reason where ``machine`` lacks that axis."""
    seen: dict[str, float] = {}
    for letter, codes, groups, refused in (("G", block.g, G_GROUPS, G_REFUSED), ("M", block.m, M_GROUPS, M_REFUSED)):
        for code in codes:
            code = round(code, 1)
            word = word_text(letter, code)
            if code in refused:
                raise GcodeError(block.line, word, refused[code])
            if letter == "G" and code in PROBING:
                raise GcodeError(block.line, word, f"machine '{machine}' has no probe input to stop a probing move"
                                 if machine else "probing needs a machine with a probe input")
            if letter == "M" and code in IO:
                raise GcodeError(block.line, word, f"machine '{machine}' has no digital or analog I/O"
                                 if machine else "I/O needs a machine with inputs and outputs")
            group = groups.get(code)
            if group is None:
                raise GcodeError(block.line, word, "not supported by this front end")
            key = f"{letter} {group}"
            if key in seen:
                raise GcodeError(block.line, word, f"conflicts with {word_text(letter, seen[key])} "
                                                   f"in the same line (both {group})")
            seen[key] = code
    if any(k in block.words for k in "ABCUVW"):
        letter = next(k for k in "ABCUVW" if k in block.words)
        axes = machine_axes(machine)
        why = (f"machine '{machine}' has no {letter} axis (its axes: {', '.join(a.upper() for a in axes)})"
               if axes and letter.lower() not in axes else "only X, Y and Z axis words are supported")
        raise GcodeError(block.line, word_text(letter, block.words[letter]), why)


def machine_axes(machine: str) -> tuple[str, ...]:
    """The named machine's axes (lower case, its joint names but the spindle); () if unknown."""
    from cnc_msgs_py.machine import SPINDLE, MachineError, load_machine

    try:
        return tuple(j for j in load_machine(machine).joint_names if j != SPINDLE) if machine else ()
    except MachineError:
        return ()


@dataclass
class Modal:
    """What stays in force from line to line; lengths in mm, program coordinates."""

    inch: bool = False  # G20
    incremental: bool = False  # G91
    arc_absolute: bool = False  # G90.1
    plane: float = 17.0
    diameter: bool = False  # G7: X words are diameters
    per_rev: bool = False  # G95
    motion: float | None = None
    retract_initial: bool = False  # G98
    path_tolerance: float | None = None  # G64 P: feed moves run on within it (gcode.path_tolerance)
    feed: float | None = None  # as written, in the program's units per min or per rev
    speed: float = 0.0  # S as written: rpm, or under G96 the surface speed
    surface: float | None = None  # G96 in force: the surface speed, m/min (gcode.surface_speed)
    max_rpm: float | None = None  # G96's D: the rpm cap (None: the spindle's limit)
    spindle_on: bool = False
    tool: int = 0  # in the spindle (M6)
    next_tool: int | None = None  # T
    length_offset: bool = False  # G43
    length_tool: int = 0  # whose length G43 applies (H, else the tool in the spindle)
    mist: bool = False  # M7
    flood: bool = False  # M8
    work_offset: str = "G54"
    position: dict[str, float] = field(default_factory=dict)  # known axes, mm, program coordinates

    def length(self, value: float) -> float:
        """A length word in mm."""
        return value * 25.4 if self.inch else value
