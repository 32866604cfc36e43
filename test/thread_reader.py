"""An independent reading of a thread job's bag: nothing from this project is imported.

Only the recording is used: the job document published on /cnc/job_goal (JSON, mm and deg)
and the measured axes on /cnc/joint_states (x = tool radius in m, z in m, spindle in rad).
The method is deliberately plain and differs from the project's thread_analysis:

* Helix constant.  On a synchronised pass the tool follows z = c + s*lead*rev + s*depth*tan(a)
  (s = +1/-1 the feed direction, rev = spindle revolutions, the last term the flank infeed
  and the vibration along it).  So c = z - s*lead*rev - s*depth*tan(a) stays constant while
  the tool cuts, and changes by one lead per revolution when the tool idles (or faster when it
  returns).  Passes are the stretches of at least half a revolution where dc/drev is under
  20 % of the lead.
* Position along the groove is counted by the spindle: psi = rev - rev_face, revolutions since
  the pass's helix crossed the face z=0 (rev_face is the pass's median of rev - s*g/lead).
  psi grows with time, so a pass's depth profile over psi needs no sorting.
* Material: the stock surface (depth 0), then after every pass the running maximum of the
  depths reached, on a grid of GRID_PER_REV points per revolution from the face to end_z.
  A pass cuts where it goes deeper than that by more than 0.5 um; a chip is a run of cutting
  grid points, its length in revolutions.
* Helix residual: c of every pass sample between the face and end_z, wrapped to one lead
  around the first pass's median, less the overall median.  The axial offset from the nominal
  helix (c without the flank term) is also fitted against depth, giving the infeed angle.

Only single-start threads are handled (the job under test is one).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

GRID_PER_REV = 360
CUT_TOL_M = 0.5e-6
CUTTING_DOC_M = 0.05e-3
SYNC_SLOPE = 0.2  # |dc/drev| / lead below this: synchronised
MIN_PASS_REVS = 0.5
SLOPE_WINDOW_REV = 0.04  # half-width of the difference used for dc/drev


def read_bag(bag: Path) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The job document and the feedback samples (t s, x m, z m, spindle rad, time order)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    job = None
    rows = []
    with AnyReader([Path(bag)], default_typestore=store) as reader:
        wanted = [c for c in reader.connections if c.topic in ("/cnc/joint_states", "/cnc/job_goal")]
        for conn, stamp, raw in reader.messages(connections=wanted):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/cnc/job_goal":
                job = json.loads(msg.data)
                continue
            pos = dict(zip(msg.name, msg.position))
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            rows.append((t, pos["x"], pos["z"], pos["spindle"]))
    if job is None:
        raise ValueError("no job document on /cnc/job_goal")
    data = np.array(rows, dtype=float)
    data = data[np.argsort(data[:, 0], kind="stable")]
    return job, data[:, 0], data[:, 1], data[:, 2], data[:, 3]


def runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True."""
    out = []
    start = None
    for i, f in enumerate(flags):
        if f and start is None:
            start = i
        elif not f and start is not None:
            out.append((start, i - 1))
            start = None
    if start is not None:
        out.append((start, len(flags) - 1))
    return out


def wrap(v, period):
    return (np.asarray(v) + period / 2) % period - period / 2


def read_thread(bag: Path) -> dict:
    """The thread figures (mm, revolutions) from a bag's feedback and job document."""
    return judge(*read_bag(bag))


