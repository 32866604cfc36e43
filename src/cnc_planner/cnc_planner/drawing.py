"""Shared by every figure: matplotlib without a display, units and thinning for drawing.

Long runs are thinned for drawing only: min/max buckets keep every peak of a trace.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend is chosen first)
import numpy as np  # noqa: E402

from cnc_msgs_py.units import to_mm  # noqa: E402

from cnc_analysis.recording import Run  # noqa: E402

from cnc_planner.forked import Forked  # noqa: E402

DPI = 110


MM = to_mm(1.0)  # m -> mm, as a scale for plot axes


LINE_POINTS = 4000  # min/max buckets per time trace: peaks survive, drawing stays fast


PATH_POINTS = 20000  # samples per drawn tool path (1 kHz feedback of a smooth path)


TWO_PI = 2.0 * math.pi


LOST_TAIL_S = 0.1  # s: feedback ending this much before the commands did is flagged
FEEDBACK, COMMAND = "tab:red", "0.25"


def save(fig: plt.Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def save_all(figures: list[tuple[plt.Figure, Path]]) -> list[Path]:
    """Render and write the figures, every other one in a forked child process: rendering
    (Agg, PNG) is most of a report's figure time and the figures are independent. What the
    child fails to write is written here."""
    if len(figures) < 2 or not hasattr(os, "fork"):
        return [save(fig, path) for fig, path in figures]
    child = Forked(lambda: [save(fig, path) for fig, path in figures[1::2]])
    for fig, path in figures[0::2]:
        save(fig, path)
    done, _ = child.result()
    for fig, path in figures[1::2]:
        if not done:
            fig.savefig(path, dpi=DPI)
        plt.close(fig)
    return [path for _, path in figures]


def recording_note(run: Run) -> str:
    """A title line warning that the recorded feedback stops before the commands do: whatever
    the figure lacks at its end was not recorded, not left undone."""
    lost = run.command_t[-1] - run.feedback_t[-1]
    return f"\nfeedback recording ends {lost:.1f} s before the last command" if lost > LOST_TAIL_S else ""


def envelope(t: np.ndarray, y: np.ndarray, points: int = LINE_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Min and max per time bucket, so a thinned trace still shows every peak."""
    if len(t) <= points:
        return t, y
    starts = np.linspace(0, len(t), points // 2, endpoint=False).astype(int)
    lo, hi = np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)
    return np.repeat(t[starts], 2), np.stack([lo, hi], axis=1).ravel()


def stride(n: int) -> slice:
    """Every k-th sample of a tool path, at most PATH_POINTS of them."""
    return slice(None, None, max(1, math.ceil(n / PATH_POINTS)))
