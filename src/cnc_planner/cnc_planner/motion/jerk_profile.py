"""Bulk sampling of a ruckig trajectory with numpy.

`Trajectory.at_time` costs one Python call per instant, which dominated planning (a job
samples millions of instants). A ruckig trajectory without intermediate waypoints is, per
degree of freedom, an optional two-phase brake pre-trajectory followed by seven phases of
constant jerk, then constant acceleration past its end. This module reads those phases once
(`Trajectory.profiles`) and evaluates any number of instants with the same formula and the
same case split as ruckig's `at_time`, so the results equal it up to float rounding.
A timeline's many pieces are sampled in one call of a compiled kernel (sample_spans,
_sample_kernel.c) that evaluates the same operations, so it equals this module's numpy
evaluation bit for bit.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from ruckig import Trajectory

from cnc_planner.motion._sample_kernel import corrections as _corrections
from cnc_planner.motion._sample_kernel import spans as _spans

# A row of TrajectorySampler.rows, as _sample_kernel.c reads it: t_sum (7), start (8), then
# p, v, a, j (8 each), the duration, the brake's duration and second phase's start, its
# p, v, a, j (2 each).
ROW_LENGTH = 58


@dataclass(frozen=True)
class _Phases:
    """One degree of freedom's phases, as ruckig's at_time reads them."""

    brake_duration: float
    brake_t0: float
    brake_pvaj: np.ndarray  # (4, 2): p, v, a, j at the start of each brake phase
    t_sum: np.ndarray       # (7,): end time of each phase after the brake
    start: np.ndarray       # (0: 0, 1..7: t_sum), the phase's start time
    pvaj: np.ndarray        # (4, 8): p, v, a at each phase boundary; j per phase (j[7] = 0)


def _integrate(t, p0, v0, a0, j):
    """ruckig's integrate(): the state after t at constant jerk j (same operation order)."""
    return (p0 + t * (v0 + t * (a0 / 2 + t * j / 6)),
            v0 + t * (a0 + t * j / 2),
            a0 + t * j)


def _integrate_into(t, p0, v0, a0, j) -> np.ndarray:
    """_integrate as one (3, len(t)) array, t * j computed once (the same values)."""
    out = np.empty((3, len(t)))
    tj = t * j
    np.add(a0, tj, out=out[2])
    out[1] = v0 + t * (a0 + tj / 2)
    out[0] = p0 + t * (v0 + t * (a0 / 2 + tj / 6))
    return out


def _phases(profile) -> _Phases:
    brake = profile.brake
    t_sum = list(itertools.accumulate(profile.t))  # in order, as numpy's cumsum adds
    return _Phases(
        brake_duration=float(brake.duration), brake_t0=float(brake.t[0]),
        brake_pvaj=np.array([brake.p, brake.v, brake.a, brake.j], dtype=float),
        t_sum=np.array(t_sum, dtype=float), start=np.array([0.0, *t_sum], dtype=float),
        pvaj=np.array([profile.p, profile.v, profile.a, [*profile.j, 0.0]], dtype=float),
    )


class TrajectorySampler:
    """Samples one ruckig trajectory at many instants at once."""

    def __init__(self, trajectory: Trajectory) -> None:
        self.duration = float(trajectory.duration)
        sections = trajectory.profiles
        if len(sections) != 1:  # waypoints need ruckig's cloud solver, which we never use
            raise ValueError("only trajectories without intermediate waypoints can be bulk-sampled")
        self._phases = [_phases(p) for p in sections[0]]
        # Per dof, its phases as one flat row (ROW_LENGTH) for sample_spans.
        self.rows = [np.concatenate((ph.t_sum, ph.start, ph.pvaj.ravel(), [self.duration, ph.brake_duration,
                                     ph.brake_t0], ph.brake_pvaj.ravel())) for ph in self._phases]

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Array (3, len(t), dofs): position, velocity, acceleration at the instants t (s)."""
        t = np.asarray(t, dtype=float)
        if len(self._phases) == 1:  # the usual case: no copy into a (3, len(t), 1) array
            return self._sample_dof(self._phases[0], t)[:, :, None]
        out = np.empty((3, len(t), len(self._phases)))
        for dof, ph in enumerate(self._phases):
            out[:, :, dof] = self._sample_dof(ph, t)
        return out

    def _sample_dof(self, ph: _Phases, t: np.ndarray) -> np.ndarray:
        if ph.brake_duration <= 0:
            # Phase 7 (past the last phase) is the constant-acceleration tail, and with no
            # brake ruckig's "after the end" case is that phase exactly (even where the
            # phases' sum rounds a little past the trajectory's duration).
            index = np.searchsorted(ph.t_sum, t, side="right")
            index[t >= self.duration] = 7
            return _integrate_into(t - ph.start[index], *ph.pvaj[:, index])
        p0, v0, a0, j = ph.pvaj[:, np.full(len(t), 7)]
        dt = t - (ph.brake_duration + ph.t_sum[-1])  # past the end: from the final state
        inside = t < self.duration
        brake = inside & (t < ph.brake_duration)
        index = (t[brake] >= ph.brake_t0).astype(int)
        dt[brake] = t[brake] - np.where(index > 0, ph.brake_t0, 0.0)
        p0[brake], v0[brake], a0[brake], j[brake] = ph.brake_pvaj[:, index]
        rest = inside & ~brake
        local = t[rest] - ph.brake_duration
        index = np.searchsorted(ph.t_sum, local, side="right")
        dt[rest] = local - ph.start[index]
        p0[rest], v0[rest], a0[rest], j[rest] = ph.pvaj[:, index]
        return np.array(_integrate(dt, p0, v0, a0, j))


def sample_spans(rows: np.ndarray, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray, ts: np.ndarray,
                 out: tuple[np.ndarray, np.ndarray, np.ndarray] | list[np.ndarray]) -> None:
    """Many pieces of ruckig dofs at once: piece k (its phases rows[k], a row of
    TrajectorySampler.rows) starting at plan time starts[k], at the instants
    ts[lo[k]:hi[k]], written to out[q][lo[k]:hi[k]]; the values its TrajectorySampler
    gives, computed where they are written (compiled: _sample_kernel.c), so that a
    timeline of tens of thousands of short pieces costs no temporaries per instant."""
    _spans(np.ascontiguousarray(rows, dtype=float).reshape(-1, ROW_LENGTH), np.asarray(starts, dtype=float),
           np.asarray(lo, dtype=np.intp), np.asarray(hi, dtype=np.intp), np.asarray(ts, dtype=float), *out)


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
