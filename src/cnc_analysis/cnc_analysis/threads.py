"""Thread-cutting analysis from sampled positions only (a bag's commands or feedback).

A thread is judged in its groove coordinates. The tool's radial depth below the stock
surface (a cylinder, or on a taper thread a cone: radius major_radius at the face,
changing by taper/2 per unit of length, growing into an external part and shrinking into
a bore) is read from x and z; its groove coordinate g is the axial position of the nominal
groove line under it, g = z - (depth * tan(infeed_angle)) along the feed, so moving along
the infeed line (the flank) leaves g unchanged. On a synchronised pass g advances exactly
one lead per spindle revolution; that is how passes are found without any planner event.
Each start of a multi-start thread is its own groove: the spindle phase at which a pass's
helix crosses a given g tells which.

Material per groove is an envelope over g: the deepest depth any earlier pass reached
there, the stock surface (depth 0) before the first. A pass cuts wherever it goes deeper
than that envelope by more than CUT_TOLERANCE; a chip is a continuous cutting stretch,
measured in spindle revolutions (one lead of g). Everything is judged on the thread
between the face z=0 and end_z; the ramp before the face and the pull-out past end_z cut
air or a relief groove. Tapered ends (the job's end_taper: G76's E and L) are left out
too: there the tool ramps out of its depth on purpose, over end_taper.length of groove.

The helix residual is what is left of the tool's axial position after the helix (one lead
per revolution, its phase fitted once for all passes) and the flank offset
depth * tan(infeed_angle) are taken off: lead error, phase drift between passes and
servo lag all show up in it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.kinds.thread import tapered_ends
from cnc_msgs_py.units import deg, mm, to_mm

from .aircut import CHIP_LIMIT_REVS
from .verdict import OVERCUT_LIMIT

TWO_PI = 2.0 * math.pi
CUT_TOLERANCE = 0.5e-6  # m: deeper than the envelope by more than this is cutting
CUTTING_PASS = 0.05e-3  # m: a pass whose depth of cut exceeds this must break its chips
DEPTH_TOLERANCE = 0.02e-3  # m: full depth reached and never exceeded within this
FLANK_TOLERANCE = DEPTH_TOLERANCE  # m: the tool's axial distance from its flank line, held as the depth
# m: a thread short of its depth by more than this fails. The planner raises the passes by
# the overcut of the deepest drive inside the tolerance (22 um on the soft lathe); a 6g
# M12x1.75's pitch diameter is toleranced 150 um wide.
SHORT_LIMIT = 0.05e-3
POINTS_PER_REV = 720  # groove grid: 0.5 deg of helix
SYNC_TOLERANCE = 0.02  # share of the lead: g advancing at lead/rev within this is synchronised
SYNC_WINDOW = 0.1  # rad of spindle over which the lead per revolution is measured
SYNC_COUNTS = 2.0  # encoder counts of error the lead measurement tolerates
MIN_SYNC_REVS = 0.5  # shorter synchronised stretches are not passes
MIN_AMPLITUDE = 1e-6  # m: a depth oscillation smaller than this is no vibration
FFT_OVERSAMPLING = 16
FREQUENCY_ROUNDS = 6  # least-squares refinement: 11 candidates, each round 5x narrower


@dataclass(frozen=True)
class Groove:
    """Thread geometry in SI, from the job's thread block (mm, deg)."""

    start_z: float
    end_z: float
    major_radius: float
    lead: float
    depth: float
    infeed_angle: float
    starts: int
    internal: bool
    taper: float = 0.0  # diameter per length into the part: the surface is a cone
    taper_length: float = 0.0  # groove length of each tapered end (end_taper.length)
    taper_entry: bool = False  # the tool ramps in from start_z (end_taper.ends entry or both)
    taper_exit: bool = False  # the tool ramps out to end_z (exit or both)

    @classmethod
    def from_job(cls, thread: dict) -> Groove:
        """Only the geometric keys are read; pass counts and depths are found in the data."""
        ends = thread.get("end_taper") or {"length": 0.0, "ends": None}
        entry, exit_ = tapered_ends(ends["ends"])
        return cls(
            start_z=mm(thread["start_z"]),
            end_z=mm(thread["end_z"]),
            major_radius=mm(thread["major_radius"]),
            lead=mm(thread["pitch"]),
            depth=mm(thread["depth"]),
            infeed_angle=deg(thread.get("infeed_angle", 29.5)),
            starts=int(thread.get("starts", 1)),
            internal=bool(thread.get("internal", False)),
            taper=float(thread.get("taper", 0.0)),
            taper_length=mm(ends["length"]),
            taper_entry=entry,
            taper_exit=exit_,
        )

    @property
    def direction(self) -> float:
        """+1 or -1: the way z runs from start_z to end_z (the feed)."""
        return math.copysign(1.0, self.end_z - self.start_z)

    @property
    def radial(self) -> float:
        """x per unit of depth: -1 external (into the stock), +1 internal (out of the bore)."""
        return 1.0 if self.internal else -1.0

    def span(self) -> tuple[float, float]:
        """The judged thread along the feed (s * g): from the face, or past an entry taper, to
        end_z, or where an exit taper begins. A ramp lifts the tool by r, which the reading of g
        (z less the flank offset of the depth read) takes as r * tan(infeed_angle) further
        along the feed: so an exit ramp is read past its start and needs no margin, an entry
        ramp up to depth * tan(infeed_angle) past its end, which is left out with it."""
        s, lo = self.direction, 0.0
        if self.taper_entry:
            lo = max(lo, s * self.start_z + self.taper_length + self.depth * math.tan(self.infeed_angle))
        return lo, s * self.end_z - (self.taper_length if self.taper_exit else 0.0)

    def grid(self) -> np.ndarray:
        """Groove coordinates g over the judged thread (span), POINTS_PER_REV per lead."""
        lo, hi = self.span()
        revs = max(hi - lo, 0.0) / self.lead
        return self.direction * (lo + self.lead * np.linspace(0.0, revs, math.ceil(revs * POINTS_PER_REV) + 1))


