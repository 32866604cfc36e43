"""Coordinate systems as LinuxCNC 2.9 keeps them: G54..G59.3, G10 L2/L20, G92/G92.1/G92.2/G92.3,
G52 and G53.

A point's table coordinates (the setup's frame: the machine's on mill3 and lathe) are
``table = R @ (program + g92) + origin``, as LinuxCNC's canon applies G92, then the
system's rotation, then its origin. Our jobs carry exactly that as their ``setup``: an
operation's setup is its system's origin plus the rotated G92 offset, and its rotation, so
the operation's coordinates stay the program's (the ones rs274 prints) and the planner
places them with no change of its own. An offset change ends the open operation (its key
holds the setup) and keeps the tool where it stands: its program position is read again
in the new frame, as LinuxCNC's is.

G54 is the job's ``setup``, G55..G59.3 the machine's var file (``var_file``) and
``program.work_offsets`` over it; a system none of them gives starts at zero, as in a fresh
var file, and selecting one that nothing set is refused for the machine reason.
G10 L2 and L20 (and G92, G52) take absolute values under G91 too, X as a diameter under
G7, as rs274 reads them. The parameters (#5210-#5219 G92, #5221-#5390 the systems, R the
rotation about Z) are in mm, as a LinuxCNC machine configured in mm keeps its var file.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .lexer import Block, GcodeError, word_text
from .parameters import whole

if TYPE_CHECKING:
    from .translate import Translator

SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
AXES = ("x", "y", "z")
G92_ENABLED = 5210
G92_FIRST = 5211  # X; 5211-5219 X Y Z A B C U V W
SYSTEM_FIRST = 5221  # G54's X; each system 20 further on, its R (rotation about Z) at +9
SYSTEM_STRIDE = 20
TOOL_AXIS = {"mill3": 2, "lathe": 0}  # layouts whose linear joints read the table frame: the tool axis
OFFSET_CODES = (10.0, 52.0, 92.0, 92.1, 92.2, 92.3)


def _matrix(deg: list[float]) -> list[list[float]]:
    """The setup's rotation, about X, then Y, then Z (as the planner's kinematics.frame)."""
    (cx, sx), (cy, sy), (cz, sz) = ((math.cos(math.radians(a)), math.sin(math.radians(a))) for a in deg)
    return [[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
            [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
            [-sy, cy * sx, cy * cx]]


def _apply(m: list[list[float]], v: list[float | None]) -> list[float | None]:
    """m @ v, an unknown (None) result where an unknown input has a weight."""
    out: list[float | None] = []
    for row in m:
        if any(w != 0.0 and x is None for w, x in zip(row, v)):
            out.append(None)
        else:
            out.append(sum(w * x for w, x in zip(row, v) if w != 0.0))
    return out


@dataclass
class System:
    """One coordinate system: its origin (mm, table frame) and rotation (deg), and the job's
    own setup while the program has not changed it (the document keeps it as written)."""

    origin: list[float]
    rotation_deg: list[float]
    given: dict | None = None


class Offsets:
    """The coordinate systems and the G92 offset of one program run."""

    def __init__(self, setup: dict, work_offsets: dict[str, dict]) -> None:
        self.systems: dict[str, System] = {}
        for name, spec in (("G54", setup), *work_offsets.items()):
            self.systems[name] = System([float(v) for v in spec.get("origin", [0.0] * 3)],
                                        [float(v) for v in spec.get("rotation_deg", [0.0] * 3)], spec)
        self.g92 = [0.0] * 3  # applied now (mm, program frame)
        self.g92_saved = [0.0] * 3  # #5211-#5213
        self.g92_on = False  # #5210

    def system(self, name: str) -> System:
        return self.systems.get(name) or System([0.0] * 3, [0.0] * 3)

    def setup(self, name: str) -> dict:
        """The setup of an operation in system ``name``: the job's own while nothing changed it."""
        sys = self.system(name)
        if sys.given is not None and not any(self.g92):
            return copy.deepcopy(sys.given)
        shift = _apply(_matrix(sys.rotation_deg), self.g92)
        return {"origin": [o + d for o, d in zip(sys.origin, shift)], "rotation_deg": list(sys.rotation_deg)}

    def key(self, name: str) -> tuple:
        sys = self.system(name)
        return (name, tuple(sys.origin), tuple(sys.rotation_deg), tuple(self.g92))

    def to_table(self, name: str, position: dict[str, float]) -> list[float | None]:
        sys = self.system(name)
        p = [None if a not in position else position[a] + d for a, d in zip(AXES, self.g92)]
        return [None if t is None else t + o for t, o in zip(_apply(_matrix(sys.rotation_deg), p), sys.origin)]

    def to_program(self, name: str, table: list[float | None]) -> dict[str, float]:
        sys = self.system(name)
        back = [list(col) for col in zip(*_matrix(sys.rotation_deg))]  # the transpose
        p = _apply(back, [None if t is None else t - o for t, o in zip(table, sys.origin)])
        return {a: v - d for a, v, d in zip(AXES, p, self.g92) if v is not None}

    def read(self, n: int) -> float:
        """#5210-#5219 and #5221-#5390 (mm, deg)."""
        if n == G92_ENABLED:
            return float(self.g92_on)
        if G92_FIRST <= n < G92_FIRST + 9:
            k = n - G92_FIRST
            return self.g92_saved[k] if k < 3 else 0.0
        k, i = divmod(n - SYSTEM_FIRST, SYSTEM_STRIDE)
        if 0 <= k < len(SYSTEMS) and i <= 9:
            sys = self.system(SYSTEMS[k])
            return sys.origin[i] if i < 3 else sys.rotation_deg[2] if i == 9 else 0.0
        return 0.0


