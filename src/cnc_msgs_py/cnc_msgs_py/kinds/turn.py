"""Turn jobs: roughing (G71-like) a lathe stock down to a profile, optionally with a finishing pass.

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

The roughing passes cut along ``turn.passes`` (default ``-z``: along Z towards the chuck, as
G71; ``+z``, or ``-x``/``+x``: along X, facing, as G72) and step by the depth of cut along
``turn.infeed``, the other axis (default ``-x``: towards the spindle axis, outside turning;
``+x`` a bore; ``-z``/``+z`` facing). The outlines then run in the passes' direction (z
decreasing for ``-z``, x increasing for ``+x``) and the material lies beyond them in the infeed
direction (under them for ``-x``, above them for a ``+x`` bore). ``Frame`` maps the job's
(z, x) onto the one roughing cycle's own axes, so that every direction is the same cycle.
``turn.pockets``: ``cut`` (G71/G72), ``leave`` (G71.1/G72.1: no pass dips into a pocket, the
contour pass bridges them) or ``only`` (G71.2/G72.2: what ``leave`` left).
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

from ..outline import CHORD_TOLERANCE, ArcError, arc_points
from ..schema import Bool, JobError, List, Num, Obj, PointOr, Str
from .kind import MAX_LIST, THREAD_ONLY_VIBRATION, KindSchema, mm_text

# The smallest values that make sense on a lathe (smaller ones would plan moves lasting years).
MIN_FEED_PER_REV = 0.001  # mm/rev
MIN_DEPTH_OF_CUT = 0.01  # mm, radial
MIN_CLEARANCE = 0.001  # mm

POINT_ZX = List(Num("mm"), length=2)  # [z, radius] on the lathe
ARC_ZX = Obj({"arc_to": POINT_ZX, "radius": Num("mm", default=None), "center": List(Num("mm"), length=2, default=None)})
# A ``[z, radius]`` point, or an arc ``{arc_to, radius and/or center}`` from the previous point.
OUTLINE = List(PointOr(POINT_ZX, ARC_ZX, "a [z, radius] point or an {arc_to: ...} arc"), min_len=2, max_len=MAX_LIST)

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
    "passes": Str(choices=("-z", "+z", "-x", "+x"), default="-z"),
    "infeed": Str(choices=("-x", "+x", "-z", "+z"), default="-x"),
    "pockets": Str(choices=("cut", "leave", "only"), default="cut"),
}, default=None)


@dataclass(frozen=True)
class Frame:
    """The roughing cycle's own axes (u, v) for a job's pass and infeed directions.

    The cycle cuts every pass towards -u and steps from pass to pass towards -v, with the
    material under the outlines: u = -(sign of passes) x (the passes' axis), v = -(sign of
    infeed) x (the infeed's axis). The default (-z, -x) is u = z, v = x exactly, so outside
    turning along Z computes bit for bit as before directions existed.
    """

    passes: str = "-z"
    infeed: str = "-x"

    def __post_init__(self) -> None:
        if self.passes[1] == self.infeed[1]:
            raise JobError("turn.infeed", f"{self.infeed} runs along the passes ({self.passes}): "
                           "it must be along the other axis")

    def _signs(self) -> tuple[float, float]:
        return (-1.0 if self.passes[0] == "+" else 1.0), (-1.0 if self.infeed[0] == "+" else 1.0)

    def to_cycle(self, z: float, x: float) -> tuple[float, float]:
        """(u, v) of a job point (z, x)."""
        su, sv = self._signs()
        p, q = (z, x) if self.passes[1] == "z" else (x, z)
        return su * p, sv * q

    def to_job(self, u: float, v: float) -> tuple[float, float]:
        """(z, x) of a cycle point (u, v)."""
        su, sv = self._signs()
        p, q = su * u, sv * v
        return (p, q) if self.passes[1] == "z" else (q, p)


def frame_of(turn: SimpleNamespace) -> Frame:
    """The cycle's axes for a parsed turn block."""
    return Frame(turn.passes, turn.infeed)


def expand_outline(entries: list, path: str, frame: Frame = Frame()) -> list[list[float]]:
    """The outline's points with every arc expanded into chords (SI); JobError at the arc's path.
    An arc must run on in the passes' direction (frame), as the outline does."""
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
            raise JobError(f"{where}.radius", f"{mm_text(abs(entry.radius))} is shorter than half the chord "
                           f"({mm_text(chord / 2.0)}) from the previous point")
        if entry.center is not None:
            c = entry.center
            rs = ((start[0] - c[0]) ** 2 + (start[1] - c[1]) ** 2) ** 0.5
            re_ = ((end[0] - c[0]) ** 2 + (end[1] - c[1]) ** 2) ** 0.5
            if abs(rs - re_) > 1.0e-9 * max(rs, 1.0):
                raise JobError(f"{where}.center", f"not equally far from the arc's start ({mm_text(rs)}) and "
                               f"end ({mm_text(re_)})")
            if entry.radius is not None and abs(abs(entry.radius) - rs) > 1.0e-9 * max(rs, 1.0):
                raise JobError(f"{where}.radius", f"{mm_text(abs(entry.radius))} does not match the center "
                               f"({mm_text(rs)} away)")
        try:
            arc = arc_points(tuple(start), tuple(end), None if entry.center is None else tuple(entry.center),
                             entry.radius, CHORD_TOLERANCE)
        except ArcError as err:
            raise JobError(f"{where}.{err.key}" if err.key else where, err.reason) from err
        cycle = [frame.to_cycle(z, x) for z, x in arc]
        for (u0, _), (u1, _) in zip(cycle, cycle[1:]):
            if u1 > u0 + 1.0e-12:
                raise JobError(where, f"the arc turns back in {frame.passes[1]} (the outline runs in the passes' "
                                      f"direction, {frame.passes})")
        last = frame.to_cycle(*points[-1])[0]
        for u, v in cycle[1:]:
            last = min(u, last)  # a tangent across the passes may carry float noise
            points.append(list(frame.to_job(last, v)))
        points[-1] = list(end)
    if len(points) > MAX_LIST:
        raise JobError(path, f"has {len(points)} points with the arcs expanded, more than the maximum {MAX_LIST}")
    return points


def check(job: SimpleNamespace) -> None:
    """The stock and the profile as plain point lists, their arcs expanded into chords."""
    frame = frame_of(job.turn)
    job.turn.stock = expand_outline(job.turn.stock, "turn.stock", frame)
    job.turn.profile = expand_outline(job.turn.profile, "turn.profile", frame)


KIND = KindSchema("turn", TURN, check, unused=THREAD_ONLY_VIBRATION, needs_spindle=True, lathe_tool=True)
