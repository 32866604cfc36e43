"""G81/G82/G83/G73 holes into our drill operation (``cnc_msgs_py.gcode.cycles``).

R and Z (and Q, P) are sticky while the cycle is in force, as in LinuxCNC. Under G91, R is
measured from the initial Z, Z from R, X/Y from the previous hole, and L repeats the hole
that far on; under G90 an L above 1 would drill one hole again and is refused.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .cycles import drill_plane
from .lexer import Block, GcodeError, word_text
from .polar import has_polar, polar_xy

if TYPE_CHECKING:
    from .translate import Translator


def _sticky(tr: "Translator", b: Block, used: set[str], letter: str, name: str, required: bool) -> float | None:
    if letter in b.words:
        used.add(letter)
        tr.cycle[letter] = b.words[letter]
    if required and letter not in tr.cycle:
        raise GcodeError(b.line, name, f"needs {letter}")
    return tr.cycle.get(letter)


def hole(tr: "Translator", b: Block, used: set[str]) -> None:
    """One canned-cycle line: its hole(s) added to the open drill operation or a new one."""
    s = tr.state
    name = word_text("G", s.motion)
    if s.plane != 17.0:
        raise GcodeError(b.line, name, "drilling cycles are supported in the XY plane (G17) only")
    tr._need_spindle(b.line, name)
    r_word = _sticky(tr, b, used, "R", name, True)
    z_word = _sticky(tr, b, used, "Z", name, True)
    q = _sticky(tr, b, used, "Q", name, s.motion in (73.0, 83.0)) if s.motion in (73.0, 83.0) else None
    p = _sticky(tr, b, used, "P", name, False) if s.motion == 82.0 else None
    repeats = 1
    if "L" in b.words:
        used.add("L")
        repeats = int(b.words["L"])
        if repeats != b.words["L"] or repeats < 0:
            raise GcodeError(b.line, word_text("L", b.words["L"]), "repeats must be a whole number >= 0")
        if repeats > 1 and not s.incremental:
            raise GcodeError(b.line, word_text("L", b.words["L"]), "under G90 repeats drill the same hole again")
    initial = tr.cycle.get("initial_z")
    if s.incremental:
        if initial is None:
            raise GcodeError(b.line, name, "G91 cycles measure R from the initial Z, which is unknown here", True)
        r = initial + s.length(r_word)
        z = r + s.length(z_word)
    else:
        r, z = s.length(r_word), s.length(z_word)
    if z >= r:
        raise GcodeError(b.line, word_text("Z", z_word), "the hole bottom Z must lie below the R plane")
    if q is not None and q <= 0.0:
        raise GcodeError(b.line, word_text("Q", q), "a peck depth must be > 0")
    if p is not None and p < 0.0:
        raise GcodeError(b.line, word_text("P", p), "a dwell must be >= 0 s")
    clearance = None
    if s.retract_initial:
        if initial is None:
            raise GcodeError(b.line, "G98", "the initial Z is unknown: move Z before the cycle, or use G99", True)
        clearance = initial if initial > r else None
    feed = tr._feed_mm_min(b.line, name)
    block = {"holes": [], **drill_plane(r, z), "feed": feed, "overlap": tr.overlap}
    if q is not None:
        block["peck"] = {"depth": s.length(q), "retract": "full" if s.motion == 83.0 else "break"}
    if p:
        block["dwell"] = p
    if clearance is not None:
        block["clearance_z"] = clearance
    key = (s.motion, r, z, q, p, feed, clearance, tr.overlap, tr._key())
    holes = tr._begin(b.line, "drill", key, block)["holes"]
    pos = s.position
    for _ in range(repeats):
        if has_polar(b):
            pos["x"], pos["y"] = polar_xy(s, b, used)
        for axis in ("x", "y"):
            if axis.upper() in b.words:
                used.add(axis.upper())
                v = s.length(b.words[axis.upper()])
                if s.incremental:
                    if axis not in pos:
                        raise GcodeError(b.line, word_text(axis.upper(), b.words[axis.upper()]),
                                         "incremental hole from an unknown position", True)
                    v += pos[axis]
                pos[axis] = v
            elif axis not in pos:
                raise GcodeError(b.line, name, f"the hole's {axis.upper()} is unknown: give {axis.upper()}", True)
        holes.append([pos["x"], pos["y"]])
    pos["z"] = clearance if clearance is not None else r
