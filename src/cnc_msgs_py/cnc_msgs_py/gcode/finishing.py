"""G70, LinuxCNC 2.9's finishing cycle, into a move operation: the contour of the ``o<Q> sub``
followed at feed, as rs274 -g makes it.

``G70 Q<sub> X Z D E P`` (or, after a ``G71 P<N> Q<N>``, ``G70 P<N> Q<N>`` with the same
N numbers: that contour, one pass, as Fanuc-style programs finish): a rapid to the start (X,
Z; else where the tool stands); then P passes (default 1), pass k offset from the contour by
E + (D - E)(P - k)/P (so the last pass runs on the contour, offset E), each one reached by a
rapid to its first point and left by a rapid back to the start, but the last, which ends on
the contour's end. The offset is to the side of the contour the start point lies on
(``_side``: out of the material), corners joined as ``compensation.offset_pieces`` joins
them: arcs about outside corners, inside corners trimmed, a corner LinuxCNC's compensation
takes as tangent (a program's rounded arcs) joined as one. The contour's first move is the
approach, as in LinuxCNC: the path starts at its end.

Its feed moves need the spindle only as any feed does (G95). Under cutter compensation
(G41/G42, G41.1/G42.1 with the nose radius) the passes are compensated as any move is, as
LinuxCNC runs its G70 (the roughing cycles refuse compensation, as LinuxCNC's do).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from . import arcs, compensation, surface_speed
from .compensation import SMALL_CORNER_RAD, Segment, offset_pieces
from .lathe import _profile, _word
from .lexer import Block, GcodeError, word_text
from .parameters import whole

if TYPE_CHECKING:
    from .translate import Translator


def contour_segments(profile: list) -> list[Segment]:
    """The (z, x) segments of a lathe profile after its first point (its approach's end)."""
    first = profile[0] if isinstance(profile[0], list) else profile[0]["arc_to"]
    at = (first[0], first[1])
    out: list[Segment] = []
    for p in profile[1:]:
        if isinstance(p, list):
            end = (p[0], p[1])
            if end != at:
                out.append(Segment(at, end))
        else:
            end = (p["arc_to"][0], p["arc_to"][1])
            out.append(Segment(at, end, (p["center"][0], p["center"][1]), p["radius"] < 0.0))
        at = end
    return out


def _side(first: Segment, start: tuple[float, float]) -> float:
    """+1 (right of travel) or -1: the side of the contour's first move the cycle's start
    point lies on, which LinuxCNC's G70 offsets towards (out of the material, whichever way
    the contour runs: outside or bore, right to left or left to right, or a face)."""
    t = first.tangent(False)
    return 1.0 if (start[0] - first.start[0]) * t[1] - (start[1] - first.start[1]) * t[0] >= 0.0 else -1.0


def g70(tr: "Translator", b: Block, used: set[str]) -> None:
    """G70 Q X Z D E P: the finishing passes as feed moves of a move operation."""
    s = tr.state
    if s.plane != 18.0:
        raise GcodeError(b.line, "G70", "a lathe cycle needs the XZ plane (G18)")
    q = _word(b, used, "Q", "G70")
    if "X" in b.words and "Z" in b.words:  # a rapid there first: where the tool stood does not matter
        sx, sz = s.length(b.words["X"]) / (2.0 if s.diameter else 1.0), s.length(b.words["Z"])
    else:
        if "x" not in s.position or "z" not in s.position:
            raise GcodeError(b.line, "G70", "starts where the tool is, which is unknown here: give X and Z", True)
        sx = s.length(b.words["X"]) / (2.0 if s.diameter else 1.0) if "X" in b.words else s.position["x"]
        sz = s.length(b.words["Z"]) if "Z" in b.words else s.position["z"]
    used.update(k for k in "XZ" if k in b.words)
    start = s.length(_word(b, used, "D", "G70", 0.0))
    end = s.length(_word(b, used, "E", "G70", 0.0))
    blocks = tr.contours.get((int(b.words.get("P", -1)), int(q)))  # G70 P<N> Q<N> after a G71 P Q: one pass
    p_word = 1.0 if blocks is not None else _word(b, used, "P", "G70", 1.0)
    used.update("P" if blocks is not None else "")
    try:
        passes = whole(p_word, word_text("P", p_word))
    except ValueError:
        passes = 0
    if passes < 1:
        raise GcodeError(b.line, word_text("P", p_word), "the number of passes must be a whole number >= 1")
    if start < 0.0 or end < 0.0:
        raise GcodeError(b.line, "G70", "D and E are distances from the contour (>= 0)")
    feed = surface_speed.feed(tr, b.line, "G70")  # per minute, or per revolution at a surface speed
    if blocks is None:
        blocks = tr.executor.expand(str(int(q)), b.line)
    profile = _profile(tr, blocks, (sz, sx), b.line, "G70")
    contour = contour_segments(profile)
    if not contour:
        raise GcodeError(b.line, "G70", "the contour has no move after its first point")
    side = _side(contour[0], (sz, sx))

    def go(z: float, x: float, feed_move: bool, center: tuple[float, float] | None = None,
           clockwise: bool = False) -> None:
        before = dict(s.position)
        s.position["z"], s.position["x"] = z, x
        if compensation.add(tr, b.line, not feed_move, feed if feed_move else None, before, dict(s.position),
                            center, clockwise):
            return  # under G41/G42 (G41.1/G42.1) the passes are offset as LinuxCNC offsets its G70's moves
        entry = {"linear": dict(s.position), **feed} if feed_move else {"rapid": dict(s.position)}
        tr._move(b.line, entry)

    if (sz, sx) != (s.position.get("z"), s.position.get("x")):
        go(sz, sx, False)
    for k in range(1, passes + 1):
        distance = side * (end + (start - end) * (passes - k) / passes)
        try:
            path = [seg for _, seg in offset_pieces(contour, distance, small_corner=SMALL_CORNER_RAD)]
        except ValueError as err:
            raise GcodeError(b.line, "G70", str(err)) from None
        go(*path[0].start, False)
        for seg in path:
            if seg.center is None:
                go(*seg.end, True)
            elif tr.comp.on:
                go(*seg.end, True, seg.center, seg.clockwise)
            else:
                for pz, px, _ in arcs.chords(seg.start, seg.end, seg.center, seg.clockwise):
                    go(pz, px, True)
        if k < passes:
            go(sz, sx, False)