def _keeping_the_tool(tr: "Translator", change) -> None:
    """Apply ``change`` (of the offsets or the system in force) with the tool standing still:
    its program position is read again in the new frame."""
    s = tr.state
    table = tr.offsets.to_table(s.work_offset, s.position)
    change()
    s.position = tr.offsets.to_program(s.work_offset, table)


def use_system(tr: "Translator", name: str) -> None:
    """Work system ``name`` (one the program has) in force, the tool staying where it is."""
    _keeping_the_tool(tr, lambda: setattr(tr.state, "work_offset", name))


def select(tr: "Translator", b: Block, code: float) -> None:
    """G54..G59.3: the system in force, the tool staying where it is."""
    name = word_text("G", code)
    if name not in tr.offsets.systems:
        raise GcodeError(b.line, name, f"machine '{tr.ctx.machine}' keeps no {name} work offset (its var file) and "
                                       "the program neither gives one (program.work_offsets) nor sets it (G10 L2/L20)")
    use_system(tr, name)


def _values(tr: "Translator", b: Block, used: set[str]) -> dict[str, float]:
    """The block's X Y Z words (mm, X a radius under G7), absolute whatever G91 says."""
    s = tr.state
    out = {}
    for a in AXES:
        if a.upper() in b.words:
            used.add(a.upper())
            v = s.length(b.words[a.upper()])
            out[a] = v / 2.0 if a == "x" and s.diameter else v
    return out


def g10(tr: "Translator", b: Block, used: set[str], level: float) -> None:
    """G10 L2 P<n> X Y Z R: system n's origin (and rotation about Z); G10 L20 P<n> X Y Z: its
    origin such that the tool's position reads those values in it. P0 is the system in force."""
    word = f"G10 L{level:g}"
    if "P" not in b.words:
        raise GcodeError(b.line, word, "needs P, the coordinate system (0: the one in force, 1-9: G54-G59.3)")
    used.update("LP")
    try:
        p = whole(b.words["P"], word_text("P", b.words["P"]))
    except ValueError:
        p = -1
    if not 0 <= p <= len(SYSTEMS):
        raise GcodeError(b.line, word_text("P", b.words["P"]), "names no coordinate system (0-9)")
    name = tr.state.work_offset if p == 0 else SYSTEMS[p - 1]
    values = _values(tr, b, used)
    if "R" in b.words and level == 20.0:
        raise GcodeError(b.line, word_text("R", b.words["R"]), "G10 L20 sets no rotation (use G10 L2 R)")
    if "R" in b.words:
        used.add("R")
    offsets = tr.offsets

    def change() -> None:
        old = offsets.system(name)
        sys = System(list(old.origin), list(old.rotation_deg))
        if "R" in b.words:
            sys.rotation_deg[2] = b.words["R"]
        if level == 2.0:
            for k, a in enumerate(AXES):
                sys.origin[k] = values.get(a, sys.origin[k])
        elif values:
            table = offsets.to_table(tr.state.work_offset, tr.state.position)
            reading: dict = {**offsets.to_program(name, table), **values}
            unknown = next((a for a in values if table[AXES.index(a)] is None), None)
            if unknown is not None:
                raise GcodeError(b.line, word, f"the tool's {unknown.upper()} position is unknown here: "
                                               f"move {unknown.upper()} first", True)
            shifted = _apply(_matrix(sys.rotation_deg),
                             [reading[a] + d if a in reading else None for a, d in zip(AXES, offsets.g92)])
            for k, a in enumerate(AXES):
                if table[k] is not None and shifted[k] is not None:
                    sys.origin[k] = table[k] - shifted[k]
                elif a in values:
                    raise GcodeError(b.line, word, "the tool's position is unknown here: move X, Y and Z first", True)
        offsets.systems[name] = sys
    _keeping_the_tool(tr, change)