def cuts_against_envelope(depths: np.ndarray, surface: np.ndarray | None = None) -> np.ndarray:
    """Per pass (rows, in cutting order, one groove): how much deeper than every earlier
    pass and the surface (depth 0 unless given) the tool goes at each grid point (m).
    NaN (not covered) neither cuts nor leaves material."""
    envelope = np.zeros(depths.shape[1]) if surface is None else surface.copy()
    cuts = np.empty_like(depths)
    for k, row in enumerate(depths):
        cuts[k] = row - envelope
        envelope = np.fmax(envelope, row)
    return cuts


def longest_runs(mask: np.ndarray) -> np.ndarray:
    """Longest run of True per row of a 2-d boolean array, in grid points."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    change = np.diff(padded, axis=1)
    out = np.zeros(mask.shape[0], dtype=int)
    for k in range(mask.shape[0]):
        starts, ends = np.flatnonzero(change[k] == 1), np.flatnonzero(change[k] == -1)
        if starts.size:
            out[k] = int(np.max(ends - starts))
    return out


def _sync_segments(theta: np.ndarray, g: np.ndarray, groove: Groove, quantum: float) -> list[tuple[int, int]]:
    """Index ranges [i0, i1] of passes: synchronised stretches (g advancing one lead per
    revolution) grown to the whole run over which g keeps advancing. The lead is measured
    over SYNC_WINDOW of spindle, or longer on a coarse encoder (``quantum``, m), so that
    its counts cannot make a synchronised stretch look out of step."""
    steps = np.diff(theta)
    turning = steps[steps > 0]
    if turning.size == 0:
        return []
    window = max(SYNC_WINDOW, TWO_PI * SYNC_COUNTS * quantum / (SYNC_TOLERANCE * groove.lead))
    w = max(1, math.ceil(window / float(np.median(turning))))
    n = theta.size
    lo, hi = np.clip(np.arange(n) - w, 0, n - 1), np.clip(np.arange(n) + w, 0, n - 1)
    dtheta = theta[hi] - theta[lo]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (g[hi] - g[lo]) * TWO_PI / (groove.direction * groove.lead * dtheta)
    sync = (dtheta > 0) & (np.abs(ratio - 1.0) < SYNC_TOLERANCE)
    change = np.diff(np.concatenate(([0], sync.astype(np.int8), [0])))
    advancing = groove.direction * np.diff(g) > 0
    segments = []
    for i0, i1 in zip(np.flatnonzero(change == 1), np.flatnonzero(change == -1) - 1):
        if theta[i1] - theta[i0] < MIN_SYNC_REVS * TWO_PI:
            continue
        while i0 > 0 and advancing[i0 - 1]:
            i0 -= 1
        while i1 < n - 1 and advancing[i1]:
            i1 += 1
        if segments and i0 <= segments[-1][1]:  # one pass seen twice through a glitch
            segments[-1] = (segments[-1][0], max(i1, segments[-1][1]))
        else:
            segments.append((int(i0), int(i1)))
    return segments


def _wrap(value: np.ndarray | float, period: float) -> np.ndarray:
    """Into [-period/2, period/2)."""
    return np.mod(np.asarray(value) + period / 2, period) - period / 2


def _vibration(psi: np.ndarray, depth: np.ndarray) -> tuple[float, float, float] | None:
    """Vibrations per revolution, phase (deg) and amplitude (m) of a pass's depth along
    the groove; psi in revolutions from start_z. The phase is that of the waveform
    depth = d - A*(1 - cos(2pi*(D*psi + phase)))/2 reversed: 0 deg puts the return point
    (the shallowest depth) at start_z. None if the depth does not oscillate."""
    ok = np.isfinite(depth)
    psi, depth = psi[ok], depth[ok]
    if psi.size < 16 or np.ptp(depth) < MIN_AMPLITUDE:
        return None
    centred = depth - depth.mean()
    step = abs(psi[1] - psi[0])
    n = 1 << (FFT_OVERSAMPLING * psi.size - 1).bit_length()  # zero padding to a power of two
    spectrum = np.abs(np.fft.rfft(centred, n))
    freqs = np.fft.rfftfreq(n, step)
    spectrum[freqs < 2.0 / (psi.size * step)] = 0.0  # slower than two cycles: trend, not vibration
    peak = freqs[int(np.argmax(spectrum))]

    def fit(per_rev: float) -> tuple[float, float, float]:
        """Residual, cos and sin coefficients of depth ~ c + a*cos + b*sin at per_rev."""
        basis = np.stack([np.ones_like(psi), np.cos(TWO_PI * per_rev * psi), np.sin(TWO_PI * per_rev * psi)], 1)
        coef, residual, *_ = np.linalg.lstsq(basis, depth, rcond=None)
        return float(residual[0]) if residual.size else 0.0, coef[1], coef[2]

    # the FFT peak is good to a bin; narrow down on the least-squares residual
    per_rev, width = float(peak), float(freqs[1])
    for _ in range(FREQUENCY_ROUNDS):
        candidates = per_rev + width * np.linspace(-1.0, 1.0, 11)
        per_rev = float(candidates[np.argmin([fit(f)[0] for f in candidates])])
        width /= 5.0
    _, a, b = fit(per_rev)
    amplitude = 2.0 * math.hypot(a, b)
    if amplitude < MIN_AMPLITUDE:
        return None
    return per_rev, math.degrees(math.atan2(b, -a)) % 360.0, amplitude


@dataclass(frozen=True)
class Reading:
    """Samples in groove coordinates: depth below the surface, groove coordinate g, the
    synchronised passes (index ranges) and, on them, the tool's axial offset from the
    nominal helix (depth*tan(infeed_angle) on a perfect cut)."""

    groove: Groove
    t: np.ndarray
    theta: np.ndarray
    depth: np.ndarray
    g: np.ndarray
    segments: list[tuple[int, int]]
    inside: np.ndarray  # on a synchronised pass between the face and end_z
    helix: np.ndarray  # g - lead*theta/2pi
    reference: float  # the helix's phase (m of g at theta = 0), fitted over all passes
    residual: np.ndarray  # helix less its phase fitted over all passes, wrapped to a pitch
    offset: np.ndarray


def read_thread(t: np.ndarray, x: np.ndarray, z: np.ndarray, spindle: np.ndarray, thread: dict) -> Reading:
    """Samples (as analyze_thread takes them) in groove coordinates.

    Raises:
        ValueError: no synchronised pass runs through the thread.
    """
    groove = Groove.from_job(thread)
    t, x, z = (np.asarray(a, dtype=float) for a in (t, x, z))
    theta = np.unwrap(np.asarray(spindle, dtype=float))
    s, lead, tan = groove.direction, groove.lead, math.tan(groove.infeed_angle)
    # depth below the cone's surface, whose radius major + radial*taper/2*g depends on the
    # groove coordinate g = z - s*depth*tan under the tool: solved for depth
    half = groove.taper / 2
    depth = (groove.radial * (x - groove.major_radius) - half * z) / (1.0 - s * tan * half)
    g = z - s * depth * tan
    moves = np.abs(np.diff(z))
    quantum = float(np.min(moves[moves > 0])) if np.any(moves > 0) else 0.0  # the z encoder's count, at most
    segments = _sync_segments(theta, g, groove, quantum)

    # helix: g - lead*theta/2pi is the same for every pass of every start, modulo lead/starts
    pitch = lead / groove.starts
    helix = g - s * lead * theta / TWO_PI
    inside = np.zeros(t.size, dtype=bool)
    for i0, i1 in segments:
        inside[i0 : i1 + 1] = True
    lo, hi = groove.span()
    inside &= (s * g >= lo) & (s * g <= hi)
    if not inside.any():
        raise ValueError("no synchronised pass runs through the thread between z=0 and end_z"
                         " (less its tapered ends)")
    reference = pitch / TWO_PI * float(np.angle(np.mean(np.exp(1j * TWO_PI * helix[inside] / pitch))))
    residual = _wrap(helix - reference, pitch)
    offset = residual + s * depth * tan  # the tool's axial offset from the nominal helix
    return Reading(groove, t, theta, depth, g, segments, inside, helix, reference, residual, offset)


def cross_section(t: np.ndarray, x: np.ndarray, z: np.ndarray, spindle: np.ndarray, thread: dict) -> list[dict]:
    """The groove's cross-section per synchronised pass: where the tool tip went in the
    plane of the thread form (axial offset from the nominal helix along the feed, and depth
    below the surface, both mm; and where along the groove, in revolutions from the face)
    between the face and end_z, in time order; its vibration
    runs along the flank, each pass from above the previous pass's deepest point."""
    r = read_thread(t, x, z, spindle, thread)
    s = r.groove.direction
    out = []
    for i0, i1 in r.segments:
        sel = np.arange(i0, i1 + 1)[r.inside[i0 : i1 + 1]]
        out.append({"index": len(out), "offset_mm": to_mm(s * r.offset[sel]), "depth_mm": to_mm(r.depth[sel]),
                    "groove_revs": s * r.g[sel] / r.groove.lead})
    return out


