"""G5.1 quadratic B-splines as LinuxCNC 2.9 reads them, expanded into straight feed moves.

``G5.1 X Y I J``: from the current point to X Y (either may be left out: that axis stays),
its one control point at the start plus I J (an offset from the start, under G90.1 too);
the curve is the quadratic Bezier of start, control point and end (a one-span quadratic
B-spline). LinuxCNC refuses it outside the XY plane (G17), without both I and J, with a Z
(or other axis) word and with cutter compensation on; so do we. G5.1 moves on its line
only: the motion mode in force (G0, G1, ...) stays, as ``#<_motion_mode>`` reads in LinuxCNC.

A move job has no spline of its own: the curve becomes chords at equal steps of its
parameter, each within ``arcs.CHORD_TOLERANCE_MM`` of the curve, the last ending exactly at
X Y. The bound is exact for a parabola: over a parameter step h the curve leaves its chord
by at most |c''| h^2 / 8, c'' = 2 (start - 2 control + end) being constant.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from . import path_tolerance, surface_speed
from .arcs import CHORD_TOLERANCE_MM, Point2
from .lexer import Block, GcodeError, word_text

if TYPE_CHECKING:
    from .translate import Translator

CODE = 5.1


def point(start: Point2, control: Point2, end: Point2, t: float) -> Point2:
    """The curve at parameter t (0: start, 1: end)."""
    a, b, c = (1.0 - t) ** 2, 2.0 * (1.0 - t) * t, t * t
    return (a * start[0] + b * control[0] + c * end[0], a * start[1] + b * control[1] + c * end[1])


def chords(start: Point2, control: Point2, end: Point2, tolerance: float = CHORD_TOLERANCE_MM) -> list[Point2]:
    """Points along the curve after the start, the end last (exactly), each chord between
    them within ``tolerance`` of the curve."""
    bend = 2.0 * math.hypot(*(s - 2.0 * c + e for s, c, e in zip(start, control, end)))  # |c''|
    n = max(1, math.ceil(math.sqrt(bend / (8.0 * tolerance))))
    return [point(start, control, end, k / n) for k in range(1, n)] + [end]


def g5_1(tr: "Translator", b: Block, g: list[float], used: set[str]) -> None:
    """A G5.1 line: the spline from the current point as feed moves (see the module)."""
    s = tr.state
    name = word_text("G", CODE)
    if 53.0 in g:
        raise GcodeError(b.line, "G53", "machine coordinates are for straight moves (G0, G1)")
    if s.plane != 17.0:
        raise GcodeError(b.line, name, "splines lie in the XY plane (G17)")
    if "Z" in b.words:
        raise GcodeError(b.line, word_text("Z", b.words["Z"]), "a G5.1 spline moves X and Y only")
    if "I" not in b.words or "J" not in b.words:
        raise GcodeError(b.line, name, "needs both I and J: the control point's offset from the start")
    if "X" not in b.words and "Y" not in b.words:
        raise GcodeError(b.line, name, "needs X or Y: the end point")
    if "x" not in s.position or "y" not in s.position:
        raise GcodeError(b.line, name, "a spline from an unknown position (move X and Y first)", True)
    used.update("IJ")
    start = (s.position["x"], s.position["y"])
    control = (start[0] + s.length(b.words["I"]), start[1] + s.length(b.words["J"]))
    before = dict(s.position)
    end_pos = tr._target(b, used)
    feed = surface_speed.feed(tr, b.line, name)
    at = before
    for x, y in chords(start, control, (end_pos["x"], end_pos["y"])):
        target = {**end_pos, "x": x, "y": y}
        if not path_tolerance.add(tr, b.line, at, target, feed):
            tr._move(b.line, {"linear": target, **feed})
        at = target
