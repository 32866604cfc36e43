"""G76 threading and G71/G72 roughing (and G71.1/G72.1, G71.2/G72.2) into our thread and turn
operations (``cnc_msgs_py.gcode.cycles`` says how their words map)."""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Iterable

from . import arcs
from ..kinds.turn import Frame
from .cycles import clip_to_stock, g76_depths, g76_taper_ends, thread_passes
from .lexer import Block, GcodeError, word_text
from .modal import check_groups

if TYPE_CHECKING:
    from .translate import Translator


def _word(b: Block, used: set[str], letter: str, name: str, default: float | None = None) -> float:
    if letter in b.words:
        used.add(letter)
        return b.words[letter]
    if default is None:
        raise GcodeError(b.line, name, f"needs {letter}")
    return default


def _at(tr: "Translator", b: Block, name: str) -> tuple[float, float]:
    pos = tr.state.position
    if tr.state.plane != 18.0:
        raise GcodeError(b.line, name, "a lathe cycle needs the XZ plane (G18)")
    if "x" not in pos or "z" not in pos:
        raise GcodeError(b.line, name, "starts where the tool is, which is unknown here: move X and Z first", True)
    tr._need_spindle(b.line, name)
    return pos["x"], pos["z"]


def g76(tr: "Translator", b: Block, used: set[str]) -> None:
    """G76 P Z I J R K Q H E L from the drive line (the tool's X) at the start Z (its Z)."""
    s = tr.state
    x, z0 = _at(tr, b, "G76")
    diameter = 2.0 if s.diameter else 1.0  # I, J, K are diameters in G7
    pitch = s.length(_word(b, used, "P", "G76"))
    end_z = s.length(_word(b, used, "Z", "G76"))
    i = s.length(_word(b, used, "I", "G76")) / diameter
    j = s.length(_word(b, used, "J", "G76")) / diameter
    k = s.length(_word(b, used, "K", "G76")) / diameter
    degression = _word(b, used, "R", "G76", 1.0)
    angle = _word(b, used, "Q", "G76", 0.0)
    spring = _word(b, used, "H", "G76", 0.0)
    taper, ends = s.length(_word(b, used, "E", "G76", 0.0)), _word(b, used, "L", "G76", 0.0)
    if ends != int(ends) or ends < 0:  # LinuxCNC: "Negative l word used", "Non integer value for integer"
        raise GcodeError(b.line, word_text("L", ends), "which ends taper must be a whole number >= 0 "
                         "(0 none, 1 entry, 2 exit, 3 both)")
    if i >= 0.0:
        raise GcodeError(b.line, word_text("I", b.words["I"]), "internal threads (I >= 0) are not supported yet")
    if not 0.0 < j <= k:
        raise GcodeError(b.line, word_text("J", b.words["J"]), "the first cut must be > 0 and at most K")
    if degression < 1.0:
        raise GcodeError(b.line, word_text("R", degression), "degression must be >= 1")
    if spring != int(spring) or spring < 0:
        raise GcodeError(b.line, word_text("H", spring), "spring passes must be a whole number >= 0")
    try:
        depths = g76_depths(j, k, degression)
    except ValueError as err:
        raise GcodeError(b.line, word_text("J", b.words["J"]), str(err)) from None
    thread = {"start_z": z0, "end_z": end_z, "major_radius": x + i, "pitch": pitch, "depth": k,
              **thread_passes(depths), "infeed_angle": angle, "spring_passes": int(spring)}
    tapered = g76_taper_ends(int(ends))
    if taper > 0.0 and tapered is not None:  # E <= 0 or L0: the plain thread, as in LinuxCNC
        thread["end_taper"] = {"length": taper, "ends": tapered}
    tr._begin(b.line, "thread", ("G76", b.line), thread)
    tr._flush()
    # our cycle ends back at its start on the drive line


def _profile(tr: "Translator", blocks: Iterable[Block], start: tuple[float, float], line: int,
             cycle: str = "G71") -> list:
    """The contour's [z, x] points and {arc_to, radius, center} arcs, from the start point.
    While it is read, the position (#<_x>, #<_z>) is the contour's last point, as LinuxCNC
    reads a G7x contour (a contour may build on it: ``G1 X[#<_x>+5]``); then the tool's again."""
    s = tr.state
    saved = dict(s.position)
    try:
        return _read_profile(tr, blocks, start, line, cycle)
    finally:
        s.position.clear()
        s.position.update(saved)