def analyze_thread(
    t: np.ndarray, x: np.ndarray, z: np.ndarray, spindle: np.ndarray, thread: dict
) -> dict:
    """Judge a cut thread from samples in time order: t (s), x (tool radius, m), z (m) and
    the spindle angle (rad), commanded or measured; thread is the job's thread block
    (mm, deg; only the geometry is read). Returns a JSON-ready dict in mm: per pass depth,
    depth of cut, longest chip, air-cut share, vibration and helix residual; over the whole
    thread the longest chip of the cutting passes, the depth error, the helix residual and
    the measured infeed angle."""
    r = read_thread(t, x, z, spindle, thread)
    groove, t, depth, g, segments, inside = r.groove, r.t, r.depth, r.g, r.segments, r.inside
    helix, reference, residual, offset = r.helix, r.reference, r.residual, r.offset
    s, lead = groove.direction, groove.lead
    pitch = lead / groove.starts
    grid = groove.grid()
    psi = s * (grid - groove.start_z) / lead  # revolutions along the helix from start_z
    # up to one lead before end_z, where the tool pulls out (an exit taper's ramp is left out already)
    full = s * grid <= groove.span()[1] - (0.0 if groove.taper_exit else lead) + 1e-12
    slope = np.polyfit(s * depth[inside], offset[inside], 1)[0]

    # which groove: where each pass's helix lies, in 1/starts of a lead from the first pass's
    shifts = [float(np.median(helix[i0 : i1 + 1][inside[i0 : i1 + 1]])) if inside[i0 : i1 + 1].any()
              else math.nan for i0, i1 in segments]
    base = next(x for x in shifts if math.isfinite(x))
    envelopes = np.zeros((groove.starts, grid.size))
    passes = []
    for (i0, i1), shift in zip(segments, shifts):
        sel = slice(i0, i1 + 1)
        start = round(float(_wrap(shift - base, lead)) / pitch) % groove.starts if math.isfinite(shift) else 0
        order = np.argsort(s * g[sel], kind="stable")
        row = np.interp(s * grid, (s * g[sel])[order], depth[sel][order], left=np.nan, right=np.nan)
        before = envelopes[start].copy()
        cut = cuts_against_envelope(row[None, :], before)[0]
        envelopes[start] = np.fmax(before, row)
        covered = np.isfinite(row)
        cutting = cut > CUT_TOLERANCE
        reached = float(np.nanmax(row)) if covered.any() else float("nan")
        doc = reached - float(np.max(before))
        vib = _vibration(psi, row)
        passes.append({
            "index": len(passes),
            "start": start,
            "t_start": float(t[i0]),
            "t_end": float(t[i1]),
            "coverage": float(covered.mean()),
            "depth_mm": to_mm(reached),
            "doc_mm": to_mm(doc),
            "max_cut_mm": to_mm(float(np.nanmax(np.maximum(cut, 0.0)))) if covered.any() else 0.0,
            "cutting": bool(doc > CUTTING_PASS),
            "max_chip_revs": float(longest_runs(cutting[None, :])[0] / POINTS_PER_REV),
            "aircut_share": float(1.0 - cutting[covered].mean()) if covered.any() else 1.0,
            "vibration_per_rev": None if vib is None else vib[0],
            "vibration_phase_deg": None if vib is None else vib[1],
            "vibration_amplitude_mm": 0.0 if vib is None else to_mm(vib[2]),
            "helix_residual_mm": to_mm(float(np.max(np.abs(residual[sel][inside[sel]]), initial=0.0))),
        })

    cutting_passes = [p for p in passes if p["cutting"]]
    docs = [p["doc_mm"] for p in passes]
    max_chip = max((p["max_chip_revs"] for p in cutting_passes), default=0.0)
    error = np.abs(envelopes[:, full] - groove.depth)
    overcut = float(np.max(envelopes - groove.depth))
    depth_error = float(np.max(error))
    helix_residual = float(np.max(np.abs(residual[inside])))
    return {
        "passes": passes,
        "synchronised_passes": len(passes),
        "cutting_passes": len(cutting_passes),
        "max_chip_revs": max_chip,
        "chips_broken": bool(max_chip <= CHIP_LIMIT_REVS),
        "depth_error_mm": to_mm(depth_error),
        "overcut_mm": to_mm(overcut),
        "full_depth": bool(depth_error <= DEPTH_TOLERANCE and overcut <= DEPTH_TOLERANCE),
        "doc_never_grows": bool(all(b <= a + to_mm(CUT_TOLERANCE) for a, b in zip(docs, docs[1:]))),
        "helix_residual_mm": to_mm(helix_residual),
        "helix_phase_deg": math.degrees(TWO_PI * (groove.start_z - reference) / (s * lead))
        % (360.0 / groove.starts),
        "infeed_angle_deg": math.degrees(math.atan(slope)),
    }