def g92(tr: "Translator", b: Block, used: set[str], code: float) -> None:
    """G92 X Y Z (the position reads these), G52 X Y Z (the offset itself), G92.1 (cleared,
    #5211-#5219 zeroed), G92.2 (cleared, kept in #5211-#5219), G92.3 (back from them)."""
    offsets, s = tr.offsets, tr.state
    name = word_text("G", code)
    values = _values(tr, b, used) if code in (52.0, 92.0) else {}
    if code == 92.0 and not values:
        raise GcodeError(b.line, name, "needs an axis word: the position it should read")
    if code == 92.0:
        missing = [a for a in values if a not in s.position]
        if missing:
            raise GcodeError(b.line, name, f"the {missing[0].upper()} position is unknown here: move "
                                           f"{missing[0].upper()} first or give program.start", True)

    def change() -> None:
        if code == 92.0:
            offsets.g92 = [s.position[a] + d - values[a] if a in values else d for a, d in zip(AXES, offsets.g92)]
        elif code == 52.0:
            offsets.g92 = [values.get(a, d) for a, d in zip(AXES, offsets.g92)]
        elif code == 92.3:
            offsets.g92 = list(offsets.g92_saved)
        else:
            offsets.g92 = [0.0] * 3
        if code == 92.1:
            offsets.g92_saved = [0.0] * 3
        elif code != 92.2 and code != 92.3:
            offsets.g92_saved = list(offsets.g92)
        offsets.g92_on = code in (52.0, 92.0, 92.3)
    _keeping_the_tool(tr, change)


def _machine_shift(tr: "Translator", line: int, word: str) -> dict[str, float]:
    """Machine less program coordinates, per axis, for ``word``: the system's origin, the G92
    offset and along the tool axis the applied tool length. Only on layouts whose linear
    joints read the table frame, and not under a rotated system."""
    from ..machine import MachineError, load_machine  # read only when a program uses machine coordinates
    try:
        layout = load_machine(tr.ctx.machine).layout
    except MachineError as err:
        raise GcodeError(line, word, str(err)) from None
    if layout not in TOOL_AXIS:
        raise GcodeError(line, word, f"machine {tr.ctx.machine} (layout {layout}) has no fixed frame for "
                                     "machine coordinates: its rotary axes carry the setup")
    sys = tr.offsets.system(tr.state.work_offset)
    if any(sys.rotation_deg):
        raise GcodeError(line, word, "machine coordinates under a rotated coordinate system are not supported")
    return {a: sys.origin[i] + tr.offsets.g92[i] + (tr.applied_length() if i == TOOL_AXIS[layout] else 0.0)
            for i, a in enumerate(AXES)}


def from_machine(tr: "Translator", line: int, word: str, machine: dict[str, float]) -> dict[str, float]:
    """Some axes' machine coordinates (the joints: the table frame plus the applied tool
    length along the tool axis) in program coordinates."""
    shift = _machine_shift(tr, line, word)
    return {a: v - shift[a] for a, v in machine.items()}


def to_machine(tr: "Translator", line: int, word: str) -> dict[str, float]:
    """The known axes of the current position in machine coordinates."""
    shift = _machine_shift(tr, line, word)
    return {a: v + shift[a] for a, v in tr.state.position.items()}


def g53_target(tr: "Translator", b: Block, used: set[str]) -> dict[str, float]:
    """A G53 line's end in program coordinates: its X Y Z are machine coordinates, the others
    stay where they are. Only on layouts whose linear joints read the table frame."""
    s = tr.state
    target = {**s.position, **from_machine(tr, b.line, "G53", _values(tr, b, used))}
    s.position = dict(target)
    return target
