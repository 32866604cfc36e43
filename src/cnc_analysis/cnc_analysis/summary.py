"""Figures every run gets, computed from a recording alone: what the feedback did.

Cycle time runs from the first to the last motion of the linear axes on feedback;
following error compares the setpoint executed at an instant with the encoder reading
published for that same instant; a lost chunk is a gap in the setpoint stream while
the axes were still moving; the stream's lead is how far the setpoints already received
reached beyond the moment the next chunk arrived.
"""
from __future__ import annotations

import numpy as np

from .recording import Run

MOTION_THRESHOLD = 1e-7  # m per sample: below this an axis counts as standing


def cycle_time(run: Run, axes: tuple[str, ...]) -> float:
    """First to last axis motion on feedback (s); 0 if nothing moved."""
    if len(run.feedback_t) < 2:
        return 0.0
    cols = [run.column(a) for a in axes if a in run.joints]
    steps = np.abs(np.diff(run.feedback[:, cols], axis=0)).max(axis=1)
    moving = np.flatnonzero(steps > MOTION_THRESHOLD)
    if len(moving) == 0:
        return 0.0
    return float(run.feedback_t[moving[-1] + 1] - run.feedback_t[moving[0]])


def following_error(run: Run) -> dict[str, float]:
    """Max |command - feedback| per joint at the instants both exist (SI units)."""
    if len(run.command_t) == 0 or len(run.feedback_t) == 0:
        return {j: 0.0 for j in run.joints}
    inside = (run.feedback_t >= run.command_t[0]) & (run.feedback_t <= run.command_t[-1])
    t = run.feedback_t[inside]
    out = {}
    for j, name in enumerate(run.joints):
        command = np.interp(t, run.command_t, run.command[:, j])
        out[name] = float(np.max(np.abs(command - run.feedback[inside, j]))) if len(t) else 0.0
    return out


def chunks_lost(run: Run) -> int:
    """Gaps in the setpoint stream after a chunk that ended in motion."""
    lost = 0
    for prev, nxt in zip(run.chunks, run.chunks[1:]):
        period = (prev.end_ns - prev.stamp_ns) // max(prev.points - 1, 1)
        if prev.moving_at_end and nxt.stamp_ns > prev.end_ns + period + period // 2:
            lost += 1
    return lost


def stream_leads(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """When each chunk after the first arrived (s, bag time) and how far the setpoints
    received before it still reached beyond that moment (s): the margin the stream had
    left. A lead at or below 0 is a buffer that ran dry (or would have, moving). Every
    chunk ends the buffer: it follows what was there or replaces it from its first stamp."""
    if len(run.chunks) < 2:
        return np.zeros(0), np.zeros(0)
    received = np.array([c.received_ns for c in run.chunks], dtype=np.int64)
    reach = np.array([c.end_ns for c in run.chunks], dtype=np.int64)
    return received[1:] / 1e9, (reach[:-1] - received[1:]) / 1e9