def thread_failures(figures: dict, vibrated: bool) -> list[str]:
    """What fails a thread judged by analyze_thread: cut deeper than its depth by more than
    OVERCUT_LIMIT, short of it by more than SHORT_LIMIT (where nothing is over it by
    DEPTH_TOLERANCE), the tool off its flank line (the helix residual) by more than
    FLANK_TOLERANCE and, for a vibrated thread, a cutting pass's chip longer than
    CHIP_LIMIT_REVS. One phrase per miss."""
    failures = []
    if figures["overcut_mm"] > to_mm(OVERCUT_LIMIT):
        failures.append(f"cut {figures['overcut_mm']:.4f} mm deeper than the thread's depth "
                        f"(limit {to_mm(OVERCUT_LIMIT):g} mm)")
    if figures["depth_error_mm"] > to_mm(SHORT_LIMIT) and figures["overcut_mm"] <= to_mm(DEPTH_TOLERANCE):
        failures.append(f"depth {figures['depth_error_mm']:.4f} mm short of the thread's depth "
                        f"(limit {to_mm(SHORT_LIMIT):g} mm)")
    if figures["helix_residual_mm"] > to_mm(FLANK_TOLERANCE):
        failures.append(f"the tool left its flank line by {figures['helix_residual_mm']:.4f} mm "
                        f"(limit {to_mm(FLANK_TOLERANCE):g} mm)")
    if vibrated and figures["max_chip_revs"] > CHIP_LIMIT_REVS:
        failures.append(f"a chip of {figures['max_chip_revs']:.2f} revolutions (limit {CHIP_LIMIT_REVS:g})")
    return failures
