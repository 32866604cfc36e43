"""G33: a straight move locked to the spindle's angle, K along its path per revolution.

Our ``sync`` move (``cnc_msgs_py.kinds.sync``) is LinuxCNC's G33: consecutive G33 moves are
one pass that waits for the spindle's index and then runs on locked to the spindle, so that
the passes of a thread cut by hand (LinuxCNC's threading.ngc) land in one groove. K is the
distance along the move per revolution, as LinuxCNC's trajectory planner advances its path
(threading.ngc exits at 45 degrees with K = sqrt(2) * pitch: one pitch of Z per revolution).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .lexer import Block, GcodeError, word_text

if TYPE_CHECKING:
    from .translate import Translator

CODE = 33.0


def g33(tr: "Translator", b: Block, used: set[str]) -> None:
    """A G33 line (or axis words while G33 is in force) into a ``sync`` move of the open
    move operation: from where the tool is (it must be known), at K per revolution of a
    spindle turning forward at one rpm."""
    s = tr.state
    if "K" not in b.words:
        raise GcodeError(b.line, "G33", "needs K, the distance per spindle revolution")
    used.add("K")
    lead = s.length(b.words["K"])
    if lead <= 0.0:
        raise GcodeError(b.line, word_text("K", b.words["K"]), "the distance per revolution must be > 0")
    if tr.comp.on:
        raise GcodeError(b.line, "G33", "a spindle-synchronised move with cutter compensation on (G41/G42): "
                                        "give G40 first")
    if tr.vibration is not None:
        raise GcodeError(b.line, "G33", "a move locked to the spindle is not vibrated: (CNC,VIBRATION OFF) before it")
    if s.surface is not None:
        raise GcodeError(b.line, "G33", "a move locked to the spindle turns at one rpm: G97 S.. before it, not G96")
    if not (s.spindle_on and s.speed > 0.0):
        raise GcodeError(b.line, "G33", "the spindle is off: give S and M3 before a move locked to it")
    before = dict(s.position)
    target = tr._target(b, used)
    if any(axis not in before for axis in target):
        raise GcodeError(b.line, "G33", "starts where the tool is, which is unknown here: move the axes first", True)
    if target == before:
        raise GcodeError(b.line, "G33", "moves nowhere: a spindle-synchronised move needs a length")
    tr._move(b.line, {"sync": target, "lead": lead})


def as_sync(doc: dict) -> None:
    """A move operation with G33 moves in it becomes a sync operation (the same moves under
    the sync kind's key): the kind that plans and judges passes locked to the spindle."""
    if any(m.get("sync") is not None for m in doc.get("move", ())):
        doc["kind"], doc["sync"] = "sync", doc.pop("move")
