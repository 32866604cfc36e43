"""Passes locked to the spindle (G33) and rigid taps (G33.1) judged from sampled positions
and the spindle angle only.

A pass runs from rest at its start through straight moves, each advancing its lead K along
its path per spindle revolution, having waited for the spindle's index (angle 0). On each
move the tool's progress along it, u, less K * theta / 2pi (theta the spindle's angle, 0 at
its index) is its offset from an ideal start at an index, taken round a lead (a groove
repeats every lead); once the move runs at its lead that offset is constant (the ramp onto
the lead took its share; nothing after it may change it). Its spread is the lock error.
The passes of one thread (the same first lead and direction) must share that offset on
their first move: each then lies where its programmed start puts it in one groove (a
compound infeed's passes start a flank offset apart on purpose).

A pass is found on the samples alone: the tool at its start, then leaving it (its last
sample within MOVED of it) until it stands at its end. Where a
move runs at its lead is measured as threads.py finds synchronised stretches: the progress
over SYNC_WINDOW of spindle within SYNC_TOLERANCE of one lead per revolution.

A rigid tap is locked from its first sample at its lead going in to its last coming out:
its offset may not change across the spindle's reversal at the bottom, where the spindle
turns too slowly for its lead to be measured, so it comes out along the helix it cut.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_msgs_py.units import to_mm

from .threads import FLANK_TOLERANCE, SYNC_TOLERANCE, SYNC_WINDOW, TWO_PI

AT = 10e-6  # m: the tool this close to a point stands there
MOVED = 1e-6  # m: further than this from the start, the pass has begun
LOCK_TOLERANCE = FLANK_TOLERANCE  # m: the offset from the ideal start held within this, pass to pass too


@dataclass(frozen=True)
class SyncPass:
    """A pass as the job programs it, in the judged coordinates (m): where it starts and each
    move's end and lead (m per revolution along the move)."""

    start: np.ndarray
    ends: list[np.ndarray]
    leads: list[float]


@dataclass(frozen=True)
class Tap:
    """A rigid tap as the job programs it (m): from its start to its bottom and back, at its
    lead (m per revolution)."""

    start: np.ndarray
    bottom: np.ndarray
    lead: float


def _near(positions: np.ndarray, point: np.ndarray, lo: int) -> int | None:
    """The first sample from lo on within AT of point."""
    hits = np.flatnonzero(np.linalg.norm(positions[lo:] - point, axis=1) < AT)
    return lo + int(hits[0]) if hits.size else None


def _begin(positions: np.ndarray, sync: SyncPass, arrive: int) -> int | None:
    """The sample at which the pass leaves its start: past its last sample within MOVED of
    the start before the tool is AT along its first move (a rapid's settling before the
    pass is not its beginning)."""
    direction = sync.ends[0] - sync.start
    progress = (positions[arrive:] - sync.start) @ (direction / np.linalg.norm(direction))
    gone = np.flatnonzero(progress > AT)
    if not gone.size:
        return None
    still = np.flatnonzero(np.linalg.norm(positions[arrive:arrive + gone[0]] - sync.start, axis=1) <= MOVED)
    return arrive + (int(still[-1]) + 1 if still.size else 0)


def _at_lead(theta: np.ndarray, u: np.ndarray, lead: float) -> np.ndarray:
    """Where the progress u runs at one lead per revolution of theta (either way round),
    measured over SYNC_WINDOW of spindle."""
    steps = np.abs(np.diff(theta))
    turning = steps[steps > 0]
    if turning.size == 0:
        return np.zeros(theta.size, dtype=bool)
    w = max(1, math.ceil(SYNC_WINDOW / float(np.median(turning))))
    n = theta.size
    lo, hi = np.clip(np.arange(n) - w, 0, n - 1), np.clip(np.arange(n) + w, 0, n - 1)
    dtheta = theta[hi] - theta[lo]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (u[hi] - u[lo]) * TWO_PI / (lead * dtheta)
    return (dtheta != 0) & (np.abs(ratio - 1.0) < SYNC_TOLERANCE)


def _move(theta: np.ndarray, u: np.ndarray, lead: float, length: float) -> dict | None:
    """One move of a pass: its offset (behind an ideal start at an index, less than a lead),
    lock error and measured lead where it runs at its lead."""
    locked = _at_lead(theta, u, lead) & (u > 0.0) & (u < length)
    if locked.sum() < 2:
        return None
    offset = u[locked] - lead * theta[locked] / TWO_PI
    slope = np.polyfit(theta[locked], u[locked], 1)[0] * TWO_PI
    centre = float(np.median(offset))
    return {"lead_mm": to_mm(lead), "measured_lead_mm": to_mm(float(slope)), "offset_mm": -to_mm(-centre % lead),
            "lock_error_mm": to_mm(float(np.max(np.abs(offset - centre)))),
            "locked_revs": float(np.sum(np.diff(theta[locked])[np.diff(np.flatnonzero(locked)) == 1]) / TWO_PI)}