def judge(job: dict, t: np.ndarray, x: np.ndarray, z: np.ndarray, spindle: np.ndarray) -> dict:
    """The thread figures from samples in time order (s, m, m, rad) and the job (mm, deg)."""
    th = job["thread"]
    if int(th.get("starts", 1)) != 1:
        raise ValueError("this reader handles single-start threads only")
    lead = th["pitch"] / 1000.0
    start_z = th["start_z"] / 1000.0
    end_z = th["end_z"] / 1000.0
    radius = th["major_radius"] / 1000.0
    full = th["depth"] / 1000.0
    tan_a = math.tan(math.radians(th.get("infeed_angle", 29.5)))
    s = 1.0 if end_z > start_z else -1.0
    depth = (x - radius) if th.get("internal", False) else (radius - x)

    rev = np.unwrap(spindle) / (2 * math.pi)
    c = z - s * lead * rev - s * depth * tan_a
    g = z - s * depth * tan_a  # where the groove line under the tool is, axially

    # --- passes: c constant while the spindle turns
    n = len(t)
    step = np.median(np.diff(rev)[np.diff(rev) > 0])
    w = max(1, int(round(SLOPE_WINDOW_REV / step)))
    i = np.arange(n)
    a, b = np.clip(i - w, 0, n - 1), np.clip(i + w, 0, n - 1)
    drev = rev[b] - rev[a]
    dc = c[b] - c[a]
    sync = (drev > 0.5 * w * step) & (np.abs(dc) < SYNC_SLOPE * lead * np.maximum(drev, 1e-12))
    passes_idx = [(i0, i1) for i0, i1 in runs(sync) if rev[i1] - rev[i0] >= MIN_PASS_REVS]

    # --- grid along the groove, face (psi=0) to end_z
    psi_end = s * end_z / lead
    grid = np.arange(0.0, psi_end + 1e-12, 1.0 / GRID_PER_REV)
    in_full = grid <= psi_end - 1.0 + 1e-12  # face to one lead before end_z

    envelope = np.zeros_like(grid)
    passes = []
    helix_samples = []
    for i0, i1 in passes_idx:
        sl = slice(i0, i1 + 1)
        in_thread = (s * g[sl] >= 0.0) & (s * g[sl] <= s * end_z)
        if not in_thread.any():
            continue
        rev_face = float(np.median((rev[sl] - s * g[sl] / lead)[in_thread]))
        psi = rev[sl] - rev_face
        prof = np.interp(grid, psi, depth[sl], left=np.nan, right=np.nan)
        covered = np.isfinite(prof)
        before = envelope.copy()
        cut = prof - before
        cutting = np.where(covered, cut > CUT_TOL_M, False)
        longest = max((r1 - r0 + 1 for r0, r1 in runs(cutting)), default=0)
        reached = float(np.nanmax(prof))
        doc = reached - float(before.max())
        envelope = np.fmax(envelope, prof)
        helix_samples.append(np.flatnonzero(in_thread) + i0)
        passes.append({
            "t_start": float(t[i0]),
            "t_end": float(t[i1]),
            "coverage": float(covered.mean()),
            "depth_mm": reached * 1e3,
            "doc_mm": doc * 1e3,
            "cutting": doc > CUTTING_DOC_M,
            "max_chip_revs": longest / GRID_PER_REV,
            "aircut_share": float(1.0 - cutting[covered].mean()),
        })

    # --- helix: one phase for all passes
    if not helix_samples:
        raise ValueError("no synchronised pass through the thread")
    first = helix_samples[0]
    ref = float(np.median(c[first]))
    every = np.concatenate(helix_samples)
    cw = wrap(c[every] - ref, lead)
    mid = float(np.median(cw))
    residual = cw - mid
    per_pass_res = []
    for idx in helix_samples:
        per_pass_res.append(float(np.max(np.abs(wrap(c[idx] - ref, lead) - mid))) * 1e3)
    for p, r in zip(passes, per_pass_res):
        p["helix_residual_mm"] = r
    offset = wrap(z[every] - s * lead * rev[every] - ref, lead)  # axial offset from the nominal helix
    slope, _ = np.polyfit(s * depth[every], offset, 1)

    docs = [p["doc_mm"] for p in passes]
    depth_error = float(np.max(np.abs(envelope[in_full] - full)))
    overcut = float(np.max(envelope - full))
    return {
        "job": job,
        "passes": passes,
        "synchronised_passes": len(passes),
        "cutting_passes": sum(p["cutting"] for p in passes),
        "max_chip_revs": max((p["max_chip_revs"] for p in passes if p["cutting"]), default=0.0),
        "depth_error_mm": depth_error * 1e3,
        "overcut_mm": overcut * 1e3,
        "min_coverage": min((p["coverage"] for p in passes), default=0.0),
        "full_depth": depth_error <= 0.02e-3 and overcut <= 0.02e-3,
        "doc_never_grows": all(b2 <= a2 + CUT_TOL_M * 1e3 for a2, b2 in zip(docs, docs[1:])),
        "helix_residual_mm": float(np.max(np.abs(residual))) * 1e3,
        "infeed_angle_deg": math.degrees(math.atan(slope)),
    }


if __name__ == "__main__":
    import sys

    out = read_thread(Path(sys.argv[1]))
    out.pop("job")
    print(json.dumps(out, indent=1))
