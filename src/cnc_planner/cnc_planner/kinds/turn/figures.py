"""The turn figure: roughing passes on feedback over the stock and the profile, feed
moves told from air moves."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cnc_msgs_py.machine import Machine

from cnc_analysis.recording import Run

from cnc_planner.drawing import FEEDBACK, MM, plt, recording_note, stride
from cnc_planner.kinds.turn.outline import allowances, offset_outline
from cnc_planner.kinds.turn.roughing import plan_of
from cnc_planner.kinematics import Kinematics


LOOKAHEAD_MOVES = 3  # planned moves a feedback sample may be matched to: lag cuts short moves
CAPTIONS = {  # figure file stem -> what the report page says under it
    "turn_passes": "Roughing passes over the stock outline and the final profile (X radius over Z), on feedback.",
}


def _turn_passes(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray) -> plt.Figure:
    """Stock, part and the tool tip on feedback, true to scale: each feedback sample takes the
    kind (feed or rapid) of the planned move it executes, so cutting and air moves read apart."""
    tj = job.turn
    stock, profile = [tuple(p) for p in tj.stock], [tuple(p) for p in tj.profile]
    plan = plan_of(tj)
    segments, frame = plan.job_segments(), plan.frame
    kin = Kinematics(machine, job.setup, job.tool)
    fb = run.feedback[window][stride(int(window.sum()))]
    radius, axial = kin.tip_radius_z(fb[:, run.column("x")], fb[:, run.column("z")])
    tip = np.stack([axial, radius], axis=1)
    # the rapid from wherever the job found the tool to the cycle's start point comes first
    starts = np.array([tip[0]] + [a for a, _ in segments])
    ends = np.array([tuple(tj.origin)] + [m.end for _, m in segments])
    feed = np.array([False] + [m.kind == "feed" for _, m in segments])
    feed_of_sample = feed[_follow_moves(tip, starts, ends)]
    z, r = tip[:, 0] * MM, tip[:, 1] * MM
    z_span = max(z.max(), *(p[0] * MM for p in stock)) - min(z.min(), *(p[0] * MM for p in stock))
    r_span = max(r.max(), max(p[1] for p in stock) * MM)
    floor = min(0.0, *(frame.to_cycle(*q)[1] for q in stock + profile))  # the axis, or a face's depth

    def area(outline: list[tuple[float, float]]) -> np.ndarray:
        """The region under the outline in the cycle's axes (down to the axis outside), drawn in z, x."""
        cycle = [frame.to_cycle(*q) for q in outline]
        ring = [(cycle[0][0], floor), *cycle, (cycle[-1][0], floor)]
        return np.array([frame.to_job(u, v) for u, v in ring]) * MM

    fig, ax = plt.subplots(figsize=(12, float(np.clip(8.5 * r_span / z_span + 1.4, 3.8, 9.0))))
    ax.fill(*area(stock).T, color="tan", alpha=0.45, lw=1, ec="saddlebrown", label="stock before roughing")
    ax.fill(*area(profile).T, color="0.7", lw=1, ec="0.3", label="final profile")
    offset = offset_outline([frame.to_cycle(*q) for q in profile], *allowances(frame, tj.finish_allowance,
                                                                                tj.finish_allowance_z))
    allowance = np.array([frame.to_job(*q) for q in offset]) * MM
    ax.plot(allowance[:, 0], allowance[:, 1], color="0.2", ls="--", lw=0.9,
            label=f"profile + allowance {tj.finish_allowance * MM:.2f} mm (X), {tj.finish_allowance_z * MM:.2f} mm (Z)")
    ax.plot(z, np.where(~feed_of_sample, r, np.nan), color="tab:blue", lw=0.9, ls="--", label="rapid (air)")
    ax.plot(z, np.where(feed_of_sample, r, np.nan), color=FEEDBACK, lw=1.8, label="cutting feed")
    ax.plot(*(np.array(tj.origin) * MM), "ko", ms=5, label="start point")
    ax.axhline(0.0, color="0.4", lw=0.8, ls="-.")
    ax.set_aspect("equal")
    ax.set_xlabel("Z (mm)")
    ax.set_ylabel("X radius (mm)")
    ax.grid(alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8)
    ax.set_title(f"{job.job_id}: roughing passes on feedback, {plan.passes} planned{recording_note(run)}",
                 fontsize=11)
    fig.tight_layout()
    return fig


def _follow_moves(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Index of the planned move each sample (in time order) executes: the nearest of the
    current move and the next ones, never going back, so that a rapid crossing an earlier
    pass line stays a rapid."""
    distance = _segment_distance(points, starts, ends)
    index = np.empty(len(points), dtype=int)
    k = 0
    for i, row in enumerate(distance):
        k += int(np.argmin(row[k:k + LOOKAHEAD_MOVES]))
        index[i] = k
    return index


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 2) to each segment a[k]-b[k]: shape (n, m)."""
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=1), 1e-24)
    share = np.clip(np.einsum("nmk,mk->nm", points[:, None, :] - a[None], ab) / length2, 0.0, 1.0)
    nearest = a[None] + share[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2)


def draw(run: Run, job: SimpleNamespace, machine: Machine, window: np.ndarray, report: dict) -> list[tuple]:
    """The turn job's figure: (figure, file name) pairs."""
    return [(_turn_passes(run, job, machine, window), "turn_passes.png")]
