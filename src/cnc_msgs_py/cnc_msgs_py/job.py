"""Job documents (schema ``cnc_job/1``): what a cell controller asks the planner to do.

Documents are JSON on the ``job_goal`` topic (YAML files on the command line) in
machinist units: lengths mm, feeds mm/min (turning feeds mm/rev), speeds rpm, angles deg.
``parse_job`` validates a whole document and returns it in SI units (m, m/s, rad, rad/s);
any error names the field path and the reason, before anything can move.

Lathe outlines (``turn.stock``, ``turn.profile``) run right to left (z decreasing) as
``[z, radius]`` points. An entry may instead be an arc from the previous point::

    profile:
    - [0, 10]
    - {arc_to: [-5, 15], radius: 5}        # by radius: the shorter arc
    - {arc_to: [-10, 20], center: [-10, 15]}  # by center (the shorter arc)
    - [-40, 20]

``radius`` is signed: positive turns counter-clockwise in the Z-X plane (z right, x up), which,
run right to left, bulges away from the axis (convex, a rounded corner); negative bulges towards
it (concave, a fillet or a round groove). Give ``center``, ``radius`` or both (a half circle
needs the radius to pick its side; with both, |radius| must be the center's distance). The
parser expands every arc into chords within 1 um of the arc (``cnc_msgs_py.outline``), so the
parsed job holds plain point lists; an arc whose radius is shorter than half its chord, whose
center is not equally far from both ends, that is the first entry or that turns back in z is
refused at its field path (e.g. ``turn.profile[2].radius``).

``turn.finish_allowance`` (radial, as U of G71) and ``turn.finish_allowance_z`` (axial, as W,
default 0.1 mm) are left on the profile by roughing: the tool stays that far off diameters and
shoulder faces, in both directions.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import yaml

from .schema import Bool, Either, JobError, List, Num, Obj, Str, show
from .outline import CHORD_TOLERANCE, ArcError, arc_points
from .units import rpm, to_mm

SCHEMA = "cnc_job/1"
KINDS = ("drill", "turn", "thread", "move", "path")
AXIS_KEYS = ("x", "y", "z", "a", "b", "c")
MAX_LIST = 100_000  # holes, moves, outline points: beyond this a job is refused
# Smallest values that make sense on a machine tool. Smaller positive values would plan
# moves lasting years (or not at all: ruckig gives up), so they are refused by name.
MIN_FEED = 1.0  # mm/min
MIN_FEED_PER_REV = 0.001  # mm/rev
MIN_RPM = 1.0  # a spindle is off (0) or turns at least this fast
MIN_PITCH = 0.01  # mm
MIN_DEPTH_OF_CUT = 0.01  # mm, radial, turning
MIN_CLEARANCE = 0.001  # mm, turning

MM = Num("mm")
POINT_ZX = List(Num("mm"), length=2)  # [z, radius] on the lathe
ARC_ZX = Obj({"arc_to": POINT_ZX, "radius": Num("mm", default=None), "center": List(Num("mm"), length=2, default=None)})


@dataclass(frozen=True)
class PointOr:
    """A point given as a list, or a mapping form of it (an arc, a hole with its own depth)."""

    point: List
    mapping: Obj
    expected: str
    default: Any = None

    def check(self, value: Any, path: str) -> Any:
        if isinstance(value, dict):
            return self.mapping.check(value, path)
        if isinstance(value, list):
            return self.point.check(value, path)
        raise JobError(path, f"expected {self.expected}, got {show(value)}")


# A ``[z, radius]`` point, or an arc ``{arc_to, radius and/or center}`` from the previous point.
OUTLINE = List(PointOr(POINT_ZX, ARC_ZX, "a [z, radius] point or an {arc_to: ...} arc"), min_len=2, max_len=MAX_LIST)

VIBRATION = Obj({
    "D": Num("1", gt=0.0, max=50.0, default=None),
    "Q": Num("1", gt=0.0, max=20.0, default=None),  # required with D; optional with E and R
    "E": Num("1", gt=0.0, max=50.0, default=None),
    "R": Num("1", gt=0.0, max=50.0, default=None),
    "phase_shift": Num("deg", min=-360.0, max=360.0, default=0.0),
    "D_step": Num("1", min=0.0, max=10.0, default=0.0),
}, default=None)

HOLE_AT = Obj({"at": List(Num("mm"), length=2), "depth": Num("mm", gt=0.0, default=None),
               "surface_z": Num("mm", default=None)})


# A hole: ``[x, y]``, or ``{at: [x, y], depth, surface_z}`` overriding the block's values.
HOLE = PointOr(List(Num("mm"), length=2), HOLE_AT, "an [x, y] point or an {at: [x, y], ...} hole")

PECK = Obj({
    "depth": Num("mm", gt=0.0),  # Q: feed this much deeper per peck
    "retract": Str(("full", "break"), default="full"),  # G83 to R, or G73 chip-break
    "full_every": Num("1", min=1, max=1000, integer=True, default=None),  # with break: every N-th to R
}, default=None)
OBSTACLE = List(Num("mm"), length=5)  # [x0, y0, x1, y1, top_z]: a clamp's box, program coordinates

DRILL = Obj({
    "holes": List(HOLE, min_len=1, max_len=MAX_LIST),
    "surface_z": Num("mm", default=0.0),
    "depth": Num("mm", gt=0.0),
    "r_gap": Num("mm", gt=0.0, max=50.0, default=2.0),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED),
    "overlap": Str(("auto", "off"), default="auto"),
    "mode": Either((Str(("auto",)), Num("1", min=1, max=3, integer=True)), "auto, 1, 2 or 3", default="auto"),
    "gentle_air_accel": Bool(default=False),
    "dwell": Num("1", min=0.0, max=60.0, default=0.0),  # s at the bottom of every hole (G82)
    "peck": PECK,
    "clearance_z": Num("mm", default=None),  # X/Y travels no lower than this (G98-like)
    "obstacles": List(OBSTACLE, max_len=1000, default=None),
    "order": Str(("given", "shortest"), default="given"),
}, default=None)

MOVE_TARGET = Obj({k: Num("mm", default=None) for k in AXIS_KEYS})
MOVE = List(Obj({
    "rapid": Obj(MOVE_TARGET.fields, default=None),
    "linear": Obj(MOVE_TARGET.fields, default=None),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED, default=None),
    "dwell": Num("1", gt=0.0, max=3600.0, default=None),
}), min_len=1, max_len=MAX_LIST, default=None)

TURN = Obj({
    "stock": OUTLINE,
    "profile": OUTLINE,
    "depth_of_cut": Num("mm", gt=0.0, min=MIN_DEPTH_OF_CUT, max=20.0),
    "clearance": Num("mm", gt=0.0, min=MIN_CLEARANCE, max=20.0, default=0.5),
    "feed": Num("mm/rev", gt=0.0, min=MIN_FEED_PER_REV, max=5.0),
    "origin": POINT_ZX,
    "finish_allowance": Num("mm", min=0.0, max=5.0, default=0.0),
    "finish_allowance_z": Num("mm", min=0.0, max=5.0, default=0.1),
    "finishing_pass": Bool(default=False),
}, default=None)

THREAD = Obj({
    "start_z": Num("mm"),
    "end_z": Num("mm"),
    "major_radius": Num("mm", gt=0.0),
    "pitch": Num("mm", gt=0.0, min=MIN_PITCH, max=100.0),
    "depth": Num("mm", gt=0.0),
    "passes": Num("1", min=1, max=100, integer=True, default=6),
    "depths": List(Num("mm", gt=0.0), min_len=1, max_len=100, default=None),
    "infeed_angle": Num("deg", min=0.0, max=90.0, default=29.5),
    "spring_passes": Num("1", min=0, max=10, integer=True, default=1),
    "starts": Num("1", min=1, max=16, integer=True, default=1),
    "internal": Bool(default=False),
    "taper": Num("1", min=0.0, max=0.5, default=0.0),  # diameter per length (NPT 1:16 = 0.0625)
}, default=None)

PATH = Obj({
    "points": List(List(Num("mm"), min_len=3, max_len=3), min_len=2, max_len=MAX_LIST),
    "tool_axis": List(List(Num("1"), length=3), min_len=2, max_len=MAX_LIST, default=None),
    "feed": Num("mm/min", gt=0.0, min=MIN_FEED),
    "chord_tolerance": Num("mm", gt=0.0, default=0.01),
}, default=None)

JOB = Obj({
    "schema": Str((SCHEMA,)),
    "job_id": Str(pattern=r"[A-Za-z0-9_.:-]{1,64}"),
    "kind": Str(KINDS),
    "machine": Str(pattern=r"[A-Za-z0-9_.-]{1,64}"),
    "tool": Obj({
        "length": Num("mm", min=0.0, max=1000.0, default=0.0),
        "diameter": Num("mm", min=0.0, max=500.0, default=None),  # 0: a lathe tool (D0)
        "nose_radius": Num("mm", min=0.0, max=10.0, default=0.0),
    }, default={}),
    "setup": Obj({
        "origin": List(Num("mm"), length=3, default=[0.0, 0.0, 0.0]),
        "rotation_deg": List(Num("deg"), length=3, default=[0.0, 0.0, 0.0]),
        # A named work offset of config/work_offsets.yaml instead of origin/rotation_deg
        # (the planner resolves it; with it, origin and rotation_deg must be left out or 0).
        "work_offset": Str(pattern=r"[A-Za-z0-9_.-]{1,64}", default=None),
    }, default={}),
    "spindle_rpm": Num("rpm", min=0.0, max=100_000.0, default=0.0),
    "drill": DRILL,
    "move": MOVE,
    "turn": TURN,
    "thread": THREAD,
    "path": PATH,
    "vibration": VIBRATION,
})

# Fields each kind needs besides its own block.
NEEDS_SPINDLE = ("drill", "turn", "thread")
LATHE_KINDS = ("turn", "thread")  # their tools may have diameter 0 (D0 in lathe tool tables)
# Keys a kind has no use for: given anyway, they are refused by name, never ignored.
# (The blocks of the other kinds are refused in _check_kind; path refuses a vibration.)
UNUSED_KEYS = {
    "drill": ("tool.nose_radius", "vibration.phase_shift", "vibration.D_step"),
    "move": ("vibration.phase_shift", "vibration.D_step"),
    "turn": ("vibration.phase_shift", "vibration.D_step"),
    "thread": (),
    "path": ("vibration.phase_shift", "vibration.D_step"),
}
UNUSED_WHY = {
    "tool.nose_radius": "a drill has no nose radius (it is a lathe insert's)",
    "vibration.phase_shift": "only a thread shifts the vibration phase from pass to pass",
    "vibration.D_step": "only a thread raises D from pass to pass",
}
# Drill keys that only the overlapped cycle uses.
OVERLAP_ONLY = {"mode": "the conventional cycle (overlap: off) has no retract modes",
                "gentle_air_accel": "the conventional cycle (overlap: off) has no air arc"}


def _mm(value_m: float) -> str:
    return f"{to_mm(value_m):.4g} mm"


def expand_outline(entries: list, path: str) -> list[list[float]]:
    """The outline's points with every arc expanded into chords (SI); JobError at the arc's path."""
    points: list[list[float]] = []
    for i, entry in enumerate(entries):
        where = f"{path}[{i}]"
        if isinstance(entry, list):
            points.append(entry)
            continue
        if not points:
            raise JobError(where, "an arc needs a point before it to start from")
        start, end = points[-1], entry.arc_to
        if entry.radius is None and entry.center is None:
            raise JobError(where, "an arc needs a radius or a center")
        chord = ((end[0] - start[0]) ** 2 + (end[1] - start[1]) ** 2) ** 0.5
        if chord <= 1.0e-12:
            raise JobError(f"{where}.arc_to", "is the previous point: an arc needs two different ends")
        if entry.radius is not None and abs(entry.radius) < chord / 2.0 - 1.0e-12:
            raise JobError(f"{where}.radius", f"{_mm(abs(entry.radius))} is shorter than half the chord "
                           f"({_mm(chord / 2.0)}) from the previous point")
        if entry.center is not None:
            c = entry.center
            rs = ((start[0] - c[0]) ** 2 + (start[1] - c[1]) ** 2) ** 0.5
            re_ = ((end[0] - c[0]) ** 2 + (end[1] - c[1]) ** 2) ** 0.5
            if abs(rs - re_) > 1.0e-9 * max(rs, 1.0):
                raise JobError(f"{where}.center", f"not equally far from the arc's start ({_mm(rs)}) and "
                               f"end ({_mm(re_)})")
            if entry.radius is not None and abs(abs(entry.radius) - rs) > 1.0e-9 * max(rs, 1.0):
                raise JobError(f"{where}.radius", f"{_mm(abs(entry.radius))} does not match the center "
                               f"({_mm(rs)} away)")
        try:
            arc = arc_points(tuple(start), tuple(end), None if entry.center is None else tuple(entry.center),
                             entry.radius, CHORD_TOLERANCE)
        except ArcError as err:
            raise JobError(f"{where}.center" if "half circle" in str(err) else where,
                           str(err).removeprefix("arc: ")) from err
        for (z0, _), (z1, x1) in zip(arc, arc[1:]):
            if z1 > z0 + 1.0e-12:
                raise JobError(where, "the arc turns back in z (outlines run right to left, z decreasing)")
        for z, x in arc[1:]:
            points.append([min(z, points[-1][0]), x])  # a vertical tangent may carry float noise
        points[-1] = list(end)
    if len(points) > MAX_LIST:
        raise JobError(path, f"has {len(points)} points with the arcs expanded, more than the maximum {MAX_LIST}")
    return points


def _check_drill(d: SimpleNamespace, vibration: SimpleNamespace | None) -> None:
    """Per-hole values spelled out: ``holes`` becomes [x, y] points and ``hole_planes`` the
    (surface_z, depth) of each hole; pecks, clearance and obstacles checked against them."""
    points, planes = [], []
    for i, hole in enumerate(d.holes):
        if isinstance(hole, list):
            points.append(hole)
            planes.append((d.surface_z, d.depth))
        else:
            points.append(hole.at)
            planes.append((d.surface_z if hole.surface_z is None else hole.surface_z,
                           d.depth if hole.depth is None else hole.depth))
    d.holes, d.hole_planes = points, planes
    top = max(surface for surface, _ in planes) + d.r_gap
    if d.clearance_z is not None and d.clearance_z < top - 1e-12:
        raise JobError("drill.clearance_z", f"{_mm(d.clearance_z)} lies below the highest R plane ({_mm(top)})")
    for k, (x0, y0, x1, y1, _) in enumerate(d.obstacles or []):
        if not (x0 < x1 and y0 < y1):
            raise JobError(f"drill.obstacles[{k}]", "needs x0 < x1 and y0 < y1")
        for i, (x, y) in enumerate(points):
            if x0 <= x <= x1 and y0 <= y <= y1:
                raise JobError(f"drill.obstacles[{k}]", f"covers drill.holes[{i}]")
    if d.peck is not None:
        if vibration is not None:
            raise JobError("drill.peck", "the vibration breaks the chip without pecking: give one of them")
        if d.peck.full_every is not None and d.peck.retract != "break":
            raise JobError("drill.peck.full_every", "only chip-break pecks (retract: break) retract fully every N")


def _check_kind(job: SimpleNamespace) -> None:
    """Cross-field rules that a field-by-field check cannot see."""
    kind = job.kind
    if getattr(job, kind) is None:
        raise JobError(kind, f"required for kind '{kind}'")
    for other in KINDS:
        if other != kind and getattr(job, other) is not None:
            raise JobError(other, f"not allowed in a '{kind}' job")
    if 0.0 < job.spindle_rpm < rpm(MIN_RPM):
        raise JobError("spindle_rpm", f"must be 0 (spindle off) or at least {MIN_RPM:g} rpm")
    if kind in NEEDS_SPINDLE and job.spindle_rpm <= 0.0:
        raise JobError("spindle_rpm", f"must be > 0 for a {kind} job")
    if kind == "move":
        for i, move in enumerate(job.move):
            given = [k for k in ("rapid", "linear", "dwell") if getattr(move, k) is not None]
            if len(given) != 1:
                raise JobError(f"move[{i}]", "needs exactly one of rapid, linear, dwell")
            if move.linear is not None and move.feed is None:
                raise JobError(f"move[{i}].feed", "required for a linear move")
            if move.linear is None and move.feed is not None:
                raise JobError(f"move[{i}].feed", "only a linear move takes a feed")
            if given[0] != "dwell" and not any(v is not None for v in vars(getattr(move, given[0])).values()):
                raise JobError(f"move[{i}].{given[0]}", "names no axis")
    vib = job.vibration
    if vib is not None:
        if vib.D is None and (vib.E is None or vib.R is None):
            raise JobError("vibration", "give D, or E and R (for D < 1)")
        if vib.D is not None and (vib.E is not None or vib.R is not None):
            raise JobError("vibration", "give either D or E and R, not both")
        if vib.E is not None and vib.R is not None and vib.R >= vib.E:
            raise JobError("vibration.R", "revolutions in retreat must be fewer than E")
        if vib.D is not None and vib.Q is None:
            raise JobError("vibration.Q", "required with D (amplitude = Q * feed per rev)")
        if vib.Q is None and not 2.0 * vib.R < vib.E:
            raise JobError("vibration.R", f"without Q the forward stroke and the retreat run at equal speed, "
                                          f"which needs R < E/2 = {vib.E / 2:g}; give Q as well")
        if kind == "move" and job.spindle_rpm <= 0.0:
            raise JobError("spindle_rpm", "must be > 0 when a vibration is given")
    if kind == "drill":
        _check_drill(job.drill, job.vibration)
    if kind == "turn":
        job.turn.stock = expand_outline(job.turn.stock, "turn.stock")
        job.turn.profile = expand_outline(job.turn.profile, "turn.profile")
    if kind == "thread":
        t = job.thread
        if t.depths is not None:
            if any(b <= a for a, b in zip(t.depths, t.depths[1:])):
                raise JobError("thread.depths", "cumulative depths must increase")
            if abs(t.depths[-1] - t.depth) > 1e-9:
                raise JobError("thread.depths", "the last depth must equal thread.depth")
        if not t.internal and t.depth >= t.major_radius:
            raise JobError("thread.depth", "must be smaller than major_radius")
        if t.end_z >= t.start_z:
            raise JobError("thread.end_z", "must lie left of start_z (smaller z)")
    if kind == "path" and job.path.tool_axis is not None and len(job.path.tool_axis) != len(job.path.points):
        raise JobError("path.tool_axis", "needs one vector per point")


def _given(doc: dict, dotted: str) -> bool:
    """Whether the raw document gives a value (not null) at a dotted key path."""
    node: Any = doc
    for key in dotted.split("."):
        if not isinstance(node, dict) or node.get(key) is None:
            return False
        node = node[key]
    return True


def _check_unused(doc: dict, job: SimpleNamespace) -> None:
    """A key the job's kind does not use is an error naming it: nothing given is ignored."""
    for key in UNUSED_KEYS[job.kind]:
        if _given(doc, key):
            raise JobError(key, f"not used by a {job.kind} job: {UNUSED_WHY[key]}")
    if job.tool.diameter == 0.0 and job.kind not in LATHE_KINDS:
        raise JobError("tool.diameter", f"must be > 0 mm for a {job.kind} job (0, D0, is a lathe tool's)")
    if job.kind == "drill" and job.drill.overlap == "off":
        for key, why in OVERLAP_ONLY.items():
            if _given(doc, f"drill.{key}"):
                raise JobError(f"drill.{key}", f"not used: {why}")


