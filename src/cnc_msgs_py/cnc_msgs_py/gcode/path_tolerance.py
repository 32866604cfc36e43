"""G64 P<tolerance>: feed moves run on without stopping, the tip within P of the programmed path.

LinuxCNC blends consecutive feed moves under G64, keeping within P of the programmed path
where P is given; G61 (and G61.1) stop exactly at every point. Our moves stop at every
point, which is G61. Our [path](../../../../docs/path.md) method runs a polyline at its feed
without stopping where the drives can turn the corner, and keeps the tip within its
``chord_tolerance`` on the drive model's feedback: G64 P is that tolerance. So under G64 P
consecutive G1/G2/G3 feed moves at one feed (arcs as their chords) are one path operation
whose points are the moves' ends. A feed move that the path method cannot take stays a
move, stopping at its end as under G61: one at a surface speed (its feed follows the
changing rpm), a vibrated one, one naming a rotary axis or on a machine without X, Y and Z (a lathe), or
from a position not known yet. G64 without P blends without a bound in LinuxCNC; ours then
stops at every point, as it does without any G64.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .lexer import Block, GcodeError, word_text
from .modal import machine_axes

if TYPE_CHECKING:
    from .translate import Translator

XYZ = ("x", "y", "z")


def set_mode(tr: "Translator", b: Block, used: set[str], code: float) -> None:
    """G61/G61.1 (exact stop), G64 [P] (P: the path tolerance, program units)."""
    s = tr.state
    s.path_tolerance = None
    if code == 64.0 and "P" in b.words:
        used.add("P")
        if b.words["P"] < 0.0:
            raise GcodeError(b.line, word_text("P", b.words["P"]), "a path tolerance must be >= 0")
        s.path_tolerance = s.length(b.words["P"]) or None  # P0: LinuxCNC's unbounded blending, ours stops
    used.update("Q" if "Q" in b.words else "")  # the naive CAM tolerance: collinear points are run through anyway


def add(tr: "Translator", line: int, before: dict[str, float], target: dict[str, float], feed: dict) -> bool:
    """The feed move from ``before`` to ``target`` added to a path operation under G64 P; False
    where it must stay a move (see the module's docstring)."""
    s = tr.state
    tolerance = s.path_tolerance
    if tolerance is None or "feed" not in feed or tr.vibration is not None or s.surface is not None:
        return False
    if set(target) - set(XYZ) or any(a not in before or a not in target for a in XYZ):
        return False
    if not set(XYZ) <= set(machine_axes(tr.ctx.machine)):
        return False
    start = [before[a] for a in XYZ]
    key = (*tr._key(), feed["feed"], tolerance)
    fresh = {"points": [start], "feed": feed["feed"], "chord_tolerance": tolerance}
    block = tr._begin(line, "path", key, fresh)
    if block["points"][-1] != start:  # (the tool got here another way: a path of its own)
        tr._flush()
        block = tr._begin(line, "path", key, fresh)
    block["points"].append([target[a] for a in XYZ])
    return True
