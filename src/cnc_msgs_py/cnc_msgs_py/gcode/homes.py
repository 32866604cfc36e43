"""G28/G30 (rapid home through an optional point) and G28.1/G30.1 (store the home), as
LinuxCNC 2.9 reads them.

- ``G28 [X Y Z]``: a rapid to the point the axis words name, in program coordinates (G90 or
  G91 as any move; without axis words it is where the tool stands), then a rapid of the
  named axes (every axis of the machine when none is named) to the stored position:
  #5161-#5163 (G30: #5181-#5183), machine coordinates, as G53 reads them
  (``offsets.from_machine``: the table frame plus the applied tool length). The motion mode
  in force stays.
- ``G28.1`` / ``G30.1``: the current position, in machine coordinates, into those
  parameters. The line's axis words are the motion mode's, moved after the store, as
  LinuxCNC does.
- The stored positions start at the machine description's ``home`` (its power-up
  position), in mm: a job has no var file to keep LinuxCNC's between runs. A fresh LinuxCNC
  var file reads 0, machine zero, where a LinuxCNC machine homes to by convention; ours
  stands at ``home`` at power-up, so that is where our G28 goes (machine zero on a
  description without one). It lies inside the machine's travel; the point a program's
  offsets or intermediate point make of it is checked against the travel as any move is.
- Refused, as LinuxCNC refuses them: with cutter compensation on (compensation.check_line),
  beside a motion code (both take the axis words), with polar words; and where machine
  coordinates have no fixed frame or under a rotated system (``offsets``).
  #5164-#5169 and #5184-#5189 (A B C U V W) read 0.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from . import offsets
from .lexer import Block, GcodeError, word_text
from .modal import MOTION, machine_axes
from .polar import has_polar

if TYPE_CHECKING:
    from .translate import Translator

AXES = ("x", "y", "z")
GO = {28.0: 5161, 30.0: 5181}  # the code and its stored position's first parameter (X)
STORE = {28.1: 5161, 30.1: 5181}


class Homes:
    """The G28 and G30 positions of one program run (mm, machine coordinates)."""

    def __init__(self, machine: str) -> None:
        self.machine = machine
        self.stored: dict[int, float] = {}  # parameter -> value, as G28.1/G30.1 set them

    def read(self, n: int) -> float:
        """#5161-#5169 and #5181-#5189."""
        if n in self.stored:
            return self.stored[n]
        k = (n - 5161) % 20
        return self._power_up().get(AXES[k], 0.0) if k < len(AXES) else 0.0

    def _power_up(self) -> dict[str, float]:
        from ..machine import MachineError, load_machine  # read only when a program uses G28/G30
        try:
            m = load_machine(self.machine)
        except MachineError:
            return {}
        return {a: 1e3 * v for a, v in m.home_joints.items() if a in AXES}


def _axes(tr: "Translator") -> list[str]:
    """The machine's X, Y, Z axes (all three when the machine is unknown)."""
    return [a for a in AXES if a in machine_axes(tr.ctx.machine)] or list(AXES)


def words(tr: "Translator", b: Block, used: set[str], g: list[float]) -> bool:
    """G28.1/G30.1 and G28/G30 of a line; True when they took its axis words (G28, G30)."""
    store = next((c for c in g if c in STORE), None)
    if store is not None:
        _store(tr, b, store)
    code = next((c for c in g if c in GO), None)
    if code is not None:
        _go(tr, b, used, g, code)
    return code is not None


def _store(tr: "Translator", b: Block, code: float) -> None:
    name = word_text("G", code)
    machine = offsets.to_machine(tr, b.line, name)
    missing = next((a for a in _axes(tr) if a not in machine), None)
    if missing is not None:
        raise GcodeError(b.line, name, f"the {missing.upper()} position is unknown here: move {missing.upper()} "
                                       "first or give program.start", True)
    tr.homes.stored.update({STORE[code] + AXES.index(a): v for a, v in machine.items()})


def _go(tr: "Translator", b: Block, used: set[str], g: list[float], code: float) -> None:
    s = tr.state
    name = word_text("G", code)
    motion = next((c for c in g if c in MOTION), None)
    if motion is not None:
        raise GcodeError(b.line, name, f"cannot share a line with {word_text('G', motion)}: both take the axis words")
    if has_polar(b):
        raise GcodeError(b.line, name, "polar words (@ ^) are for motion: give X, Y or Z")
    named = [a for a in AXES if a.upper() in b.words] or _axes(tr)
    home = offsets.from_machine(tr, b.line, name, {a: tr.homes.read(GO[code] + AXES.index(a)) for a in named})
    before = dict(s.position)
    via = tr._target(b, used)
    if via != before:
        tr._move(b.line, {"rapid": via})
    s.position.update(home)
    if s.position != via:
        tr._move(b.line, {"rapid": dict(s.position)})