def _read_profile(tr: "Translator", blocks: Iterable[Block], start: tuple[float, float], line: int,
                  cycle: str) -> list:
    s = tr.state
    z, x = start
    out: list = []
    motion = None
    for b in blocks:
        # the cycle moves X and Z alone: LinuxCNC reads nothing else of a contour's axis words
        b = replace(b, words={k: v for k, v in b.words.items() if k not in OTHER_AXES})
        check_groups(b, tr.ctx.machine)
        g = [round(v, 1) for v in b.g]
        for code in g:
            if code in (0.0, 1.0, 2.0, 3.0):
                motion = code
            elif code not in (90.0, 91.0):
                raise GcodeError(b.line, word_text("G", code), f"not supported inside a {cycle} contour")
        if b.m or any(k not in "XZIKRF" for k in b.words):
            k = next(iter(b.m and ["M"] or [k for k in b.words if k not in "XZIKRF"]))
            raise GcodeError(b.line, k, f"not supported inside a {cycle} contour")
        if "X" not in b.words and "Z" not in b.words:
            continue
        if motion is None:
            raise GcodeError(b.line, "X" if "X" in b.words else "Z", f"no motion mode in the {cycle} contour (G1)")
        nx = s.length(b.words["X"]) / (2.0 if s.diameter else 1.0) if "X" in b.words else x
        nz = s.length(b.words["Z"]) if "Z" in b.words else z
        if motion in (2.0, 3.0):
            name = word_text("G", motion)
            try:
                if "R" in b.words:
                    center = arcs.center_from_radius((z, x), (nz, nx), s.length(b.words["R"]), motion == 2.0)
                else:
                    center = (z + s.length(b.words.get("K", 0.0)), x + s.length(b.words.get("I", 0.0)))
                arcs.check_center((z, x), (nz, nx), center)
            except ValueError as err:
                raise GcodeError(b.line, name, str(err)) from None
            center = _on_bisector((z, x), (nz, nx), center)
            radius = math.hypot(z - center[0], x - center[1])
            out.append({"arc_to": [nz, nx], "center": [center[0], center[1]],
                        "radius": -radius if motion == 2.0 else radius})
        else:
            out.append([nz, nx])
        z, x = nz, nx
        s.position["z"], s.position["x"] = z, x
    if len(out) < 2:
        raise GcodeError(line, cycle, "the contour needs at least two points")
    return out


def _on_bisector(start: tuple[float, float], end: tuple[float, float],
                 center: tuple[float, float]) -> tuple[float, float]:
    """The center moved square to the chord onto its bisector: an arc within LinuxCNC's radius
    tolerance (a program's rounded I/K) as the exact arc a job outline takes (the move is that
    tolerance at most; an exact center stays where it is)."""
    (sz, sx), (ez, ex) = start, end
    cz, cx = (ez - sz, ex - sx)
    if cz == 0.0 and cx == 0.0:
        return center  # a full circle: no chord to be square to
    along = ((center[0] - (sz + ez) / 2.0) * cz + (center[1] - (sx + ex) / 2.0) * cx) / (cz * cz + cx * cx)
    return center[0] - along * cz, center[1] - along * cx


def _numbered_blocks(tr: "Translator", b: Block, p: int, q: int) -> list[Block]:
    """The blocks N<p> to N<q> following the G71 line, taken from the program's run (so that
    they are not run again as moves)."""
    blocks: list[Block] = []
    for block in tr.source:
        if blocks or block.number == p:
            blocks.append(block)
            if block.number == q:
                return blocks
    raise GcodeError(b.line, word_text("P", p), "P and Q must name N numbers of the contour following the G71 line, "
                                               "P first")


# G71/G72 (modal.ROUGHING_CYCLES) and their .1 (no pockets) and .2 (only the pockets) variants:
# the pass axis and pockets
ROUGHING = {71.0: ("z", "cut"), 71.1: ("z", "leave"), 71.2: ("z", "only"),
            72.0: ("x", "cut"), 72.1: ("x", "leave"), 72.2: ("x", "only")}
OTHER_AXES = "YABCUVW"  # axis words a G7x contour carries but its cycle does not move
MONOTONIC_MM = 1.0e-3  # LinuxCNC's G7x tolerance: a contour may run back this far against the passes


def _cycle_frame(profile: list, axis: str) -> Frame:
    """The directions LinuxCNC's G71 (axis z) or G72 (axis x) reads from the contour: its
    passes run the way the contour runs from its first point to its last along that axis, and
    step from the side the contour's first point lies on towards its last point's across it
    (interp_g7x.cc: swap(), after rotate() for G72). Outside turning, a bore, a face and a face
    bore (and G71 towards +z) are these four quadrants, twice."""
    first, last = (p if isinstance(p, list) else p["arc_to"] for p in (profile[0], profile[-1]))
    (fz, fx), (lz, lx) = first, last
    if axis == "z":
        return Frame("+z" if fz < lz else "-z", "+x" if fx > lx else "-x")
    return Frame("+x" if fx < lx else "-x", "-z" if fz < lz else "+z")


def _check_monotonic(b: Block, name: str, profile: list, frame: Frame) -> None:
    """LinuxCNC's refusal of a contour that runs back against the passes."""
    ends = [frame.to_cycle(*(p if isinstance(p, list) else p["arc_to"])) for p in profile]
    for (u0, _), (u1, _) in zip(ends, ends[1:]):
        if u1 > u0 + MONOTONIC_MM:
            z, x = frame.to_job(u1, 0.0)
            at = f"Z{z:g}" if frame.passes[1] == "z" else f"X{x:g}"
            raise GcodeError(b.line, name, f"G7X error: Not monotonic: the contour runs back against the passes "
                                           f"({frame.passes}) at {at}, as LinuxCNC refuses it")


