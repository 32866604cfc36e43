"""Polar words ``@`` (distance) and ``^`` (angle, degrees) in the XY plane, as LinuxCNC 2.9
reads them: about the program origin; under G90 each word is the new distance or angle (a
missing one keeps the current point's), under G91 each is added to the current point's. They
cannot share a line with X or Y; only G17 has them."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .lexer import Block, GcodeError

if TYPE_CHECKING:
    from .modal import Modal

POLAR = ("@", "^")


def has_polar(b: Block) -> bool:
    return any(k in b.words for k in POLAR)


def polar_xy(s: "Modal", b: Block, used: set[str]) -> tuple[float, float]:
    """The point (mm) a line's @ and ^ name from the current one."""
    word = next(k for k in POLAR if k in b.words)
    if "X" in b.words or "Y" in b.words:
        raise GcodeError(b.line, word, "polar words cannot share a line with X or Y")
    if s.plane != 17.0:
        raise GcodeError(b.line, word, "polar coordinates lie in the XY plane (G17)")
    if "x" not in s.position or "y" not in s.position:
        raise GcodeError(b.line, word, "the current X/Y is unknown here: move X and Y first", True)
    used.update(k for k in POLAR if k in b.words)
    x, y = s.position["x"], s.position["y"]
    r0, a0 = math.hypot(x, y), math.degrees(math.atan2(y, x))
    r = s.length(b.words["@"]) if "@" in b.words else (0.0 if s.incremental else r0)
    a = b.words.get("^", 0.0 if s.incremental else a0)
    if s.incremental:
        r, a = r0 + r, a0 + a
    return r * math.cos(math.radians(a)), r * math.sin(math.radians(a))