def parse_job(doc: Any) -> SimpleNamespace:
    """Validate a whole job document and return it in SI units.

    Args:
        doc: the decoded document (a dict), as from JSON or YAML.

    Raises:
        JobError: names the first offending field and the reason.
    """
    job = JOB.check(doc, "")
    _check_kind(job)
    _check_unused(doc, job)
    return job


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """JSON objects with a key given twice are refused: which value was meant is unknown."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


class _DuplicateKey(ValueError):
    pass


def decode_job(text: str) -> Any:
    """Decode a job_goal message (JSON); a decode error is a JobError too.

    JSON's ``NaN`` and ``Infinity`` tokens decode (the schema then names the field that
    holds one); a key given twice in one object, nesting too deep and integers too long
    to convert are decode errors.
    """
    try:
        return json.loads(text, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as err:
        raise JobError("", f"not valid JSON ({err.msg} at line {err.lineno} column {err.colno})") from err
    except _DuplicateKey as err:
        raise JobError("", f"not valid JSON (key {show(err.args[0])} given twice in one object)") from err
    except RecursionError as err:
        raise JobError("", "not valid JSON (nested too deep)") from err
    except ValueError as err:  # e.g. an integer literal beyond Python's digit limit
        raise JobError("", f"not valid JSON ({str(err).split(':')[0][:80]})") from err


def load_job_file(path: str | Path) -> dict:
    """Read a job document from a YAML or JSON file, as the CLI accepts them.

    Raises:
        JobError: the file is missing or not a YAML/JSON mapping.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise JobError("", f"cannot read job file {path}: {err.strerror}") from err
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise JobError("", f"job file {path} is not valid YAML/JSON ({err})") from err
    except RecursionError as err:
        raise JobError("", f"job file {path} is not valid YAML/JSON (nested too deep)") from err
    if not isinstance(doc, dict):
        raise JobError("", f"job file {path} must hold a mapping")
    return doc


