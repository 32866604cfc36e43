"""G33: a straight move locked to the spindle's angle, K along its path per revolution;
G33.1: a rigid tap along Z, K per revolution, the spindle reversed at the bottom.

Our ``sync`` move (``cnc_msgs_py.kinds.sync``) is LinuxCNC's G33: consecutive G33 moves are
one pass that waits for the spindle's index and then runs on locked to the spindle, so that
the passes of a thread cut by hand (LinuxCNC's threading.ngc) land in one groove. K is the
distance along the move per revolution, as LinuxCNC's trajectory planner advances its path
(threading.ngc exits at 45 degrees with K = sqrt(2) * pitch: one pitch of Z per revolution).
G33.1 Z K is our ``tap`` move: from where the tool stands to Z and back, the tool where it
started afterwards (rs274's RIGID_TAP).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .lexer import Block, GcodeError, word_text

if TYPE_CHECKING:
    from .translate import Translator

CODES = (33.0, 33.1)


def locked(tr: "Translator", b: Block, used: set[str]) -> None:
    """A G33 or G33.1 line (or axis words while it is in force) into a ``sync`` or ``tap``
    move of the open move operation: from where the tool is (it must be known), at K per
    revolution of a spindle turning forward at one rpm."""
    s = tr.state
    name = word_text("G", s.motion)
    if "K" not in b.words:
        raise GcodeError(b.line, name, "needs K, the distance per spindle revolution")
    used.add("K")
    lead = s.length(b.words["K"])
    if lead <= 0.0:
        raise GcodeError(b.line, word_text("K", b.words["K"]), "the distance per revolution must be > 0")
    if tr.comp.on:
        raise GcodeError(b.line, name, "a spindle-synchronised move with cutter compensation on (G41/G42): "
                                       "give G40 first")
    if tr.vibration is not None:
        raise GcodeError(b.line, name, "a move locked to the spindle is not vibrated: (CNC,VIBRATION OFF) before it")
    if s.surface is not None:
        raise GcodeError(b.line, name, "a move locked to the spindle turns at one rpm: G97 S.. before it, not G96")
    tr._need_spindle(b.line, name)
    if s.motion == CODES[1] and "I" in b.words:
        raise GcodeError(b.line, word_text("I", b.words["I"]), "a faster retract is not supported: the tap comes "
                                                              "out at the speed it went in")
    before = dict(s.position)
    target = tr._target(b, used)
    if any(axis not in before for axis in target):
        raise GcodeError(b.line, name, "starts where the tool is, which is unknown here: move the axes first", True)
    if target == before:
        raise GcodeError(b.line, name, "moves nowhere: a spindle-synchronised move needs a length")
    if s.motion == CODES[0]:
        tr._move(b.line, {"sync": target, "lead": lead})
        return
    moved = next((a for a in target if a != "z" and target[a] != before[a]), None)
    if moved is not None:
        raise GcodeError(b.line, name, f"a rigid tap runs along Z: move {moved.upper()} before it")
    s.position = before  # the tap ends where it started, as LinuxCNC's does
    tr._move(b.line, {"tap": {"z": target["z"]}, "lead": lead})


def as_sync(doc: dict) -> None:
    """A move operation with G33 or G33.1 moves in it becomes a sync operation (the same moves under
    the sync kind's key): the kind that plans and judges passes locked to the spindle."""
    if any(m.get("sync") is not None or m.get("tap") is not None for m in doc.get("move", ())):
        doc["kind"], doc["sync"] = "sync", doc.pop("move")