def judge_passes(t: np.ndarray, positions: np.ndarray, spindle: np.ndarray, passes: list[SyncPass]) -> dict:
    """Each pass's moves on the samples (t, positions (n, axes) in the passes' coordinates,
    spindle angle), found in program order; the groove offset's spread over the passes of
    one thread; the failures (``failures``, one phrase each)."""
    theta = np.unwrap(np.asarray(spindle, dtype=float))
    positions = np.asarray(positions, dtype=float)
    found, failures, cursor = [], [], 0
    for k, sync in enumerate(passes):
        arrive = _near(positions, sync.start, cursor)
        begin = None if arrive is None else _begin(positions, sync, arrive)
        end = None if begin is None else _near(positions, sync.ends[-1], begin)
        if end is None:
            failures.append(f"pass {k} never ran from its start to its end")
            continue
        cursor = end
        part = slice(arrive, end + 1)
        moves, here = [], sync.start
        for j, (point, lead) in enumerate(zip(sync.ends, sync.leads)):
            length = float(np.linalg.norm(point - here))
            direction = (point - here) / length
            judged = _move(theta[part], (positions[part] - here) @ direction, lead, length)
            if judged is None:
                failures.append(f"pass {k} move {j} never ran at its lead")
            else:
                moves.append({"move": j, **judged})
                if judged["lock_error_mm"] > to_mm(LOCK_TOLERANCE):
                    failures.append(f"pass {k} move {j} strays {judged['lock_error_mm']:.4f} mm from its lock")
            here = point
        found.append({"index": k, "t_start": float(t[begin]), "t_end": float(t[end]), "moves": moves,
                      "thread": _thread_of(sync)})
    spread = _groove_spread(found)
    if spread > to_mm(LOCK_TOLERANCE):
        failures.append(f"the passes of a thread lie {spread:.4f} mm apart in their groove")
    errors = [m["lock_error_mm"] for p in found for m in p["moves"]]
    return {"passes": found, "groove_spread_mm": spread, "max_lock_error_mm": max(errors, default=0.0),
            "failures": failures}


def _thread_of(sync: SyncPass) -> list[float]:
    """What makes passes one thread's: the first move's lead and direction (rounded: keys)."""
    direction = (sync.ends[0] - sync.start) / np.linalg.norm(sync.ends[0] - sync.start)
    return [round(sync.leads[0], 12), *np.round(direction, 9).tolist()]


def _groove_spread(found: list[dict]) -> float:
    """The largest spread (mm) of the first move's offset over the passes of one thread, a
    groove being one lead round: offsets a lead apart are one groove."""
    groups: dict[tuple, list[float]] = {}
    for p in found:
        if p["moves"] and p["moves"][0]["move"] == 0:
            groups.setdefault(tuple(p["thread"]), []).append(p["moves"][0]["offset_mm"])
    spreads = []
    for (lead, *_), offsets in groups.items():
        period = to_mm(lead)
        around = (np.array(offsets) - offsets[0] + period / 2) % period - period / 2  # from the first, within half a lead
        spreads.append(float(np.ptp(around)))
    return max(spreads, default=0.0)


def judge_taps(t: np.ndarray, positions: np.ndarray, spindle: np.ndarray, taps: list[Tap]) -> dict:
    """Each tap on the samples, found in program order: its lock from the first sample at its
    lead going in to the last coming out, the spindle's reversal between (the offset must
    not change across it: out along the helix it cut going in), the lead measured in and
    out, and how deep it went; the failures (``failures``)."""
    theta = np.unwrap(np.asarray(spindle, dtype=float))
    positions = np.asarray(positions, dtype=float)
    found, failures, cursor = [], [], 0
    for k, tap in enumerate(taps):
        depth = float(np.linalg.norm(tap.bottom - tap.start))
        direction = (tap.bottom - tap.start) / depth
        arrive = _near(positions, tap.start, cursor)
        u = None if arrive is None else (positions[arrive:] - tap.start) @ direction
        deepest = None if u is None or not np.any(u > depth / 2) else arrive + int(np.argmax(u > depth / 2))
        end = None if deepest is None else _near(positions, tap.start, deepest)
        if end is None:
            failures.append(f"tap {k} never went in and back out to its start")
            continue
        cursor = end
        part = slice(arrive, end + 1)
        u, th = u[: end + 1 - arrive], theta[part]
        at_lead = np.flatnonzero(_at_lead(th, u, tap.lead) & (u > 0.0))
        bottom = int(np.argmax(u))
        going_in, coming_out = at_lead[at_lead < bottom], at_lead[at_lead > bottom]
        if going_in.size < 2 or coming_out.size < 2:
            failures.append(f"tap {k} never ran at its lead both ways")
            continue
        locked = slice(int(going_in[0]), int(coming_out[-1]) + 1)
        offset = u[locked] - tap.lead * th[locked] / TWO_PI
        centre = float(np.median(offset))

        def lead_of(i: np.ndarray) -> float:
            return to_mm(float(np.polyfit(th[i], u[i], 1)[0]) * TWO_PI)

        entry = {"index": k, "t_start": float(t[arrive]), "t_end": float(t[end]), "lead_mm": to_mm(tap.lead),
                 "measured_lead_in_mm": lead_of(going_in), "measured_lead_out_mm": lead_of(coming_out),
                 "depth_mm": to_mm(depth), "reached_mm": to_mm(float(u[bottom])),
                 "reversed_rpm": float(np.min(np.gradient(th, t[part]))) * 60.0 / TWO_PI,  # < 0: it turned back
                 "lock_error_mm": to_mm(float(np.max(np.abs(offset - centre))))}
        found.append(entry)
        if entry["lock_error_mm"] > to_mm(LOCK_TOLERANCE):
            failures.append(f"tap {k} strays {entry['lock_error_mm']:.4f} mm from its lock")
        if abs(entry["reached_mm"] - entry["depth_mm"]) > to_mm(LOCK_TOLERANCE):
            failures.append(f"tap {k} reached {entry['reached_mm']:.4f} of {entry['depth_mm']:.4f} mm")
    return {"taps": found, "failures": failures}