def g71(tr: "Translator", b: Block, used: set[str], code: float = 71.0) -> None:
    """G71/G72 (.1, .2) Q<sub> (or P<N> Q<N>) X Z D I R: roughing along Z (G71) or along X (G72)."""
    s = tr.state
    name = word_text("G", code)
    axis, pockets = ROUGHING[code]
    x0, z0 = _at(tr, b, name)
    q = _word(b, used, "Q", name)
    if "P" in b.words:
        used.add("P")
        blocks = _numbered_blocks(tr, b, int(b.words["P"]), int(q))
        tr.contours[(int(b.words["P"]), int(q))] = blocks
    else:
        blocks = tr.executor.expand(str(int(q)), b.line)
    sx = s.length(b.words["X"]) / (2.0 if s.diameter else 1.0) if "X" in b.words else x0
    sz = s.length(b.words["Z"]) if "Z" in b.words else z0
    used.update(k for k in "XZ" if k in b.words)
    allowance = s.length(_word(b, used, "D", name, 0.0))
    depth = s.length(_word(b, used, "I", name))
    clearance = s.length(_word(b, used, "R", name, 0.5))
    if s.feed is None:
        raise GcodeError(b.line, name, "no feed given (F)")
    feed = s.length(s.feed) if s.per_rev else s.length(s.feed) / s.speed
    profile = _profile(tr, blocks, (sz, sx), b.line, name)
    frame = _cycle_frame(profile, axis)
    _check_monotonic(b, name, profile, frame)
    if tr.ctx.stock is not None:
        if frame != Frame():
            raise GcodeError(b.line, name, f"the program's stock outline is one for outside turning towards -z; "
                                           f"this cycle's passes run {frame.passes}, stepping {frame.infeed}")
        stock = tr.ctx.stock
        profile = clip_to_stock(profile, stock)
    else:  # the stock the cycle assumes: up to its start point across the passes, from it (or from the
        # contour's first point, where that lies ahead of it, as LinuxCNC moves its start) to the contour's end
        ends = [frame.to_cycle(*(p if isinstance(p, list) else p["arc_to"]))[0] for p in profile]
        u0, v0 = frame.to_cycle(sz, sx)
        u0 = max(u0, ends[0])
        stock = [list(frame.to_job(u0, v0)), list(frame.to_job(min(ends), v0))]
    origin = outside(stock, profile, allowance, clearance, (z0, x0), frame)
    # D all round, as LinuxCNC offsets the contour: G71 leaves it on diameters (faces keep our axial default)
    allowances = {"finish_allowance": allowance} if axis == "z" else {"finish_allowance": allowance,
                                                                      "finish_allowance_z": allowance}
    turn = {"stock": stock, "profile": profile, "depth_of_cut": depth, "clearance": clearance, "feed": feed,
            "origin": list(origin), **allowances, "finishing_pass": True}
    if frame != Frame():
        turn.update(passes=frame.passes, infeed=frame.infeed)
    if pockets != "cut":
        turn["pockets"] = pockets
    tr._begin(b.line, "turn", (name, b.line), turn)
    tr._flush()
    s.position["z"], s.position["x"] = origin  # our cycle ends back at its origin


def _bulge(p: list | dict, frame: Frame) -> float:
    """The highest v (across the passes, in the cycle's axes) a profile element reaches (an
    arc's center + its radius bounds its bulge)."""
    if isinstance(p, list):
        return frame.to_cycle(*p)[1]
    return max(frame.to_cycle(*p["arc_to"])[1], frame.to_cycle(*p["center"])[1] + abs(p["radius"]))


def outside(stock: list, profile: list, allowance: float, clearance: float, at: tuple[float, float],
            frame: Frame = Frame()) -> tuple[float, float]:
    """Where the roughing starts and ends: the tool's (z, x) when it stands clear of the
    stock and the finished profile, else R (the clearance) beyond them against the infeed,
    straight out from where it stands. LinuxCNC's G71 may start on the stock's corner
    (``G0 X40 Z2`` then ``G71 ... X40 Z2``): its first move retracts by R, and so does ours."""
    u, v = frame.to_cycle(*at)
    top = max(max(frame.to_cycle(*p)[1] for p in stock if isinstance(p, list)),
              max(_bulge(p, frame) for p in profile) + allowance)
    first = frame.to_cycle(*(profile[0] if isinstance(profile[0], list) else profile[0]["arc_to"]))[0]
    right = max(frame.to_cycle(*next(p for p in stock if isinstance(p, list)))[0], first)
    if v > top or u > right:
        return at
    return frame.to_job(u, top + clearance)
