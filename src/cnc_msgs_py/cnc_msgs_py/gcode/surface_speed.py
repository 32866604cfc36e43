"""G96 and G97, the spindle speed mode, as LinuxCNC 2.9 reads them on a lathe.

``G96 D<max rpm> S<surface speed>``: from this line on S is the cutting speed at the tool's
radius, m/min (ft/min under G20, converted here once), and D the rpm the spindle may never
exceed (D0 or none: the machine's spindle limit caps). ``G97``: S is rpm again; without an S
in its line the spindle turns at the last S, as LinuxCNC's does.

What turns at a surface speed here: G71 roughing (our turn operation carries
``surface_speed``, and the planner follows the radius along its passes), and rapids and
G1/G2/G3 feeds, compensated or not (a move operation with ``surface_speed``; under G95 its
feeds are ``feed_per_rev``, per revolution of the spindle's actual, changing speed; under
G94 per minute). What cannot, refused at its word with why: threads (G76: the lead is locked
to the spindle angle), a (CNC,VIBRATION) cut (locked to one spindle speed), drilling and
G70's finishing pass (not yet). At a surface speed the feed of a G71 must
be per revolution (G95): the rpm changes along the cut, and a feed per minute would change
the chip with it.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..machine import MachineError, load_machine
from .lexer import Block, GcodeError, word_text
from .modal import DRILL_CYCLES, MOTION, ROUGHING_CYCLES, Modal

if TYPE_CHECKING:
    from .translate import Translator

INCHES_PER_FOOT = 12.0
LATHES = ("lathe", "lathe_y")  # layouts whose x is the tool's radius
SHARES_D = (41.0, 42.0, 41.1, 42.1, 70.0, *ROUGHING_CYCLES)  # codes whose own D a G96 in their line would take


def _m_per_min(s: Modal, value: float) -> float:
    """S under G96 in m/min: ft/min under G20 (through Modal.length's one inch factor)."""
    return s.length(value * INCHES_PER_FOOT) / 1000.0 if s.inch else value


def words(tr: "Translator", b: Block, used: set[str], g: list[float]) -> None:
    """G96 (with its D) and G97 of a line, and an S word under G96; after the line's S is read."""
    s = tr.state
    if 96.0 in g:
        _need_lathe(tr, b)
        shared = next((c for c in g if c in SHARES_D), None)
        if shared is not None:
            raise GcodeError(b.line, "G96", f"give G96 D.. S.. on a line of its own: D is also "
                                            f"{word_text('G', shared)}'s word here")
        cap = b.words.get("D", 0.0)
        used.add("D")
        if cap < 0.0:
            raise GcodeError(b.line, word_text("D", cap), "the maximum rpm must be >= 0 (0: the spindle's limit)")
        if s.speed <= 0.0:
            raise GcodeError(b.line, "G96", "needs S, the surface speed (m/min, ft/min under G20)")
        s.max_rpm = cap or None
        s.surface = _m_per_min(s, s.speed)
    elif 97.0 in g:
        s.surface, s.max_rpm = None, None
    elif s.surface is not None and "S" in b.words:
        if b.words["S"] <= 0.0:
            raise GcodeError(b.line, word_text("S", b.words["S"]), "a surface speed must be > 0 (G97 for rpm)")
        s.surface = _m_per_min(s, b.words["S"])


def _need_lathe(tr: "Translator", b: Block) -> None:
    """G96 on a machine that is not a lathe is refused at its word: the speed follows the
    tool's radius, which only a lathe's x is. A machine the description does not know is
    left for the planner to refuse."""
    try:
        layout = load_machine(tr.ctx.machine).layout
    except MachineError:
        return
    if layout not in LATHES:
        raise GcodeError(b.line, "G96", f"constant surface speed needs a lathe (the speed follows the tool's "
                                        f"radius, x): {tr.ctx.machine} is a {layout}")


def check_motion(tr: "Translator", b: Block, g: list[float]) -> None:
    """Refuse, at its word, a motion that cannot run at the surface speed in force."""
    s = tr.state
    if s.surface is None:
        return
    motion = next((c for c in g if c in MOTION), None)
    moves = motion is not None or b.has_axes()
    code = motion if motion is not None else s.motion
    if code is None or not moves:
        return
    word = word_text("G", code)
    if code == 76.0:
        raise GcodeError(b.line, word, "a thread turns at one rpm (its lead is locked to the spindle angle): "
                                       "G97 S.. before it, not G96")
    if code in DRILL_CYCLES:
        raise GcodeError(b.line, word, "a drill turns at one rpm: G97 S.. before it, not G96")
    if code in (1.0, 2.0, 3.0, 70.0, *ROUGHING_CYCLES):
        if tr.vibration is not None:
            raise GcodeError(b.line, word, "(CNC,VIBRATION) is locked to one spindle speed: not at constant surface "
                                           "speed (G97 S.., or (CNC,VIBRATION OFF))")
        if not s.per_rev and code not in (1.0, 2.0, 3.0, 70.0):  # (G70 finishes in feed moves, as G1)
            raise GcodeError(b.line, word, "at constant surface speed the feed is per revolution (G95): the rpm "
                                           "changes along the cut")


def feed(tr: "Translator", line: int, word: str) -> dict:
    """A feed move's feed keys: ``feed`` (mm/min) as the front end writes it, or under G96 with
    G95 ``feed_per_rev`` (mm/rev), per revolution of the spindle's actual, changing speed."""
    s = tr.state
    if s.surface is None or not s.per_rev:
        return {"feed": tr._feed_mm_min(line, word)}
    return {"feed_per_rev": tr._given_feed(line, word, s.spindle_on)}  # S is a surface speed here


def spindle(s: Modal) -> dict:
    """An operation's spindle keys: ``spindle_rpm``, or ``surface_speed`` under G96."""
    if not s.spindle_on or s.surface is None:
        return {"spindle_rpm": s.speed if s.spindle_on else 0.0}
    css = {"m_min": s.surface}
    if s.max_rpm is not None:
        css["max_rpm"] = s.max_rpm
    return {"surface_speed": css}


def key(s: Modal) -> tuple:
    """What of the spindle ends an operation when it changes."""
    if not s.spindle_on:
        return (0.0,)
    return (s.speed,) if s.surface is None else ("G96", s.surface, s.max_rpm)
