"""Bulk sampling of ruckig trajectories, compiled.

`Trajectory.at_time` costs one Python call per instant, which dominated planning (a job
samples millions of instants). A ruckig trajectory without intermediate waypoints is, per
degree of freedom, an optional two-phase brake pre-trajectory followed by seven phases of
constant jerk, then constant acceleration past its end. This module reads those phases once
(`Trajectory.profiles`) into one row per dof, and a small compiled kernel
(_sample_kernel.c, built by setup.py) evaluates any number of instants with the same
formula and the same case split as ruckig's `at_time`, so the results equal it up to float
rounding (tested); a timeline's many pieces are sampled in one call (sample_spans).
"""
from __future__ import annotations

import itertools

import numpy as np
from ruckig import Trajectory

from cnc_planner.motion._sample_kernel import corrections as _corrections
from cnc_planner.motion._sample_kernel import spans as _spans

# A row of TrajectorySampler.rows, as _sample_kernel.c reads it: t_sum (7), start (8), then
# p, v, a, j (8 each), the duration, the brake's duration and second phase's start, its
# p, v, a, j (2 each).
ROW_LENGTH = 58
PHASE_POSITIONS = slice(7 + 8, 7 + 8 + 8)  # p in a row: after t_sum and start


def _row(profile, duration: float) -> list[float]:
    """One dof's phases (a ruckig Profile) as a row: the phases' end times summed in order
    (as ruckig sums them), their start states and jerks (none past the end), the brake's."""
    t_sum = list(itertools.accumulate(profile.t))
    brake = profile.brake
    return [*t_sum, 0.0, *t_sum, *profile.p, *profile.v, *profile.a, *profile.j, 0.0,
            duration, brake.duration, brake.t[0], *brake.p, *brake.v, *brake.a, *brake.j]


def axis_row(trajectory: Trajectory) -> np.ndarray:
    """The row of a one-dof trajectory (TrajectorySampler(trajectory).rows[0], read without
    the sampler: a search reads thousands of single-axis moves)."""
    sections = trajectory.profiles
    if len(sections) != 1 or len(sections[0]) != 1:
        raise ValueError("only one-dof trajectories without intermediate waypoints have one row")
    return np.array(_row(sections[0][0], float(trajectory.duration)))


def rest_row(position: float) -> np.ndarray:
    """A row that stands at ``position`` (a move of no duration: every phase starts there at
    rest): sampled, exactly position, 0 and 0 at every instant."""
    row = np.zeros(ROW_LENGTH)
    row[PHASE_POSITIONS] = position
    return row


class TrajectorySampler:
    """Samples one ruckig trajectory at many instants at once."""

    def __init__(self, trajectory: Trajectory) -> None:
        self.duration = float(trajectory.duration)
        sections = trajectory.profiles
        if len(sections) != 1:  # waypoints need ruckig's cloud solver, which we never use
            raise ValueError("only trajectories without intermediate waypoints can be bulk-sampled")
        self._table = np.array([_row(p, self.duration) for p in sections[0]], dtype=float)
        self.rows = list(self._table)  # per dof, its row for sample_spans

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Array (3, len(t), dofs): position, velocity, acceleration at the instants t (s)."""
        t = np.asarray(t, dtype=float)
        out = np.empty((3, len(t), len(self.rows)))
        for dof in range(len(self.rows)):
            sample_spans(self._table[dof:dof + 1], np.zeros(1), np.zeros(1, np.intp), np.full(1, len(t)), t,
                         (out[0, :, dof], out[1, :, dof], out[2, :, dof]))
        return out


def sample_spans(rows: np.ndarray, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray, ts: np.ndarray,
                 out: tuple[np.ndarray, np.ndarray, np.ndarray] | list[np.ndarray] | np.ndarray,
                 held: bool = False) -> None:
    """Many pieces of ruckig dofs at once: piece k (its phases rows[k], a row of
    TrajectorySampler.rows) starting at plan time starts[k], at the instants
    ts[lo[k]:hi[k]], written to out[q][lo[k]:hi[k]]; the values its TrajectorySampler
    gives, computed where they are written (compiled: _sample_kernel.c), so that a
    timeline of tens of thousands of short pieces costs no temporaries per instant.
    ``held``: past its end a piece holds its end state (as sampling it at
    np.minimum(t, duration)) instead of going on at its final acceleration."""
    _spans(np.ascontiguousarray(rows, dtype=float).reshape(-1, ROW_LENGTH), np.asarray(starts, dtype=float),
           np.asarray(lo, dtype=np.intp), np.asarray(hi, dtype=np.intp), np.asarray(ts, dtype=float), *out, held)


def add_corrections(table: np.ndarray, offset: np.ndarray, length: np.ndarray, starts: np.ndarray, lo: np.ndarray,
                    hi: np.ndarray, period: float, ts: np.ndarray,
                    out: tuple[np.ndarray, np.ndarray, np.ndarray] | list[np.ndarray]) -> None:
    """Drive-model corrections learned on the servo grid, added to commands: part k, in
    order, adds its correction (length[k] samples of p, then of v, then of a, one after
    the other in ``table`` from offset[k], sample i at i * period from starts[k]) linearly
    interpolated at the instants ts[lo[k]:hi[k]] to out[q][lo[k]:hi[k]]. The values
    np.interp gives, added in part order as np.add.at adds them (compiled:
    _sample_kernel.c)."""
    _corrections(np.ascontiguousarray(table, dtype=float), np.asarray(offset, dtype=np.intp),
                 np.asarray(length, dtype=np.intp), np.asarray(starts, dtype=float), np.asarray(lo, dtype=np.intp),
                 np.asarray(hi, dtype=np.intp), float(period), np.asarray(ts, dtype=float), *out)
