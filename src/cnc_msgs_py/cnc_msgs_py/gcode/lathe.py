"""G76 threading and G71 roughing into our thread and turn operations
(``cnc_msgs_py.gcode.cycles`` says how their words map)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from . import arcs
from .cycles import clip_to_stock, g76_depths, thread_passes
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
    taper, ends = _word(b, used, "E", "G76", 0.0), _word(b, used, "L", "G76", 0.0)
    if taper != 0.0 or ends != 0.0:
        raise GcodeError(b.line, word_text("E", taper) if taper else word_text("L", ends),
                         "tapered thread ends are not supported yet (E0 L0)")
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
    tr._begin(b.line, "thread", ("G76", b.line), thread)
    tr._flush()
    # our cycle ends back at its start on the drive line


def _profile(tr: "Translator", blocks: list[Block], start: tuple[float, float], line: int, cycle: str = "G71") -> list:
    """The contour's [z, radius] points and {arc_to, radius, center} arcs, from the start point."""
    s = tr.state
    z, x = start
    out: list = []
    motion = None
    for b in blocks:
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
                radius = arcs.check_center((z, x), (nz, nx), center)
            except ValueError as err:
                raise GcodeError(b.line, name, str(err)) from None
            out.append({"arc_to": [nz, nx], "center": [center[0], center[1]],
                        "radius": -radius if motion == 2.0 else radius})
        else:
            out.append([nz, nx])
        z, x = nz, nx
    if len(out) < 2:
        raise GcodeError(line, cycle, "the contour needs at least two points")
    return out


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


def g71(tr: "Translator", b: Block, used: set[str]) -> None:
    """G71 Q<sub> (or P<N> Q<N>) X Z D I R: roughing."""
    s = tr.state
    x0, z0 = _at(tr, b, "G71")
    q = _word(b, used, "Q", "G71")
    if "P" in b.words:
        used.add("P")
        blocks = _numbered_blocks(tr, b, int(b.words["P"]), int(q))
        tr.contours[(int(b.words["P"]), int(q))] = blocks
    else:
        blocks = tr.executor.expand(str(int(q)), b.line)
    sx = s.length(b.words["X"]) / (2.0 if s.diameter else 1.0) if "X" in b.words else x0
    sz = s.length(b.words["Z"]) if "Z" in b.words else z0
    used.update(k for k in "XZ" if k in b.words)
    allowance = s.length(_word(b, used, "D", "G71", 0.0))
    depth = s.length(_word(b, used, "I", "G71"))
    clearance = s.length(_word(b, used, "R", "G71", 0.5))
    if s.feed is None:
        raise GcodeError(b.line, "G71", "no feed given (F)")
    feed = s.length(s.feed) if s.per_rev else s.length(s.feed) / s.speed
    profile = _profile(tr, blocks, (sz, sx), b.line)
    if tr.ctx.stock is not None:
        stock = tr.ctx.stock
        profile = clip_to_stock(profile, stock)
    else:
        z_min = min((p[0] if isinstance(p, list) else p["arc_to"][0]) for p in profile)
        stock = [[sz, sx], [z_min, sx]]
    origin = outside(stock, profile, allowance, clearance, (z0, x0))
    turn = {"stock": stock, "profile": profile, "depth_of_cut": depth, "clearance": clearance, "feed": feed,
            "origin": list(origin), "finish_allowance": allowance, "finishing_pass": True}
    tr._begin(b.line, "turn", ("G71", b.line), turn)
    tr._flush()
    s.position["z"], s.position["x"] = origin  # our cycle ends back at its origin


def _radius(p: list | dict) -> float:
    """The largest radius a profile element reaches (an arc's center radius + its radius
    bounds its bulge)."""
    if isinstance(p, list):
        return p[1]
    return max(p["arc_to"][1], p["center"][1] + abs(p["radius"]))


def outside(stock: list, profile: list, allowance: float, clearance: float, at: tuple[float, float]) -> tuple[float, float]:
    """Where the roughing starts and ends: the tool's (z, radius) when it stands clear of the
    stock and the finished profile, else R (the clearance) above them, straight out from
    where it stands. LinuxCNC's G71 may start on the stock's corner (``G0 X40 Z2`` then
    ``G71 ... X40 Z2``): its first move retracts by R, and so does ours."""
    z, x = at
    top = max(max(p[1] for p in stock if isinstance(p, list)), max(_radius(p) for p in profile) + allowance)
    first = profile[0][0] if isinstance(profile[0], list) else profile[0]["arc_to"][0]
    right = max(next(p[0] for p in stock if isinstance(p, list)), first)
    if x > top or z > right:
        return z, x
    return z, top + clearance