def load_job(job: dict | str | Path) -> dict:
    """A job document from a dict, YAML/JSON text or a file path, validated whole.

    A string holding a newline, a '{' first or a 'key: value' pair is document text;
    any other string is a file path.

    Raises:
        JobError: names the offending field and the reason (or the unreadable file).
    """
    if isinstance(job, Path):
        doc = load_job_file(job)
    elif isinstance(job, str):
        text = job.strip()
        if "\n" in text or text.startswith("{") or ": " in text:
            try:
                doc = yaml.safe_load(text)
            except yaml.YAMLError as err:
                raise JobError("", f"job text is not valid YAML/JSON ({err})") from err
        else:
            doc = load_job_file(text)
    else:
        doc = job
    if not isinstance(doc, dict):
        raise JobError("", "a job document must be a mapping")
    parse_job(doc)
    return doc


def job_id_of(doc: Any) -> str:
    """The job_id of a document even if it is invalid, for status messages."""
    if isinstance(doc, dict) and isinstance(doc.get("job_id"), str):
        # printable and encodable (a lone surrogate from a \ud800 escape is not), so that
        # the status and the log line carrying it cannot fail
        job_id = doc["job_id"][:64]
        if not job_id.isprintable():
            job_id = job_id.encode("unicode_escape").decode("ascii")[:64]
        return job_id.encode("utf-8", "backslashreplace").decode("utf-8")
    return ""
