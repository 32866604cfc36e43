"""M70-M73: the modal state saved and restored, as LinuxCNC 2.9 does it.

M70 saves the modal state in the current call's context (the program's, or a
subroutine's), M72 restores what M70 saved there (it can be restored again), M71 forgets
it, and M73 saves it so that the subroutine's endsub or return restores it. What is saved
is what LinuxCNC saves of ours: units, distance and arc distance modes, the plane, the feed
mode and feed, the spindle's speed, surface speed mode and on/off, coolant, the canned
cycle's return level, lathe diameter mode and the work coordinate system. Positions,
tools and offsets' values are not state: they stay as they are.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .lexer import Block, GcodeError
from .offsets import use_system

if TYPE_CHECKING:  # the translator imports this module
    from .translate import Translator

SAVED = ("inch", "incremental", "arc_absolute", "plane", "per_rev", "feed", "speed", "surface", "max_rpm",
         "spindle_on", "mist", "flood", "retract_initial", "diameter", "work_offset")
CODES = (70.0, 71.0, 72.0, 73.0)


def _snapshot(tr: "Translator") -> dict:
    return {name: getattr(tr.state, name) for name in SAVED}


def restore(tr: "Translator", saved: dict) -> None:
    """The state ``saved`` in force again; a work system restored keeps the tool where it is."""
    for name in SAVED[:-1]:
        setattr(tr.state, name, saved[name])
    if saved["work_offset"] != tr.state.work_offset:
        use_system(tr, saved["work_offset"])


def codes(tr: "Translator", b: Block, m: list[float]) -> None:
    """A line's M70-M73, in the context of the call running (the executor's last frame)."""
    frame = tr.executor.frames[-1]
    if 70.0 in m:
        frame.saved = _snapshot(tr)
    elif 71.0 in m:
        if frame.saved is None:
            raise GcodeError(b.line, "M71", "no state saved with M70 here to forget")
        frame.saved = None
    elif 72.0 in m:
        if frame.saved is None:
            raise GcodeError(b.line, "M72", "no state saved with M70 here to restore (or M71 forgot it)")
        restore(tr, frame.saved)
    elif 73.0 in m:
        if len(tr.executor.frames) == 1:
            raise GcodeError(b.line, "M73", "saves the state for a subroutine's return: outside one, use M70")
        frame.autorestore = _snapshot(tr)


def on_return(tr: "Translator"):
    """What the executor calls as a subroutine returns: the state M73 saved, restored."""
    def returning(frame) -> None:
        if frame.autorestore is not None:
            restore(tr, frame.autorestore)
    return returning


