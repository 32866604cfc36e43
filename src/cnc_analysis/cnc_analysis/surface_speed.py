"""Constant surface speed (G96) judged on feedback: the cutting speed v = omega * r from the
spindle's measured velocity and the tool tip's measured radius, wherever the tool cuts.

Where it cuts is read from the feedback alone, not from the planner's moves or events: the
tip moves steadily at one of the job's feeds per revolution of the spindle's *measured*
speed, or one of its feeds per minute (within FEED_BAND), for at least MIN_CUT_S. Rapids
pass through such a speed only for a millisecond as they start and stop, so they never
count; a feed per revolution that did not follow the spindle's actual speed would show as
no cutting at all, which fails too.

Where the requested rpm, v / (2 pi r), is at or above the cap (D, or the spindle's limit)
within TOLERANCE, the surface speed cannot be held and is not judged: there the spindle
must only stay at or below the cap. Everywhere else the measured surface speed must be
within TOLERANCE of the request; the rpm must never exceed the cap by more than
CAP_MARGIN, cutting or not.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.units import to_m_per_min, to_mm, to_rpm

from .recording import Run

TOLERANCE = 0.02  # share of the requested surface speed: a tool's life does not notice 2 %
FEED_BAND = 0.25  # the tip's speed within this share of feed per rev x measured rev/s: cutting
MIN_CUT_S = 0.02  # s: steadier than a rapid's start or stop, shorter than any real cut
CAP_MARGIN = 0.001  # share of the cap the measured rpm may exceed it by (its measurement ripple)
CRITERION = (f"on feedback: the surface speed within {100 * TOLERANCE:g} % while cutting where the cap does not "
             f"bind, the rpm never above the cap")


def _steady_runs(mask: np.ndarray, t: np.ndarray, shortest: float) -> np.ndarray:
    """``mask`` with its runs shorter than ``shortest`` (s) cleared."""
    out = np.zeros_like(mask)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        if t[b - 1] - t[a] >= shortest:
            out[a:b] = True
    return out


def judge_surface_speed(t: np.ndarray, radius: np.ndarray, tip_speed: np.ndarray, spindle: np.ndarray,
                        requested: float, cap: float, feeds_per_rev: tuple[float, ...] = (),
                        feeds: tuple[float, ...] = ()) -> dict:
    """The surface speed while cutting, from feedback samples (SI: s, m, m/s, rad/s).

    Args:
        t, radius, tip_speed, spindle: per feedback sample, the time, the tip's radius, the
            tip's path speed and the spindle's velocity.
        requested: the surface speed asked for (m/s); cap: the rpm it may not exceed (rad/s);
        feeds_per_rev: the job's feeds per revolution (m); feeds: its feeds per minute (m/s).

    Returns the figures (m/min, rpm, %; ``feed_per_rev_mm`` the 1st, 50th and 99th percentile
    of the measured feed per revolution while cutting) and ``failures``, one phrase per miss.
    """
    w = np.abs(spindle)
    near = np.zeros(len(t), dtype=bool)
    for feed in [f * w / (2.0 * math.pi) for f in feeds_per_rev] + list(feeds):
        near |= (feed > 0.0) & (np.abs(tip_speed - feed) <= FEED_BAND * feed)
    cutting = _steady_runs(near, t, MIN_CUT_S)
    r = np.abs(radius)
    capped = r * cap <= requested / (1.0 - TOLERANCE)
    held = cutting & ~capped
    surface = w * r
    dt = np.diff(t, append=t[-1]) if len(t) else t
    out = {
        "requested_m_min": round(to_m_per_min(requested), 3),
        "cap_rpm": round(to_rpm(cap), 1),
        "cutting_s": round(float(dt[cutting].sum()), 3),
        "held_s": round(float(dt[held].sum()), 3),
        "capped_s": round(float(dt[cutting & capped].sum()), 3),
        "max_rpm": round(to_rpm(float(w.max())) if len(w) else 0.0, 1),
    }
    if cutting.any() and feeds_per_rev:  # the feed per revolution of the measured speed, as the tip measured it
        per_rev = tip_speed[cutting] / (w[cutting] / (2.0 * math.pi))
        out["feed_per_rev_mm"] = [round(to_mm(float(q)), 4) for q in np.percentile(per_rev, (1, 50, 99))]
    failures = []
    if held.any():
        off = surface[held] / requested - 1.0
        k = int(np.argmax(np.abs(off)))
        out.update(min_m_min=round(to_m_per_min(float(surface[held].min())), 3),
                   max_m_min=round(to_m_per_min(float(surface[held].max())), 3),
                   max_deviation_pct=round(100.0 * float(abs(off[k])), 3),
                   worst_radius_mm=round(to_mm(float(r[held][k])), 3))
        if abs(off[k]) > TOLERANCE:
            failures.append(f"surface speed {100.0 * off[k]:+.2f} % off {to_m_per_min(requested):g} m/min at "
                            f"radius {to_mm(float(r[held][k])):.3f} mm")
    elif not cutting.any() and (feeds_per_rev or feeds):
        failures.append("no cut found at the job's feeds (per revolution of the measured spindle speed)")
    if len(w) and w.max() > cap * (1.0 + CAP_MARGIN):
        failures.append(f"spindle at {to_rpm(float(w.max())):.1f} rpm, above the cap of {to_rpm(cap):.1f} rpm")
    out["failures"] = failures
    return out


def surface_speed_on(run: Run, window: np.ndarray, radius: np.ndarray, css: SimpleNamespace, spindle_limit: float,
                     feeds_per_rev: tuple[float, ...] = (), feeds: tuple[float, ...] = ()) -> dict:
    """judge_surface_speed on a recording's window: ``radius`` the tip's radius there (m), ``css``
    the job's surface_speed (SI), capped by its max_rpm and ``spindle_limit`` (rad/s, the
    machine description's); the tip's speed from the x and z feedback velocities."""
    cap = spindle_limit if css.max_rpm is None else min(css.max_rpm, spindle_limit)
    velocity = run.feedback_velocity[window]
    tip_speed = np.hypot(velocity[:, run.column("x")], velocity[:, run.column("z")])
    return judge_surface_speed(run.feedback_t[window], radius, tip_speed, velocity[:, run.column("spindle")],
                               css.m_min, cap, feeds_per_rev, feeds)
